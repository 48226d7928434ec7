module;

#include <omp.h>

#include "pmb_float_bond.h"
export module peridot.models:pmb_stencil;
import peridot.std;
import :body;
import :pmb_bond;

// PMB on a lattice stencil (Stencil): the bond loop runs over the points of a grid row for one
// offset at a time, so partners are contiguous, xi_k, |xi_k| and c w_k are constants of the loop
// and the only per-bond memory traffic is the state byte.
//
// Single precision, and why it is safe. Displacements are rounded to float on the padded grid
// and each bond is evaluated in float from eta = u_j - u_i, never from positions: the stretch
// is s = (2 xi.eta + eta.eta) / (L (|y| + L)), |y|^2 = L^2 + 2 xi.eta + eta.eta, which has no
// cancellation, so s carries a relative error of a few float ulps (~1e-7 s) plus the rounding of
// u itself, |u| 2^-24 / L: for a 0.25 mm bond and |u| = 1 mm that is 2e-7, against s0 = 2e-4 for
// glass at delta = 1 mm. Break decisions can therefore differ from the double CSR path only for
// bonds within ~1e-3 s0 of the threshold. Pair forces are summed in float over 16 offsets at a
// time, then in double.
//
// Both directions of a bond see eta and -eta and xi and -xi, which give bitwise-equal products
// and sums in the same order, so both break in the same step. Each row sums its own points'
// bonds in offset order, so results do not depend on the thread count.
export namespace peridot::stencil_kernel {

struct Scratch {
  LargeArray<float> u;     // 3 components on the padded grid, zero off the body
  LargeArray<double> f;    // per thread: 3 rows of force sums
  std::size_t sites = 0;
  std::vector<float> ex, ey, ez, len, cw;  // per offset: xi_k, |xi_k|, c w_k
};

// Rounds u to float on the padded grid (sized and zeroed on first use).
void pack(const Body& body, const VectorField& u, Scratch& s) {
  const Stencil& st = body.stencil;
  const std::size_t ns = st.sites();
  if (s.sites != ns) {
    s.u.resize(3 * ns + Stencil::slack);
    std::fill(s.u.begin(), s.u.end(), 0.0f);
    s.sites = ns;
  }
  const auto n = std::int64_t(body.size());
  float* g = s.u.data();
#pragma omp parallel for schedule(static)
  for (std::int64_t i = 0; i < n; ++i) {
    const auto site = std::size_t(st.point_site[std::size_t(i)]);
    for (int c = 0; c < 3; ++c) g[std::size_t(c) * ns + site] = float(u[c][std::size_t(i)]);
  }
}

// Offsets summed in float before their sum joins the double total: float vectors are twice as
// wide, and a 16-term float sum adds at most ~4 ulps to a force that then accumulates in double.
constexpr std::size_t offsets_per_flush = 16;

// Everything one row's pass reads: the row's first site, its float force buffers, the grids.
struct RowPass {
  const float *ux, *uy, *uz;      // padded grids
  const std::uint8_t* nf;         // padded no-fail flags, or null
  const float *ex, *ey, *ez, *len, *cw;
  const std::int64_t* shift;
  std::size_t K, nx;  // offsets, and lanes per row (whole vectors)
  float crit;
};

// Bond x of a row along one offset (pmb_float_bond.h) from the float grids, and whether the bond
// is intact (bit 0 of its state) and breaks now.
struct Lane {
  PmbFloatBond bond;
  float h0, h1, h2;
  int alive, snap;
};

template <bool NoFail>
[[gnu::always_inline]] inline Lane lane(const RowPass& p, std::int64_t base, std::int64_t t, std::size_t x, int b, float e0, float e1, float e2,
                                        float L) {
  Lane l;
  l.h0 = p.ux[t + std::int64_t(x)] - p.ux[base + std::int64_t(x)];
  l.h1 = p.uy[t + std::int64_t(x)] - p.uy[base + std::int64_t(x)];
  l.h2 = p.uz[t + std::int64_t(x)] - p.uz[base + std::int64_t(x)];
  l.bond = pmb_float_bond(L, L * L, e0, e1, e2, l.h0, l.h1, l.h2);
  const int breakable = NoFail ? !(p.nf[base + std::int64_t(x)] | p.nf[t + std::int64_t(x)]) : 1;
  l.alive = b & 1;
  l.snap = l.alive & breakable & int(l.bond.breaks(p.crit));
  return l;
}

// One grid row: the bonds of its points, offset by offset, vectorised over the row. Returns
// the bonds it broke. The state bytes are read in the force loop and written only for the
// offsets where a bond broke, by a second loop that decides them again the same way: breaks are
// rare, and writing every state byte back each step was a fifth of the pass at 512k points.
template <bool NoFail>
[[gnu::always_inline]] inline int row_forces(const RowPass& p, std::int64_t base, std::uint8_t* state, float* acc, double* fx, double* fy,
                                             double* fz) {
  const std::size_t nx = p.nx;
  float* ax = acc;
  float* ay = acc + nx;
  float* az = acc + 2 * nx;
  for (std::size_t x = 0; x < nx; ++x) fx[x] = fy[x] = fz[x] = 0;
  int snapped = 0;
  for (std::size_t k0 = 0; k0 < p.K; k0 += offsets_per_flush) {
    for (std::size_t x = 0; x < nx; ++x) ax[x] = ay[x] = az[x] = 0;
    const std::size_t k1 = std::min(p.K, k0 + offsets_per_flush);
    for (std::size_t k = k0; k < k1; ++k) {
      std::uint8_t* st = state + k * nx;
      const std::int64_t t = base + p.shift[k];
      const float e0 = p.ex[k], e1 = p.ey[k], e2 = p.ez[k], L = p.len[k], cwk = p.cw[k];
      int snapped_k = 0;
#pragma omp simd reduction(+ : snapped_k)
      for (std::size_t x = 0; x < nx; ++x) {
        const Lane l = lane<NoFail>(p, base, t, x, st[x], e0, e1, e2, L);
        snapped_k += l.snap;
        const int now = l.alive & (l.snap ^ 1);
        const float kb = now ? l.bond.force_factor(cwk) : 0.0f;
        ax[x] += kb * (e0 + l.h0);
        ay[x] += kb * (e1 + l.h1);
        az[x] += kb * (e2 + l.h2);
      }
      if (snapped_k) {
        for (std::size_t x = 0; x < nx; ++x) {
          const int b = st[x];
          st[x] = std::uint8_t(b & ~lane<NoFail>(p, base, t, x, b, e0, e1, e2, L).snap);
        }
        snapped += snapped_k;
      }
    }
    for (std::size_t x = 0; x < nx; ++x) {
      fx[x] += double(ax[x]);
      fy[x] += double(ay[x]);
      fz[x] += double(az[x]);
    }
  }
  return snapped;
}

// Built for AVX-512, AVX2 and the baseline, picked at load time, so a portable build runs at the
// width of the machine: float vectors are what the row loop is made of.
[[gnu::target_clones("avx512f", "avx2", "default")]] int row_forces_plain(const RowPass& p, std::int64_t base, std::uint8_t* state,
                                                                          float* acc, double* fx, double* fy, double* fz) {
  return row_forces<false>(p, base, state, acc, fx, fy, fz);
}
[[gnu::target_clones("avx512f", "avx2", "default")]] int row_forces_no_fail(const RowPass& p, std::int64_t base, std::uint8_t* state,
                                                                            float* acc, double* fx, double* fy, double* fz) {
  return row_forces<true>(p, base, state, acc, fx, fy, fz);
}

std::size_t forces(double c, double s0, Body& body, const VectorField& u, VectorField& f, Scratch& s) {
  Stencil& st = body.stencil;
  // Chosen once per pass: the no-fail test costs two byte loads per bond when there is a grid.
  const auto row_forces_of = st.no_fail.empty() ? row_forces_plain : row_forces_no_fail;
  pack(body, u, s);
  const std::size_t K = st.offsets(), nx = st.row_length(), n_real = std::size_t(st.n[0]), ns = st.sites();
  const auto r0 = std::int64_t(st.first_row()), r1 = std::int64_t(st.last_row());
  const int threads = omp_get_max_threads();
  const std::size_t per_thread = 3 * nx * (sizeof(double) + sizeof(float)) / sizeof(double) + 8;
  if (s.f.size() < std::size_t(threads) * per_thread) s.f.resize(std::size_t(threads) * per_thread);
  if (s.cw.size() != K) {
    s.ex.resize(K), s.ey.resize(K), s.ez.resize(K), s.len.resize(K), s.cw.resize(K);
    for (std::size_t k = 0; k < K; ++k) {
      s.ex[k] = float(st.offset[k][0] * st.h);
      s.ey[k] = float(st.offset[k][1] * st.h);
      s.ez[k] = float(st.offset[k][2] * st.h);
      s.len[k] = float(st.length[k]);
      s.cw[k] = float(c * st.weight[k]);
    }
  }
  const RowPass p{s.u.data(), s.u.data() + ns, s.u.data() + 2 * ns, st.no_fail.data(), s.ex.data(), s.ey.data(), s.ez.data(),
                  s.len.data(),  s.cw.data(),  st.shift.data(),    K,            nx,         float(s0)};
  const std::int32_t* site_point = st.site_point.data();
  std::size_t broken = 0;
#pragma omp parallel reduction(+ : broken)
  {
    double* fx = s.f.data() + std::size_t(omp_get_thread_num()) * per_thread;
    double* fy = fx + nx;
    double* fz = fy + nx;
    float* acc = reinterpret_cast<float*>(fz + nx);
#pragma omp for schedule(static)
    for (std::int64_t r = r0; r < r1; ++r) {
      const std::int64_t base = st.row_site(std::size_t(r));
      std::uint8_t* state = st.state.data() + std::size_t(r) * K * nx;
      broken += std::size_t(row_forces_of(p, base, state, acc, fx, fy, fz));
      for (std::size_t x = 0; x < n_real; ++x) {  // lanes past n_x reach into the next row's sites
        const auto i = site_point[base + std::int64_t(x)];
        if (i < 0) continue;
        f[0][std::size_t(i)] = fx[x];
        f[1][std::size_t(i)] = fy[x];
        f[2][std::size_t(i)] = fz[x];
      }
    }
  }
  return broken;
}

// Visits every intact bond row by row: visit(i, j, k) with points i and j along offset k.
template <class Visit>
void for_each_bond(const Stencil& st, std::uint8_t mask, std::int64_t r, Visit&& visit) {
  const std::size_t nx = std::size_t(st.n[0]), stride = st.row_length();
  const std::uint8_t* row = st.row_state(std::size_t(r));
  const std::int64_t base = st.row_site(std::size_t(r));
  for (std::size_t x = 0; x < nx; ++x) {
    const auto i = st.site_point[std::size_t(base) + x];
    if (i < 0) continue;
    for (std::size_t k = 0; k < st.offsets(); ++k)
      if ((row[k * stride + x] & mask) == mask) visit(std::size_t(i), std::size_t(st.site_point[std::size_t(base + st.shift[k]) + x]), k);
  }
}

// Each point's share of the strain energy, in double from the double displacements, as the CSR
// path does (energies are outside the hot loop). Rows a rank does not evaluate stay zero.
void point_energies(double c, const Body& body, const VectorField& u, std::vector<double>& per_point) {
  const Stencil& st = body.stencil;
  per_point.assign(body.size(), 0.0);
#pragma omp parallel for schedule(static)
  for (std::int64_t r = std::int64_t(st.first_row()); r < std::int64_t(st.last_row()); ++r)
    for_each_bond(st, Stencil::exists | Stencil::intact, r, [&](std::size_t i, std::size_t j, std::size_t k) {
      double r2 = 0;
      for (int a = 0; a < 3; ++a) {
        const double y = st.offset[k][std::size_t(a)] * st.h + (u[a][j] - u[a][i]);
        r2 += y * y;
      }
      per_point[i] += pmb_bond::energy(c, pmb_bond::stretch(r2, st.length[k]), st.length[k], st.weight[k]) * st.volume;
    });
}

double stable_time_step(double c, const Body& body) {
  const Stencil& st = body.stencil;
  std::vector<double> stiffness(body.size());
#pragma omp parallel for schedule(static)
  for (std::int64_t r = std::int64_t(st.first_row()); r < std::int64_t(st.last_row()); ++r)
    for_each_bond(st, Stencil::exists, r, [&](std::size_t i, std::size_t, std::size_t k) { stiffness[i] += pmb_bond::stiffness(c, st.weight[k], st.length[k]); });
  double dt = std::numeric_limits<double>::infinity();  // a min is exact: the same for any thread count
  for (double k : stiffness)
    if (k > 0) dt = std::min(dt, pmb_bond::stable_step(body.density, k));
  return dt;
}

}  // namespace peridot::stencil_kernel
