export module peridot.discretization:point_cloud;
import peridot.std;
import peridot.geometry;

export namespace peridot {

// What a point is for. Exterior ghosts are bond partners without unknowns (LPS/GMLS,
// fictitious nodes); collar points carry prescribed data (Dirichlet volume constraints).
// fictitious: a node of the Taylor-extrapolated layer around a body (seed 004): no degrees of
// freedom, its displacement is a linear function of real ones.
enum class Role : std::uint8_t { interior = 0, collar = 1, ghost = 2, fictitious = 3 };

// Structure-of-arrays point cloud. 2D clouds keep z = 0 and volumes are areas (m^2):
// 2D quantities are per unit thickness; 1D clouds (bars) keep y = z = 0, volumes are lengths
// and quantities are per unit cross-section.
struct PointCloud {
  int dim = 2;
  double spacing = 0;                         // lattice spacing h [m]
  std::array<std::vector<double>, 3> x;       // reference positions [m]
  std::vector<double> volume;                 // nodal volume [m^3] (3D) or area [m^2] (2D)
  std::vector<Role> role;
  // Mesh discretizations keep their P1 elements for output, interpolation and V_ij: triangles
  // (node indices, counter-clockwise) in 2D, positively oriented tetrahedra in 3D; lattices
  // have none.
  std::vector<std::array<std::int32_t, 3>> triangles;
  std::vector<std::array<std::int32_t, 4>> tetrahedra;

  std::size_t size() const { return volume.size(); }
  Vec3 position(std::size_t i) const { return {x[0][i], x[1][i], x[2][i]}; }
  void push_back(const Vec3& p, double v, Role r = Role::interior) {
    for (int k = 0; k < 3; ++k) x[k].push_back(p[k]);
    volume.push_back(v);
    role.push_back(r);
  }
  Aabb bounds() const;
};

struct LatticeOptions {
  double spacing = 0;        // h [m], > 0
  double perturbation = 0;   // each coordinate moves by U[-p h, p h]; 0 <= p < 0.5
  std::uint64_t seed = 1;    // random stream for the perturbation
};

// Cell-centred lattice x = lo + (k + 1/2) h over the shape's bounding box, keeping the
// points the shape contains. Volumes are h^d.
PointCloud lattice(const Shape& shape, const LatticeOptions& options);

// lattice(shape, options) as a grid of sites a rank can make its own points from: the m0 x m1
// x m2 sites of the shape's bounding box, of which the shape keeps some. Point k of lattice()
// is the k-th kept site in site order (site (kx, ky, kz) is kx + m0 (ky + m1 kz)).
//   - A full grid (an axis-aligned box, Shape::is_box, whose sites are all kept) stores nothing
//     per site: point k is site k.
//   - Any other shape keeps its sites as runs along x, row by row (row ky + m1 kz): a few per
//     row for the bodies decks describe, so about (number of rows) x 24 bytes, not bytes per
//     point. Finding them tests every site once (as lattice() does).
struct BoxLattice {
  int dim = 2;
  double h = 0;
  Aabb bounds;                    // the shape's: site (0, 0, 0) sits at bounds.lo + h / 2
  std::array<std::int64_t, 3> m{1, 1, 1};
  double perturbation = 0;        // LatticeOptions'
  std::uint64_t seed = 1;
  // Not a full grid: row r's kept sites are the runs [from, to) in x, runs[run_offset[r]] up to
  // runs[run_offset[r + 1]], and row_start[r] points come before row r. Empty for a full grid.
  std::vector<std::int64_t> row_start, run_offset;
  std::vector<std::array<std::int32_t, 2>> runs;

  bool full() const { return row_start.empty(); }
  std::size_t sites() const { return std::size_t(m[0] * m[1] * m[2]); }
  std::size_t size() const { return full() ? sites() : std::size_t(row_start.back()); }  // points
  Vec3 site(std::int64_t k) const;  // unperturbed
  std::int64_t site_of(std::int64_t id) const;  // the site of point id
  std::int64_t id_of_site(std::int64_t site) const;  // the point at a site, or -1 where none is
  // Calls visit(x_from, x_to, y, z, first_id) for each run of points inside a box of sites,
  // [lo, hi) per axis, clipped to it, in ascending ids: the points of sites x_from .. x_to - 1
  // of row (y, z), numbered from first_id.
  template <class Visit>
  void for_each_run(const std::array<std::int64_t, 6>& box, Visit&& visit) const {
    for (auto z = std::max<std::int64_t>(box[4], 0); z < std::min(box[5], m[2]); ++z)
      for (auto y = std::max<std::int64_t>(box[2], 0); y < std::min(box[3], m[1]); ++y) {
        const std::int64_t x0 = std::max<std::int64_t>(box[0], 0), x1 = std::min(box[1], m[0]);
        if (x0 >= x1) continue;
        const std::int64_t row = y + m[1] * z;
        if (full()) {
          visit(x0, x1, y, z, x0 + m[0] * row);
          continue;
        }
        std::int64_t id = row_start[std::size_t(row)];
        for (auto r = run_offset[std::size_t(row)]; r < run_offset[std::size_t(row) + 1]; ++r) {
          const std::int64_t from = runs[std::size_t(r)][0], to = runs[std::size_t(r)][1];
          const std::int64_t a = std::max(from, x0), b = std::min(to, x1);
          if (a < b) visit(a, b, y, z, id + (a - from));
          id += to - from;
        }
      }
  }
  // The points inside a box of sites: their ids (ascending) and their number.
  std::vector<std::int64_t> ids_in(const std::array<std::int64_t, 6>& box) const;
  std::size_t count_in(const std::array<std::int64_t, 6>& box) const;
};
// A full grid, or nullopt where the shape is no box or its sites are not a full grid.
std::optional<BoxLattice> box_lattice(const Shape& shape, const LatticeOptions& options);
// Any shape's grid (a full one where box_lattice gives one); nullopt where lattice() would
// fail (no point, bad options). Throws std::invalid_argument beyond 2e9 sites, as lattice().
std::optional<BoxLattice> shape_lattice(const Shape& shape, const LatticeOptions& options);
// The points of a grid inside a box of sites, numbered from 0 in site order: how many there are,
// and the number of the one at site (x, y, z) of the box (a ghost's index on its owner, an
// unknown's number within its owner's rows). Memory in the box's rows.
class BoxNumbering {
 public:
  BoxNumbering(const BoxLattice& grid, const std::array<std::int64_t, 6>& box);
  std::int64_t size() const { return before_.back(); }
  std::int64_t index(std::int64_t x, std::int64_t y, std::int64_t z) const;

 private:
  const BoxLattice* g_;
  std::array<std::int64_t, 6> box_;
  std::vector<std::int64_t> before_;  // the box's points before each of its rows, then all
  std::int64_t row(std::int64_t y, std::int64_t z) const { return (z - box_[4]) * (box_[3] - box_[2]) + (y - box_[2]); }
};

// A full grid keeping only the sites keep(site) accepts (asked once per site, in site order):
// runs row by row, points numbered among the kept sites. shape_lattice keeps the sites a shape
// holds; a caller may keep sites by their perturbed points (LatticeStream), and must then make
// points from the full grid, whose ids carry the perturbation stream.
BoxLattice keep_sites(BoxLattice full_grid, const std::function<bool(std::int64_t site)>& keep);

// lattice()'s perturbed points of a grid made one by one, for ids strictly ascending across the
// calls: the seed's stream is skipped past the points in between.
class LatticeStream {
 public:
  explicit LatticeStream(const BoxLattice& grid);
  Vec3 point(std::int64_t id);

 private:
  const BoxLattice* g_;
  std::mt19937_64 rng_;
  std::uniform_real_distribution<double> jitter_;
  std::int64_t next_ = 0;  // the point whose draws the stream gives next
};

// The points with the given ids, strictly ascending (as lattice() makes them: positions,
// volumes h^dim, interior). A perturbed point takes the same draws of the seed's stream as in
// lattice(): the stream is skipped past the points before it, so the time is linear in the
// largest id, the memory in the ids.
PointCloud lattice_points(const BoxLattice& grid, std::span<const std::int64_t> ids);

}  // namespace peridot

namespace peridot {

Aabb PointCloud::bounds() const {
  Aabb b{{0, 0, 0}, {0, 0, 0}};
  if (size() == 0) return b;
  for (int k = 0; k < 3; ++k) {
    b.lo[k] = b.hi[k] = x[k][0];
    for (double v : x[k]) {
      b.lo[k] = std::min(b.lo[k], v);
      b.hi[k] = std::max(b.hi[k], v);
    }
  }
  return b;
}

namespace {

// Sites per axis of the lattice over box b: the extent over h, snapped to the integer when it
// is one up to round-off. Throws for extents that would need more than 2e9 sites.
std::array<long, 3> site_counts(const Aabb& b, int dim, double h) {
  std::array<long, 3> n{1, 1, 1};
  for (int k = 0; k < dim; ++k) {
    const double cells = (b.hi[k] - b.lo[k]) / h;
    // Guard the double -> integer conversion: an infinite or huge extent would overflow it.
    if (!(cells < 2e9)) throw std::invalid_argument("lattice: spacing too small for the body's extent, more than 2e9 lattice sites");
    // Snap to the integer when the extent is a multiple of h up to round-off.
    n[k] = std::abs(cells - std::round(cells)) < 1e-9 * std::max(1.0, cells) ? std::lround(cells)
                                                                             : static_cast<long>(std::ceil(cells));
    if (n[k] < 1) n[k] = 1;
  }
  const double total = double(n[0]) * double(n[1]) * double(n[2]);
  if (total > 2e9) throw std::invalid_argument("lattice: spacing too small, more than 2e9 lattice sites");
  return n;
}

// The centre of site (kx, ky, kz) of the lattice over box b.
Vec3 site_at(const Aabb& b, int dim, double h, std::int64_t kx, std::int64_t ky, std::int64_t kz) {
  return Vec3{b.lo[0] + (double(kx) + 0.5) * h, dim >= 2 ? b.lo[1] + (double(ky) + 0.5) * h : 0.0,
              dim == 3 ? b.lo[2] + (double(kz) + 0.5) * h : 0.0};
}

}  // namespace

Vec3 BoxLattice::site(std::int64_t k) const { return site_at(bounds, dim, h, k % m[0], (k / m[0]) % m[1], k / (m[0] * m[1])); }

namespace {

// The grid of the shape's bounding box with lattice()'s options, every site kept (m: sites per
// axis); nullopt for options lattice() refuses.
std::optional<BoxLattice> bounding_grid(const Shape& shape, const LatticeOptions& o) {
  if (shape.empty() || !(o.perturbation >= 0 && o.perturbation < 0.5) || !(o.spacing > 0) || !std::isfinite(o.spacing)) return std::nullopt;
  BoxLattice g;
  g.dim = shape.dimension();
  g.h = o.spacing;
  g.perturbation = o.perturbation;
  g.seed = o.seed;
  g.bounds = shape.bounds();
  const auto n = site_counts(g.bounds, g.dim, g.h);
  for (int a = 0; a < 3; ++a) g.m[std::size_t(a)] = n[std::size_t(a)];
  return g;
}

}  // namespace

std::optional<BoxLattice> box_lattice(const Shape& shape, const LatticeOptions& o) {
  if (!shape.is_box()) return std::nullopt;
  auto grid = bounding_grid(shape, o);
  if (!grid) return std::nullopt;
  BoxLattice& g = *grid;
  const auto n = g.m;
  // A box tests each axis alone: the sites kept along an axis, at site 0 of the others, are
  // those of every row. They must be a prefix for ids to follow the grid.
  for (int a = 0; a < g.dim; ++a) {
    std::array<std::int64_t, 3> k{0, 0, 0};
    std::int64_t kept = 0;
    for (k[a] = 0; k[a] < n[a]; ++k[a]) {
      if (!shape.contains(site_at(g.bounds, g.dim, g.h, k[0], k[1], k[2]))) break;
      ++kept;
    }
    for (; k[a] < n[a]; ++k[a])
      if (shape.contains(site_at(g.bounds, g.dim, g.h, k[0], k[1], k[2]))) return std::nullopt;
    if (kept == 0) return std::nullopt;
    g.m[a] = kept;
  }
  return g;
}

std::int64_t BoxLattice::site_of(std::int64_t id) const {
  if (full()) return id;
  // The last row starting at or below id holds it (rows without points share their start).
  const auto row = std::int64_t(std::upper_bound(row_start.begin(), row_start.end(), id) - row_start.begin()) - 1;
  std::int64_t left = id - row_start[std::size_t(row)];
  for (auto r = run_offset[std::size_t(row)]; r < run_offset[std::size_t(row) + 1]; ++r) {
    const std::int64_t from = runs[std::size_t(r)][0], len = runs[std::size_t(r)][1] - from;
    if (left < len) return from + left + m[0] * row;
    left -= len;
  }
  throw std::logic_error("BoxLattice::site_of: a point id past its row's runs");
}

std::vector<std::int64_t> BoxLattice::ids_in(const std::array<std::int64_t, 6>& box) const {
  std::vector<std::int64_t> ids;
  ids.reserve(count_in(box));
  for_each_run(box, [&](std::int64_t a, std::int64_t b, std::int64_t, std::int64_t, std::int64_t first) {
    for (std::int64_t k = 0; k < b - a; ++k) ids.push_back(first + k);
  });
  return ids;
}

std::size_t BoxLattice::count_in(const std::array<std::int64_t, 6>& box) const {
  std::size_t n = 0;
  for_each_run(box, [&](std::int64_t a, std::int64_t b, std::int64_t, std::int64_t, std::int64_t) { n += std::size_t(b - a); });
  return n;
}

std::optional<BoxLattice> shape_lattice(const Shape& shape, const LatticeOptions& o) {
  if (auto g = box_lattice(shape, o)) return g;
  auto grid = bounding_grid(shape, o);
  if (!grid) return std::nullopt;
  // lattice()'s test of each site.
  const BoxLattice g = keep_sites(*grid, [&](std::int64_t site) { return shape.contains(grid->site(site)); });
  if (g.size() == 0) return std::nullopt;
  return g;
}

BoxLattice keep_sites(BoxLattice g, const std::function<bool(std::int64_t site)>& keep) {
  if (!g.full()) throw std::invalid_argument("keep_sites: the grid keeps some sites already");
  const std::int64_t rows = g.m[1] * g.m[2];
  g.row_start.assign(std::size_t(rows) + 1, 0);
  g.run_offset.assign(std::size_t(rows) + 1, 0);
  for (std::int64_t row = 0; row < rows; ++row) {
    std::int64_t kept = 0, from = -1;
    for (std::int64_t x = 0; x <= g.m[0]; ++x) {
      const bool in = x < g.m[0] && keep(x + g.m[0] * row);
      if (in && from < 0) from = x;
      if (!in && from >= 0) {
        g.runs.push_back({std::int32_t(from), std::int32_t(x)});
        kept += x - from;
        from = -1;
      }
    }
    g.row_start[std::size_t(row) + 1] = g.row_start[std::size_t(row)] + kept;
    g.run_offset[std::size_t(row) + 1] = std::int64_t(g.runs.size());
  }
  return g;
}

BoxNumbering::BoxNumbering(const BoxLattice& g, const std::array<std::int64_t, 6>& box) : g_(&g), box_(box) {
  for (int a = 0; a < 3; ++a) {
    box_[std::size_t(2 * a)] = std::max<std::int64_t>(box_[std::size_t(2 * a)], 0);
    box_[std::size_t(2 * a + 1)] = std::max(box_[std::size_t(2 * a)], std::min(box_[std::size_t(2 * a + 1)], g.m[std::size_t(a)]));
  }
  before_.assign(std::size_t((box_[3] - box_[2]) * (box_[5] - box_[4])) + 1, 0);
  g.for_each_run(box_, [&](std::int64_t a, std::int64_t b, std::int64_t y, std::int64_t z, std::int64_t) { before_[std::size_t(row(y, z)) + 1] += b - a; });
  for (std::size_t k = 1; k < before_.size(); ++k) before_[k] += before_[k - 1];
}

std::int64_t BoxNumbering::index(std::int64_t x, std::int64_t y, std::int64_t z) const {
  return before_[std::size_t(row(y, z))] + std::int64_t(g_->count_in({box_[0], x, y, y + 1, z, z + 1}));
}

std::int64_t BoxLattice::id_of_site(std::int64_t site) const {
  if (site < 0 || std::size_t(site) >= sites()) return -1;
  if (full()) return site;
  const std::int64_t row = site / m[0], x = site % m[0];
  std::int64_t id = row_start[std::size_t(row)];
  for (auto r = run_offset[std::size_t(row)]; r < run_offset[std::size_t(row) + 1]; ++r) {
    const std::int64_t from = runs[std::size_t(r)][0], to = runs[std::size_t(r)][1];
    if (x < from) return -1;
    if (x < to) return id + (x - from);
    id += to - from;
  }
  return -1;
}

PointCloud lattice_points(const BoxLattice& g, std::span<const std::int64_t> ids) {
  PointCloud pc;
  pc.dim = g.dim;
  pc.spacing = g.h;
  const double vol = std::pow(g.h, g.dim);
  for (int k = 0; k < 3; ++k) pc.x[k].reserve(ids.size());
  pc.volume.reserve(ids.size());
  pc.role.reserve(ids.size());
  if (std::adjacent_find(ids.begin(), ids.end(), std::greater_equal<>()) != ids.end() || (!ids.empty() && (ids.front() < 0 || std::size_t(ids.back()) >= g.size())))
    throw std::invalid_argument("lattice_points: the ids must be ascending sites of the grid");
  LatticeStream stream(g);
  for (const auto id : ids) pc.push_back(stream.point(id), vol);
  return pc;
}

// lattice()'s stream: dim draws per kept site, in site order, one engine value per draw.
LatticeStream::LatticeStream(const BoxLattice& g) : g_(&g), rng_(g.seed), jitter_(-g.perturbation * g.h, g.perturbation * g.h) {}

Vec3 LatticeStream::point(std::int64_t id) {
  Vec3 p = g_->site(g_->site_of(id));
  if (g_->perturbation > 0) {
    rng_.discard(std::uint64_t(g_->dim) * std::uint64_t(id - next_));
    for (int k = 0; k < g_->dim; ++k) p[k] += jitter_(rng_);
    next_ = id + 1;
  }
  return p;
}

PointCloud lattice(const Shape& shape, const LatticeOptions& o) {
  if (shape.empty()) throw std::invalid_argument("lattice: geometry is empty");
  if (!(o.spacing > 0) || !std::isfinite(o.spacing))
    throw std::invalid_argument("lattice: spacing must be a finite number > 0");
  if (!(o.perturbation >= 0 && o.perturbation < 0.5))
    throw std::invalid_argument("lattice: perturbation must be in [0, 0.5)");
  const int dim = shape.dimension();
  const Aabb b = shape.bounds();
  const double h = o.spacing;
  const std::array<long, 3> n = site_counts(b, dim, h);

  PointCloud pc;
  pc.dim = dim;
  pc.spacing = h;
  const double vol = std::pow(h, dim);
  std::mt19937_64 rng(o.seed);
  std::uniform_real_distribution<double> jitter(-o.perturbation * h, o.perturbation * h);
  // Lattice sites -> inside the shape -> perturbed -> points. The jitter is drawn only for
  // kept sites, in site order, so a seed gives the same cloud as it always has.
  const auto site = [&](std::int64_t k) { return site_at(b, dim, h, k % n[0], (k / n[0]) % n[1], k / (n[0] * n[1])); };
  const auto perturbed = [&](Vec3 p) {
    if (o.perturbation > 0)
      for (int k = 0; k < dim; ++k) p[k] += jitter(rng);
    return p;
  };
  auto points = std::views::iota(std::int64_t{0}, std::int64_t(n[0]) * n[1] * n[2]) | std::views::transform(site) |
                      std::views::filter([&](const Vec3& p) { return shape.contains(p); }) | std::views::transform(perturbed);
  for (const Vec3& p : points) pc.push_back(p, vol);
  if (pc.size() == 0) throw std::invalid_argument("lattice: geometry contains no lattice points at this spacing");
  return pc;
}

}  // namespace peridot
