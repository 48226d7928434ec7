module;
#include <stdint.h>  // SIZE_MAX
export module peridot.discretization:stencil;
import peridot.std;
import peridot.geometry;
import :point_cloud;
import :large_array;
import :neighbor_search;

export namespace peridot {

// Bonds of a body whose points sit on one lattice with equal volumes: every partner is a fixed
// lattice offset k, so there is no neighbour list. Reference bond vectors xi_k = k h, their
// lengths and quadrature weights are per-offset constants, and the only per-bond datum is one
// byte of state per (point, offset), stored offset-major within each grid row ([row][k][x]) so
// that a kernel vectorises over the points of a row for one offset at a time.
//
// Points live on a padded grid (pad = the stencil's reach on every side), so a partner site
// s + shift_k is always inside the grid; sites without a point have no bonds.
struct Stencil {
  static constexpr std::uint8_t exists = 2;  // the bond was created (so it counts in damage)
  static constexpr std::uint8_t intact = 1;  // it carries force; fracture clears only this bit

  int dim = 0;
  double h = 0;                            // lattice spacing [m]
  double horizon = 0;                      // delta [m]
  double volume = 0;                       // every point's volume [m^3, m^2 in 2D]
  int pad = 0;                             // reach of the stencil in lattice steps
  std::array<int, 3> n{1, 1, 1};           // index box of the points (x fastest)
  std::array<int, 3> padded{1, 1, 1};      // n + 2 pad in each used dimension
  std::vector<std::array<int, 3>> offset;  // k, lexicographic in (z, y, x)
  std::vector<std::int64_t> shift;         // site shift of offset k on the padded grid
  std::vector<double> length;              // |xi_k| = h |k| [m]
  std::vector<double> weight;              // volume x partial-volume factor of offset k
  LargeArray<std::int32_t> site_point;     // padded site -> point, or -1
  LargeArray<std::int64_t> point_site;     // point -> padded site
  LargeArray<std::uint8_t> state;          // [row][k][x < row_length()]: exists | intact bits
  LargeArray<std::uint8_t> no_fail;        // per padded site (and slack), empty when no point is no-fail
  // Rows whose bonds a pass over bonds (energies, the stable step) evaluates: all of them, except
  // on a rank of a distributed run, which evaluates only the rows of the points it owns (the
  // others are ghosts; see Slab).
  std::size_t row_begin = 0, row_end = SIZE_MAX;
  // The same rows in the force pass's visit order, which runs z fastest (v = z + n_z y), so that
  // a bond's two ends are at most reach (n_z + 1) rows apart in it (pmb_stencil.cppm).
  std::size_t visit_begin = 0, visit_end = SIZE_MAX;

  // Lanes per row and offset in `state`: n_x rounded up to 16, so a row's loop runs in whole
  // vectors (the lanes past n_x have no bonds). Grids keep `slack` sites past their end for it.
  static constexpr std::size_t lanes = 16;
  static constexpr std::size_t slack = lanes;
  std::size_t row_length() const { return (std::size_t(n[0]) + lanes - 1) / lanes * lanes; }

  bool empty() const { return offset.empty(); }
  std::size_t offsets() const { return offset.size(); }
  std::size_t rows() const { return std::size_t(n[1]) * std::size_t(n[2]); }
  std::size_t sites() const { return std::size_t(padded[0]) * std::size_t(padded[1]) * std::size_t(padded[2]); }
  std::size_t first_row() const { return std::min(row_begin, rows()); }
  std::size_t last_row() const { return std::min(row_end, rows()); }
  // Row of point i.
  std::size_t row_of(std::size_t i) const {
    const std::int64_t s = point_site[i], px = padded[0], py = padded[1];
    return std::size_t((s / px) % py - pad + std::int64_t(n[1]) * (s / (px * py) - (dim == 3 ? pad : 0)));
  }
  // Evaluate only the rows from the first to the last that holds one of `points` (the others'
  // forces and bond states are then left as they are).
  template <class Indices>
  void restrict_rows(const Indices& points) {
    row_begin = visit_begin = SIZE_MAX;
    row_end = visit_end = 0;
    for (auto i : points) {
      const std::size_t r = row_of(std::size_t(i)), v = visit_of_row(r);
      row_begin = std::min(row_begin, r);
      row_end = std::max(row_end, r + 1);
      visit_begin = std::min(visit_begin, v);
      visit_end = std::max(visit_end, v + 1);
    }
    if (row_begin > row_end) row_begin = row_end = visit_begin = visit_end = 0;
  }
  std::size_t first_visit() const { return std::min(visit_begin, rows()); }
  std::size_t last_visit() const { return std::min(visit_end, rows()); }
  // Row r = y + n_y z is visited v = z + n_z y-th, and back.
  std::size_t visit_of_row(std::size_t r) const {
    const auto ny = std::size_t(n[1]);
    return r / ny + std::size_t(n[2]) * (r % ny);
  }
  std::size_t row_of_visit(std::size_t v) const {
    const auto nz = std::size_t(n[2]);
    return v / nz + std::size_t(n[1]) * (v % nz);
  }
  // First padded site of row r = y + n_y z.
  std::int64_t row_site(std::size_t r) const {
    const auto y = std::int64_t(r % std::size_t(n[1])), z = std::int64_t(r / std::size_t(n[1]));
    const std::int64_t pz = dim == 3 ? pad : 0;
    return pad + std::int64_t(padded[0]) * ((y + pad) + std::int64_t(padded[1]) * (z + pz));
  }
  // States of row r: offset k of the row's point x at [k row_length() + x].
  const std::uint8_t* row_state(std::size_t r) const { return state.data() + r * offsets() * row_length(); }
  // Index into `state` of the bond of point i along offset k: state_base(i) + k row_length().
  std::size_t state_index(std::size_t i, std::size_t k) const { return state_base(i) + k * row_length(); }
  std::size_t state_base(std::size_t i) const {
    const std::int64_t s = point_site[i];
    const std::int64_t px = padded[0], py = padded[1];
    const std::int64_t x = s % px - pad, y = (s / px) % py - pad, z = s / (px * py) - (dim == 3 ? pad : 0);
    const auto row = std::size_t(y + std::int64_t(n[1]) * z);
    return row * offsets() * row_length() + std::size_t(x);
  }
  // Partner of point i along offset k, or -1.
  std::int32_t partner(std::size_t i, std::size_t k) const { return site_point[std::size_t(point_site[i] + shift[k])]; }

  // Directed bonds created (intact or not), and those broken.
  std::size_t size() const;
  std::size_t broken() const;
  std::size_t bytes() const;
  double bytes_per_bond() const { return size() ? double(bytes()) / double(size()) : 0.0; }
  // The fracture state per (point, offset), one byte each (exists | intact bits).
  std::span<std::uint8_t> states() { return {state.data(), state.size()}; }
  std::span<const std::uint8_t> states() const { return {state.data(), state.size()}; }
  static constexpr const char* name = "lattice stencil";
  const char* storage() const { return "lattice stencil: a state byte per point and offset"; }
};

// The stencil of a cloud, or nullopt with the reason in `why` when the points are not all on
// one lattice of spacing points.spacing (to 1e-9 h) with one volume. Bonds are those
// build_bonds(points, options) creates, and with `cut_cracks_broken` the bonds crossing
// options.cracks exist but start broken (as cut_bonds leaves them) instead of not existing.
// The stencil's reach in lattice steps: the farthest lattice offset a bond spans.
int stencil_reach(const BondOptions& options, int dim, double spacing);

std::optional<Stencil> build_stencil(const PointCloud& points, const BondOptions& options, bool cut_cracks_broken, std::string& why);

// Marks the no-fail points (nonzero entries of `no_fail`, per point) on the padded grid.
void set_no_fail(Stencil& stencil, const std::vector<std::uint8_t>& no_fail);

}  // namespace peridot

namespace peridot {

std::size_t Stencil::size() const {
  std::size_t c = 0;
#pragma omp parallel for schedule(static) reduction(+ : c)
  for (std::int64_t b = 0; b < std::int64_t(state.size()); ++b) c += (state[std::size_t(b)] & exists) != 0;
  return c;
}

std::size_t Stencil::broken() const {
  std::size_t c = 0;
#pragma omp parallel for schedule(static) reduction(+ : c)
  for (std::int64_t b = 0; b < std::int64_t(state.size()); ++b) c += state[std::size_t(b)] == exists;
  return c;
}

std::size_t Stencil::bytes() const {
  return state.capacity() + no_fail.capacity() + site_point.capacity() * sizeof(std::int32_t) +
         point_site.capacity() * sizeof(std::int64_t) + offset.capacity() * (sizeof(offset[0]) + sizeof(std::int64_t) + 2 * sizeof(double));
}

int stencil_reach(const BondOptions& o, int dim, double spacing) { return int(std::floor(bond_cutoff(o, dim, spacing) / spacing)); }

std::optional<Stencil> build_stencil(const PointCloud& pc, const BondOptions& o, bool cut_cracks_broken, std::string& why) {
  const double h = pc.spacing;
  const std::size_t np = pc.size();
  if (!(h > 0) || np == 0) {
    why = "no lattice spacing";
    return std::nullopt;
  }
  if (pc.dim != 2 && pc.dim != 3) {
    why = "only 2D and 3D bodies";
    return std::nullopt;
  }
  Stencil st;
  st.dim = pc.dim;
  st.h = h;
  st.horizon = o.horizon;
  st.volume = pc.volume[0];
  // Integer coordinates relative to point 0.
  std::array<std::vector<std::int32_t>, 3> g;
  std::array<std::int64_t, 3> lo{0, 0, 0}, hi{0, 0, 0};
  for (int c = 0; c < pc.dim; ++c) {
    g[c].resize(np);
    const double x0 = pc.x[c][0];
    std::int64_t mn = 0, mx = 0;
    for (std::size_t i = 0; i < np; ++i) {
      const double t = (pc.x[c][i] - x0) / h, r = std::round(t);
      if (std::abs(t - r) > 1e-9 || std::abs(r) > 1e8) {
        why = "the points are not on one lattice";
        return std::nullopt;
      }
      g[c][i] = std::int32_t(r);
      mn = std::min<std::int64_t>(mn, g[c][i]);
      mx = std::max<std::int64_t>(mx, g[c][i]);
    }
    lo[c] = mn;
    hi[c] = mx;
  }
  for (std::size_t i = 0; i < np; ++i)
    if (pc.volume[i] != st.volume) {
      why = "the point volumes differ";
      return std::nullopt;
    }
  // The offsets build_bonds would find, with its cutoff and quadrature factors.
  const double cutoff = bond_cutoff(o, pc.dim, h);
  st.pad = stencil_reach(o, pc.dim, h);
  for (int c = 0; c < pc.dim; ++c) {
    st.n[c] = int(hi[c] - lo[c] + 1);
    st.padded[c] = st.n[c] + 2 * st.pad;
  }
  const double sites = double(st.padded[0]) * st.padded[1] * st.padded[2];
  if (sites > 2e9 || sites > 8.0 * double(np) + 1e6) {
    why = "the lattice box is mostly empty";
    return std::nullopt;
  }
  const int R = st.pad, rz = pc.dim == 3 ? R : 0;
  for (int z = -rz; z <= rz; ++z)
    for (int y = -R; y <= R; ++y)
      for (int x = -R; x <= R; ++x) {
        if (x == 0 && y == 0 && z == 0) continue;
        const double dx = x * h, dy = y * h, dz = z * h;
        if (dx * dx + dy * dy + dz * dz > cutoff * cutoff) continue;
        const double f = partner_volume_factor(o, pc.dim, h, dx, dy, dz);
        if (f == 0.0) continue;
        st.offset.push_back({x, y, z});
        st.shift.push_back(x + std::int64_t(st.padded[0]) * (y + std::int64_t(st.padded[1]) * z));
        st.length.push_back(std::sqrt(dx * dx + dy * dy + dz * dz));
        st.weight.push_back(st.volume * f);
      }
  const std::size_t K = st.offsets(), nx = std::size_t(st.n[0]), stride = st.row_length();
  st.site_point.resize(std::size_t(sites));
  std::fill(st.site_point.begin(), st.site_point.end(), -1);
  st.point_site.resize(np);
  for (std::size_t i = 0; i < np; ++i) {
    const std::int64_t gz = pc.dim == 3 ? g[2][i] - lo[2] + rz : 0;
    const std::int64_t s = (g[0][i] - lo[0] + R) + std::int64_t(st.padded[0]) * ((g[1][i] - lo[1] + R) + std::int64_t(st.padded[1]) * gz);
    if (st.site_point[std::size_t(s)] >= 0) {
      why = "two points share a lattice site";
      return std::nullopt;
    }
    st.site_point[std::size_t(s)] = std::int32_t(i);
    st.point_site[i] = s;
  }
  st.state.resize(st.rows() * K * stride);
  std::vector<Aabb> near;  // as build_bonds: only points near a crack test their bonds
  for (const auto& c : o.cracks) near.push_back(crack_box(c, 2 * cutoff));
  const auto rows = std::int64_t(st.rows());
#pragma omp parallel for schedule(static)
  for (std::int64_t r = 0; r < rows; ++r) {
    const std::int64_t s0 = st.row_site(std::size_t(r));
    std::vector<std::uint8_t> test(nx, 0);
    for (std::size_t x = 0; x < nx; ++x) {
      const auto i = st.site_point[std::size_t(s0 + std::int64_t(x))];
      if (i >= 0)
        for (const auto& box : near) test[x] = test[x] || inside(box, pc.position(std::size_t(i)));
    }
    for (std::size_t k = 0; k < K; ++k) {
      std::uint8_t* row = st.state.data() + (std::size_t(r) * K + k) * stride;
      std::fill(row + nx, row + stride, std::uint8_t(0));
      for (std::size_t x = 0; x < nx; ++x) {
        const auto i = st.site_point[std::size_t(s0 + std::int64_t(x))];
        const auto j = i < 0 ? -1 : st.site_point[std::size_t(s0 + std::int64_t(x) + st.shift[k])];
        std::uint8_t b = j < 0 ? 0 : Stencil::exists | Stencil::intact;
        if (b && test[x] && crosses_any(o.cracks, pc.position(std::size_t(i)), pc.position(std::size_t(j))))
          b = cut_cracks_broken ? Stencil::exists : 0;
        row[x] = b;
      }
    }
  }
  return st;
}

void set_no_fail(Stencil& st, const std::vector<std::uint8_t>& no_fail) {
  st.no_fail.clear();
  if (std::none_of(no_fail.begin(), no_fail.end(), [](std::uint8_t v) { return v != 0; })) return;
  st.no_fail.resize(st.sites() + Stencil::slack);
  std::fill(st.no_fail.begin(), st.no_fail.end(), std::uint8_t(0));
  for (std::size_t i = 0; i < no_fail.size(); ++i)
    if (no_fail[i]) st.no_fail[std::size_t(st.point_site[i])] = 1;
}

}  // namespace peridot
