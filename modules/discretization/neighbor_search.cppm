module;
#include <omp.h>
export module peridot.discretization:neighbor_search;
import peridot.std;
import peridot.geometry;
import :point_cloud;
import :bond_list;

export namespace peridot {

struct BondOptions {
  double horizon = 0;              // delta [m]
  double tolerance = 1e-10;        // relative: partners with |xi| <= delta (1 + tol) are bonds
  // Partial-volume correction at the horizon edge: a partner whose lattice cell (edge h,
  // centred on it) straddles the horizon is weighted by the fraction of that cell inside
  // the ball, measured on a 6^d sub-grid of the cell.
  bool partial_volume = false;
  std::vector<Crack> cracks;       // bonds that properly cross a crack are never created
  bool lean = false;               // store partner, float weight and mask only (see BondList)
  bool geometry = true;            // store xi and |xi| (unless lean); false: a compact list
};

// The reference bond vector x_j - x_i of bond b of point i, from a full list's xi or, in a lean
// list, from the positions (the same subtraction, so the same bits).
inline Vec3 bond_vector(const PointCloud& points, const BondList& bonds, std::size_t i, std::int64_t b) {
  const auto k = std::size_t(b);
  if (!bonds.xi[0].empty()) return {bonds.xi[0][k], bonds.xi[1][k], bonds.xi[2][k]};
  const auto j = std::size_t(bonds.neighbor[k]);
  return {points.x[0][j] - points.x[0][i], points.x[1][j] - points.x[1][i], points.x[2][j] - points.x[2][i]};
}

// xi and |xi| of bond b from point i: stored in a full list, from the positions in a compact or
// lean one (bond_vector and bond_length of it: the bits a builder stores).
struct BondGeometry {
  double xi[3];
  double len;
};
inline BondGeometry bond_geometry(const PointCloud& points, const BondList& bonds, std::size_t i, std::int64_t b) {
  const Vec3 xi = bond_vector(points, bonds, i, b);
  return {{xi[0], xi[1], xi[2]}, bonds.stores_geometry() ? bonds.length[std::size_t(b)] : bond_length(xi[0], xi[1], xi[2])};
}

// The inclusive search radius: delta (1 + tol), or with partial volumes the horizon plus half a
// cell diagonal, since a cell straddling the horizon may have its centre outside it.
double bond_cutoff(const BondOptions& options, int dim, double spacing);

// Quadrature factor of a partner at offset (dx, dy, dz): 1 without partial volumes, else the
// fraction of its lattice cell (edge h, centred on it) inside the horizon, measured on a 6^d
// sub-grid (exact in 1D); 0 excludes the partner.
double partner_volume_factor(const BondOptions& options, int dim, double spacing, double dx, double dy, double dz);

// A crack's bounding box grown by `grow` on every side, and whether p lies in a box: only
// points within a bond length of a crack's box can have a bond that crosses it.
Aabb crack_box(const Crack& crack, double grow);
bool inside(const Aabb& box, const Vec3& p);

// All pairs within the horizon by an O(N) cell-list search, as a CSR bond list sorted by
// partner index. Weights are the partner's volume (times the partial-volume factor).
BondList build_bonds(const PointCloud& points, const BondOptions& options);

// Marks broken (intact = 0) every existing bond that properly crosses a crack: a pre-crack
// whose cut bonds stay in the list, so damage counts them as other codes do.
void cut_bonds(const PointCloud& points, BondList& bonds, const std::vector<Crack>& cracks);

// Reference O(N^2) search for tests.
BondList build_bonds_brute_force(const PointCloud& points, const BondOptions& options);

}  // namespace peridot

namespace peridot {

namespace {

struct Search {
  double cutoff;     // inclusive search radius
  BondOptions options;
  double h;
  bool partial;
  int dim;
  std::vector<Aabb> near_crack;  // each crack's box grown by the cutoff: only points inside test bonds against cracks
};

Search make_search(const PointCloud& pc, const BondOptions& o) {
  if (!(o.horizon > 0) || !std::isfinite(o.horizon))
    throw std::invalid_argument("bonds: horizon must be a finite number > 0");
  if (pc.size() == 0) throw std::invalid_argument("bonds: point cloud is empty");
  if (pc.size() > std::size_t(std::numeric_limits<std::int32_t>::max()))
    throw std::invalid_argument("bonds: more than 2^31 points");
  Search s{bond_cutoff(o, pc.dim, pc.spacing), o, pc.spacing, o.partial_volume, pc.dim, {}};
  s.options.cracks.clear();
  // A bond of i can only cross a crack if i lies within a bond length of the crack's box.
  for (const auto& c : o.cracks) s.near_crack.push_back(crack_box(c, 2 * s.cutoff));
  return s;
}

double volume_factor(const Search& s, double dx, double dy, double dz) {
  return s.partial ? partner_volume_factor(s.options, s.dim, s.h, dx, dy, dz) : 1.0;
}

}  // namespace

Aabb crack_box(const Crack& crack, double grow) {
  std::vector<Vec3> corners;
  if (const auto* s = std::get_if<CrackSegment>(&crack)) {
    corners = {s->a, s->b};
  } else {
    const auto& r = std::get<CrackRectangle>(crack);
    corners = {r.origin, r.origin + r.edge1, r.origin + r.edge2, r.origin + r.edge1 + r.edge2};
  }
  Aabb box{corners[0], corners[0]};
  for (const auto& c : corners)
    for (int k = 0; k < 3; ++k) box.lo[k] = std::min(box.lo[k], c[k]), box.hi[k] = std::max(box.hi[k], c[k]);
  for (int k = 0; k < 3; ++k) box.lo[k] -= grow, box.hi[k] += grow;
  return box;
}

bool inside(const Aabb& box, const Vec3& p) {
  for (int k = 0; k < 3; ++k)
    if (p[k] < box.lo[k] || p[k] > box.hi[k]) return false;
  return true;
}

double bond_cutoff(const BondOptions& o, int dim, double spacing) {
  if (!o.partial_volume) return o.horizon * (1 + o.tolerance);
  if (!(spacing > 0)) throw std::invalid_argument("bonds: partial volume needs the lattice spacing");
  return (o.horizon + 0.5 * std::sqrt(double(dim)) * spacing) * (1 + o.tolerance);
}

// Cells wholly inside skip the sub-grid.
double partner_volume_factor(const BondOptions& o, int dim, double h, double dx, double dy, double dz) {
  if (!o.partial_volume) return 1.0;
  const double delta = o.horizon;
  const double r = std::sqrt(dx * dx + dy * dy + dz * dz);
  const double half_diag = 0.5 * std::sqrt(double(dim)) * h;
  if (r + half_diag <= delta) return 1.0;
  if (dim == 1) return std::clamp((delta + 0.5 * h - r) / h, 0.0, 1.0);  // exact in 1D
  constexpr int n = 6;
  const double step = h / n, d2 = delta * delta * (1 + 1e-12);
  const int nz = dim == 3 ? n : 1;
  int inside = 0;
  for (int a = 0; a < n; ++a)
    for (int b = 0; b < n; ++b)
      for (int c = 0; c < nz; ++c) {
        const double x = dx + (a + 0.5) * step - 0.5 * h, y = dy + (b + 0.5) * step - 0.5 * h;
        const double z = dim == 3 ? dz + (c + 0.5) * step - 0.5 * h : 0.0;
        inside += x * x + y * y + z * z <= d2;
      }
  return double(inside) / double(n * n * nz);
}

namespace {

// Visits candidate partners j of i (j != i) within the cutoff, in a fixed order.
template <class Candidates, class Visit>
void for_each_partner(const PointCloud& pc, const Search& s, const std::vector<Crack>& cracks, std::size_t i,
                      Candidates&& candidates, Visit&& visit) {
  const Vec3 xi = pc.position(i);
  const double c2 = s.cutoff * s.cutoff;
  bool near = false;
  for (const auto& box : s.near_crack) near = near || inside(box, xi);
  candidates(i, [&](std::size_t j) {
    if (j == i) return;
    const double dx = pc.x[0][j] - xi[0], dy = pc.x[1][j] - xi[1], dz = pc.x[2][j] - xi[2];
    const double r2 = dx * dx + dy * dy + dz * dz;
    if (r2 > c2) return;
    if (s.partial && volume_factor(s, dx, dy, dz) == 0.0) return;
    if (near && crosses_any(cracks, xi, pc.position(j))) return;
    visit(j, dx, dy, dz);
  });
}

template <class Candidates>
BondList assemble(const PointCloud& pc, const BondOptions& o, const Search& s, Candidates&& candidates) {
  const std::size_t n = pc.size();
  BondList bl;
  bl.horizon = o.horizon;
  bl.offset.assign(n + 1, 0);
#pragma omp parallel for schedule(dynamic, 256)
  for (std::size_t i = 0; i < n; ++i) {
    std::int64_t c = 0;
    for_each_partner(pc, s, o.cracks, i, candidates, [&](std::size_t, double, double, double) { ++c; });
    bl.offset[i + 1] = c;
  }
  std::partial_sum(bl.offset.begin(), bl.offset.end(), bl.offset.begin());
  const auto nb = std::size_t(bl.offset[n]);
  bl.neighbor.resize(nb);
  if (o.lean) {
    bl.weight_f.resize(nb);
  } else {
    if (o.geometry) {
      for (auto& v : bl.xi) v.resize(nb);
      bl.length.resize(nb);
    }
    bl.weight.resize(nb);
  }
  bl.intact.resize(nb);  // unwritten (LargeArray): set below, on the thread that owns the point
#pragma omp parallel
  {
    std::vector<std::int32_t> list;
#pragma omp for schedule(dynamic, 256)
    for (std::size_t i = 0; i < n; ++i) {
      list.clear();
      for_each_partner(pc, s, o.cracks, i, candidates,
                       [&](std::size_t j, double, double, double) { list.push_back(std::int32_t(j)); });
      std::sort(list.begin(), list.end());  // partner order independent of binning and threads
      std::int64_t b = bl.offset[i];
      for (auto j : list) {
        const double dx = pc.x[0][j] - pc.x[0][i], dy = pc.x[1][j] - pc.x[1][i], dz = pc.x[2][j] - pc.x[2][i];
        const double w = pc.volume[j] * volume_factor(s, dx, dy, dz);
        bl.neighbor[b] = j;
        bl.intact[b] = 1;
        if (o.lean) {
          bl.weight_f[b] = float(w);
        } else {
          if (o.geometry) {
            bl.xi[0][b] = dx;
            bl.xi[1][b] = dy;
            bl.xi[2][b] = dz;
            bl.length[b] = bond_length(dx, dy, dz);
          }
          bl.weight[b] = w;
        }
        ++b;
      }
    }
  }
  return bl;
}

}  // namespace

BondList build_bonds(const PointCloud& pc, const BondOptions& o) {
  const Search s = make_search(pc, o);
  const Aabb box = pc.bounds();
  // Cells of edge >= cutoff / 2: every partner lies in the 5^d block around a point's cell,
  // which holds 15.6 cutoff^3 of candidates in 3D against 27 for cells of edge cutoff.
  constexpr long reach = 2;
  std::array<long, 3> nc{1, 1, 1};
  for (int k = 0; k < pc.dim; ++k)
    nc[k] = std::max(1L, static_cast<long>(std::floor((box.hi[k] - box.lo[k]) * double(reach) / s.cutoff)));
  std::array<double, 3> inv{0, 0, 0};
  for (int k = 0; k < pc.dim; ++k) inv[k] = nc[k] / std::max(box.hi[k] - box.lo[k], 1e-300);
  const auto cell_of = [&](std::size_t i, int k) {
    return std::clamp(static_cast<long>((pc.x[k][i] - box.lo[k]) * inv[k]), 0L, nc[k] - 1);
  };
  const std::size_t ncell = std::size_t(nc[0] * nc[1] * nc[2]);
  // Counting sort of the points into cells.
  std::vector<std::int64_t> start(ncell + 1, 0);
  std::vector<std::int32_t> cell(pc.size());
  for (std::size_t i = 0; i < pc.size(); ++i) {
    cell[i] = std::int32_t((cell_of(i, 2) * nc[1] + cell_of(i, 1)) * nc[0] + cell_of(i, 0));
    ++start[cell[i] + 1];
  }
  std::partial_sum(start.begin(), start.end(), start.begin());
  std::vector<std::int32_t> sorted(pc.size());
  {
    std::vector<std::int64_t> fill(start.begin(), start.end() - 1);
    for (std::size_t i = 0; i < pc.size(); ++i) sorted[fill[cell[i]]++] = std::int32_t(i);
  }
  const auto candidates = [&](std::size_t i, auto&& f) {
    const long cx = cell_of(i, 0), cy = cell_of(i, 1), cz = cell_of(i, 2);
    for (long z = std::max(0L, cz - reach); z <= std::min(nc[2] - 1, cz + reach); ++z)
      for (long y = std::max(0L, cy - reach); y <= std::min(nc[1] - 1, cy + reach); ++y)
        for (long x = std::max(0L, cx - reach); x <= std::min(nc[0] - 1, cx + reach); ++x) {
          const std::size_t c = std::size_t((z * nc[1] + y) * nc[0] + x);
          for (std::int64_t k = start[c]; k < start[c + 1]; ++k) f(std::size_t(sorted[k]));
        }
  };
  return assemble(pc, o, s, candidates);
}

BondList build_bonds_brute_force(const PointCloud& pc, const BondOptions& o) {
  const Search s = make_search(pc, o);
  const auto candidates = [&](std::size_t, auto&& f) {
    for (std::size_t j = 0; j < pc.size(); ++j) f(j);
  };
  return assemble(pc, o, s, candidates);
}

void cut_bonds(const PointCloud& pc, BondList& bl, const std::vector<Crack>& cracks) {
  if (cracks.empty()) return;
  const auto n = static_cast<std::int64_t>(pc.size());
#pragma omp parallel for schedule(dynamic, 256)
  for (std::int64_t i = 0; i < n; ++i) {
    const Vec3 p = pc.position(std::size_t(i));
    for (auto b = bl.offset[i]; b < bl.offset[i + 1]; ++b)
      if (crosses_any(cracks, p, pc.position(std::size_t(bl.neighbor[b])))) bl.intact[b] = 0;
  }
}

}  // namespace peridot
