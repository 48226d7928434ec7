export module peridot.discretization:lattice_grid;
import peridot.std;
import peridot.geometry;
import :point_cloud;
import :bond_list;

export namespace peridot {

// Integer coordinates of a 2D cloud whose points sit on one square lattice (the uniform grids of
// seed 004). Geometry on the lattice (which bond crosses which cell side, and whether it hits a
// side's end) is then decided in integers, exactly, instead of with a tolerance.
struct LatticeGrid {
  double h = 0;                       // spacing [m]
  double x0 = 0, y0 = 0;              // position of grid index (0, 0) [m]
  int lo[2] = {0, 0}, n[2] = {0, 0};  // index box [lo, lo + n) in x and y
  std::vector<std::int32_t> gx, gy;   // per point
  std::vector<std::int32_t> id;       // per box site: point index, or -1

  std::int32_t at(int ix, int iy) const {
    if (ix < lo[0] || iy < lo[1] || ix >= lo[0] + n[0] || iy >= lo[1] + n[1]) return -1;
    return id[std::size_t(iy - lo[1]) * std::size_t(n[0]) + std::size_t(ix - lo[0])];
  }
};

// Throws std::invalid_argument if a point is off the lattice through point 0 by more than 1e-6 h.
LatticeGrid lattice_grid(const PointCloud& points);

// A straight segment of one grid line, of length h (a cell side, or the segment through a node
// that the stress tensor of seed 004 eq. (51) uses). In doubled grid units, so both kinds are
// integers: the segment lies on x = line/2 (axis 0) or y = line/2 (axis 1) and spans
// [centre - 1/2, centre + 1/2] along the other axis. Cell sides have odd `line`, node segments even.
struct GridSegment {
  int axis = 0;
  std::int64_t line = 0;
  std::int64_t centre = 0;
};

// Calls visit(b, alpha) for every directed bond b whose segment crosses `s` (both ends may lie on
// the line for node segments; bonds parallel to the line never cross), going along +axis
// only (direction = 1), -axis only (-1) or either way (0). alpha is 1/2 where the crossing is an end of `s` (it is shared with
// the neighbouring segment) or where the bond starts or ends on the line, else 1 (seed 004 Sec. 4.3
// and eq. (60)). `typed`: only bonds at most 45 degrees from the segment's normal
// (type A for axis 0, type B for axis 1: |xi_x| >= |xi_y| is A, otherwise B, eq. (50)).
// A visitor taking a third argument also gets the bond's start point.
// The crossing rule both enumerations below share, in doubled grid units: a bond (p, q) along
// the segment's normal axis and along it (p != 0), starting a2 / 2 from the segment's line, whose
// crossing lies D / (2p) from the segment's centre. alpha as above, or 0 where it misses.
inline double crossing_alpha(std::int64_t p, std::int64_t a2, std::int64_t D) {
  if (p > 0 ? (a2 < 0 || a2 > 2 * p) : (a2 > 0 || a2 < 2 * p)) return 0;
  if (std::llabs(D) > std::llabs(p)) return 0;
  return std::llabs(D) == std::llabs(p) || a2 == 0 || a2 == 2 * p ? 0.5 : 1.0;
}
// Whether a bond (p, q) belongs to segments of `axis` under eq. (50)'s typing.
inline bool of_type(int axis, std::int64_t p, std::int64_t q) { return axis == 0 ? std::llabs(p) >= std::llabs(q) : std::llabs(p) > std::llabs(q); }

template <class Visit>
void for_each_crossing(const LatticeGrid& g, const BondList& bonds, const GridSegment& s, int direction, bool typed, Visit&& visit) {
  const int a = s.axis, o = 1 - s.axis;
  const auto& ga = a == 0 ? g.gx : g.gy;
  const auto& go = a == 0 ? g.gy : g.gx;
  const int reach = int(std::ceil(bonds.horizon / g.h + 1e-9)) + 1;
  // Start points within the reach of the segment; each bond is visited from its start point.
  const std::int64_t line_lo = (s.line - 2 * reach) / 2 - 1, line_hi = (s.line + 2 * reach) / 2 + 1;
  for (std::int64_t ka = line_lo; ka <= line_hi; ++ka)
    for (std::int64_t ko = s.centre - reach - 1; ko <= s.centre + reach + 1; ++ko) {
      const auto j = a == 0 ? g.at(int(ka), int(ko)) : g.at(int(ko), int(ka));
      if (j < 0) continue;
      for (auto b = bonds.begin(std::size_t(j)); b < bonds.end(std::size_t(j)); ++b) {
        const auto k = std::size_t(bonds.neighbor[b]);
        const std::int64_t p = std::int64_t(ga[k]) - ga[std::size_t(j)], q = std::int64_t(go[k]) - go[std::size_t(j)];
        if (p == 0 || (direction > 0 && p < 0) || (direction < 0 && p > 0)) continue;
        if (typed && !of_type(a, p, q)) continue;
        const std::int64_t a2 = s.line - 2 * ka;  // doubled distance from the start to the line
        // 2p (y* - centre), with y* the crossing's coordinate along the segment.
        const double alpha = crossing_alpha(p, a2, 2 * p * (ko - s.centre) + a2 * q);
        if (alpha == 0) continue;
        if constexpr (std::is_invocable_v<Visit, std::size_t, double, std::size_t>)
          visit(std::size_t(b), alpha, std::size_t(j));
        else
          visit(std::size_t(b), alpha);
      }
    }
}

// Every (node, bond) pair of eq. (51) at once: calls visit(i, b, alpha, start, axis) for each
// node i and directed bond b (from `start`) that crosses i's node segment GridSegment{axis,
// 2 g_axis(i), g_other(i)}, typed, either way: the pairs for_each_crossing(g, bonds, that
// segment, 0, true, ...) visits for each node, found from the bonds in O(bonds x delta / h)
// instead of from a window of start points around each node (O(nodes x (delta / h)^2 x bonds
// per point)).
template <class Visit>
void for_each_node_crossing(const LatticeGrid& g, const BondList& bonds, Visit&& visit) {
  // floor(a / b) for b != 0.
  const auto floor_div = [](std::int64_t a, std::int64_t b) { return a / b - ((a % b != 0) && ((a < 0) != (b < 0))); };
  for (std::size_t j = 0; j < g.gx.size(); ++j)
    for (auto b = bonds.begin(j); b < bonds.end(j); ++b) {
      const auto k = std::size_t(bonds.neighbor[b]);
      for (int a = 0; a < 2; ++a) {
        const auto& ga = a == 0 ? g.gx : g.gy;
        const auto& go = a == 0 ? g.gy : g.gx;
        const std::int64_t p = std::int64_t(ga[k]) - ga[j], q = std::int64_t(go[k]) - go[j], ko = go[j];
        if (p == 0 || !of_type(a, p, q)) continue;
        const std::int64_t step = p > 0 ? 1 : -1;
        for (std::int64_t m = 0; m != p + step; m += step) {
          const std::int64_t a2 = 2 * m, line = ga[j] + m;
          // The crossing is y* = ko + a2 q / (2p) along the line; the centres within 1/2 of it
          // are floor(y*) and the one above.
          const std::int64_t below = ko + floor_div(a2 * q, 2 * p);
          for (std::int64_t c = below; c <= below + 1; ++c) {
            const double alpha = crossing_alpha(p, a2, 2 * p * (ko - c) + a2 * q);
            if (alpha == 0) continue;
            const auto i = a == 0 ? g.at(int(line), int(c)) : g.at(int(c), int(line));
            if (i >= 0) visit(std::size_t(i), std::size_t(b), alpha, j, a);
          }
        }
      }
    }
}

}  // namespace peridot

namespace peridot {

LatticeGrid lattice_grid(const PointCloud& pc) {
  if (pc.dim != 2) throw std::invalid_argument("lattice grid: only 2D clouds");
  if (pc.size() == 0 || !(pc.spacing > 0)) throw std::invalid_argument("lattice grid: need points and a spacing > 0");
  LatticeGrid g;
  g.h = pc.spacing;
  g.x0 = pc.x[0][0];
  g.y0 = pc.x[1][0];
  g.gx.resize(pc.size());
  g.gy.resize(pc.size());
  int hi[2] = {0, 0};
  g.lo[0] = g.lo[1] = 0;
  for (std::size_t i = 0; i < pc.size(); ++i) {
    const double fx = (pc.x[0][i] - g.x0) / g.h, fy = (pc.x[1][i] - g.y0) / g.h;
    const double rx = std::round(fx), ry = std::round(fy);
    if (std::abs(fx - rx) > 1e-6 || std::abs(fy - ry) > 1e-6 || std::abs(rx) > 1e8 || std::abs(ry) > 1e8)
      throw std::invalid_argument(fmt::format("lattice grid: point {} at ({:g}, {:g}) m is not on the lattice of spacing {:g} m", i, pc.x[0][i],
                                              pc.x[1][i], g.h));
    g.gx[i] = std::int32_t(rx);
    g.gy[i] = std::int32_t(ry);
    g.lo[0] = std::min(g.lo[0], g.gx[i]), g.lo[1] = std::min(g.lo[1], g.gy[i]);
    hi[0] = std::max(hi[0], g.gx[i]), hi[1] = std::max(hi[1], g.gy[i]);
  }
  g.n[0] = hi[0] - g.lo[0] + 1;
  g.n[1] = hi[1] - g.lo[1] + 1;
  g.id.assign(std::size_t(g.n[0]) * std::size_t(g.n[1]), -1);
  for (std::size_t i = 0; i < pc.size(); ++i) {
    auto& slot = g.id[std::size_t(g.gy[i] - g.lo[1]) * std::size_t(g.n[0]) + std::size_t(g.gx[i] - g.lo[0])];
    if (slot >= 0) throw std::invalid_argument(fmt::format("lattice grid: points {} and {} share a lattice site", slot, i));
    slot = std::int32_t(i);
  }
  return g;
}

}  // namespace peridot

export namespace peridot {

// The cell-centred lattice of the rectangle [lo, hi] (its sides multiples of h), real points
// first (Role::interior, row by row from lo), then `layers` rings of fictitious points
// (Role::fictitious) around it, corners included (seed 004 Sec. 3.1).
PointCloud rectangle_with_layer(const Vec3& lo, const Vec3& hi, double h, int layers);
// The points of rectangle_with_layer at the sites of `box` only ([x0, x1) x [y0, y1) in sites of
// the grown rectangle, whose site (0, 0) is its lower-left fictitious corner), in the same order
// and bit for bit: a rank's part on N ranks. `ids` gets each point's index in the whole cloud,
// `sites` its site x + (nx + 2 layers) y.
PointCloud rectangle_with_layer_part(const Vec3& lo, const Vec3& hi, double h, int layers, const std::array<std::int64_t, 4>& box,
                                     std::vector<std::int64_t>* ids = nullptr, std::vector<std::int64_t>* sites = nullptr);
// The cells of the rectangle [lo, hi] along x and y; throws std::invalid_argument unless its sides
// are whole multiples of h.
std::array<std::int64_t, 2> rectangle_cells(const Vec3& lo, const Vec3& hi, double h);

}  // namespace peridot

namespace peridot {

std::array<std::int64_t, 2> rectangle_cells(const Vec3& lo, const Vec3& hi, double h) {
  if (!(h > 0)) throw std::invalid_argument("rectangle with layer: need h > 0");
  const double fx = (hi[0] - lo[0]) / h, fy = (hi[1] - lo[1]) / h;
  const long nx = std::lround(fx), ny = std::lround(fy);
  if (nx < 1 || ny < 1 || std::abs(fx - double(nx)) > 1e-9 * fx || std::abs(fy - double(ny)) > 1e-9 * fy)
    throw std::invalid_argument(fmt::format("rectangle with layer: the sides {:g} m and {:g} m must be whole multiples of the spacing {:g} m", hi[0] - lo[0],
                                            hi[1] - lo[1], h));
  return {nx, ny};
}

PointCloud rectangle_with_layer(const Vec3& lo, const Vec3& hi, double h, int layers) {
  const auto [nx, ny] = rectangle_cells(lo, hi, h);
  return rectangle_with_layer_part(lo, hi, h, layers, {0, nx + 2 * layers, 0, ny + 2 * layers});
}

PointCloud rectangle_with_layer_part(const Vec3& lo, const Vec3& hi, double h, int layers, const std::array<std::int64_t, 4>& box,
                                     std::vector<std::int64_t>* ids, std::vector<std::int64_t>* sites) {
  if (layers < 0) throw std::invalid_argument("rectangle with layer: need layers >= 0");
  const auto [nx, ny] = rectangle_cells(lo, hi, h);
  if (double(nx + 2 * layers) * double(ny + 2 * layers) > 2e9) throw std::invalid_argument("rectangle with layer: more than 2e9 points");
  const std::int64_t L = layers, m0 = nx + 2 * L, m1 = ny + 2 * L;
  const std::int64_t x0 = std::max<std::int64_t>(box[0], 0), x1 = std::min(box[1], m0), y0 = std::max<std::int64_t>(box[2], 0), y1 = std::min(box[3], m1);
  PointCloud pc;
  pc.dim = 2;
  pc.spacing = h;
  const auto site = [&](std::int64_t x, std::int64_t y) { return Vec3{lo[0] + (double(x - L) + 0.5) * h, lo[1] + (double(y - L) + 0.5) * h, 0}; };
  const auto real = [&](std::int64_t x, std::int64_t y) { return x >= L && x < L + nx && y >= L && y < L + ny; };
  const auto add = [&](std::int64_t x, std::int64_t y, Role role, std::int64_t id) {
    pc.push_back(site(x, y), h * h, role);
    if (ids) ids->push_back(id);
    if (sites) sites->push_back(x + m0 * y);
  };
  // Real points first, row by row, then the fictitious ones, row by row over the grown rectangle.
  for (auto y = std::max(y0, L); y < std::min(y1, L + ny); ++y)
    for (auto x = std::max(x0, L); x < std::min(x1, L + nx); ++x) add(x, y, Role::interior, (y - L) * nx + (x - L));
  for (auto y = y0; y < y1; ++y) {
    // Fictitious points in the rows below y, and whether row y is all fictitious.
    const bool full_row = y < L || y >= L + ny;
    const std::int64_t before = y < L ? y * m0 : y < L + ny ? L * m0 + (y - L) * 2 * L : L * m0 + ny * 2 * L + (y - L - ny) * m0;
    for (auto x = x0; x < x1; ++x)
      if (!real(x, y)) add(x, y, Role::fictitious, nx * ny + before + (full_row || x < L ? x : x - nx));
  }
  return pc;
}

}  // namespace peridot
