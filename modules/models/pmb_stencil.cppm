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
// Each bond is evaluated once. Rows are visited z fastest (v = z + n_z y), and a bond is
// evaluated from the end whose row comes first in that order (its "forward" offset k; the other
// end holds it as the mirror offset -k). The pair force goes to the near end's sums and, negated,
// to the far end's row, which lies at most H = reach (n_z + 1) rows ahead: each thread keeps the
// double sums of the H + 1 rows ahead of it in a ring, and a row's forces are complete once the
// row itself has been evaluated. Both ends of a bond see eta and -eta and xi and -xi, which give
// bitwise-equal products, so the far end's term is exactly the negated near-end one and the
// sum is the one a two-sided evaluation would form, in another order.
//
// Thread and rank independence. A point's terms arrive in a fixed order: source rows in visit
// order, offsets in plan order within a source row, and every float partial sum starts and ends
// at the same places (the plan's groups). A thread whose rows start at visit row c0 first
// evaluates rows c0 - H to c0 - 1 again, adding only into its ring, so its rows receive every
// term in the same order as on one thread; a rank does the same with the ghost rows below its
// own (whose displacements it holds: the ghost layers are the stencil's reach deep). Bond states
// are written after every thread's pass (both ends' bytes), so no pass reads a byte another
// thread is writing.
//
// Single precision, and why it is safe. Displacements are rounded to float on the padded grid
// and each bond is evaluated in float from eta = u_j - u_i, never from positions: the stretch
// is s = (2 xi.eta + eta.eta) / (L (|y| + L)), |y|^2 = L^2 + 2 xi.eta + eta.eta, which has no
// cancellation, so s carries a relative error of a few float ulps (~1e-7 s) plus the rounding of
// u itself, |u| 2^-24 / L: for a 0.25 mm bond and |u| = 1 mm that is 2e-7, against s0 = 2e-4 for
// glass at delta = 1 mm. Break decisions can therefore differ from the double CSR path only for
// bonds within ~1e-3 s0 of the threshold. Pair forces are summed in float over at most 16
// offsets at a time (a point's own forward offsets) or one group (the at most 2 reach + 1
// offsets that reach one partner row), then in double.
export namespace peridot::stencil_kernel {

// Forward offsets that reach one partner row: dy and dz fixed, dx ascending.
struct PairGroup {
  int dy = 0, dz = 0;
  std::size_t ahead = 0;            // visit rows from the source row to the partner row
  std::uint32_t first = 0, last = 0;  // range in Scratch::forward
  bool flush_own = false;           // the own float sums join the double ones after this group
};

// One thread's sums: the double forces of the rows ahead (a ring of H + 1 rows of 3 x lanes),
// the float partial sums, and the bonds that broke in its rows, written after the pass.
struct ThreadSums {
  LargeArray<double> ring;
  std::vector<float> acc;
  std::vector<std::uint32_t> broke_row;                     // per source row: offsets that broke a bond
  std::vector<std::pair<std::size_t, std::uint32_t>> broke;  // (visit row, forward offset)
  std::vector<double*> partner;                             // per group: the partner row's sums
};

struct Scratch {
  LargeArray<float> u;  // 3 components on the padded grid, zero off the body
  std::size_t sites = 0;
  std::vector<float> ex, ey, ez, len, cw;  // per offset: xi_k, |xi_k|, c w_k
  // The pair plan, for one stencil shape.
  std::array<std::size_t, 4> plan_of{};  // offsets, lanes, n_y, n_z
  std::vector<std::uint32_t> forward;    // forward offsets, grouped
  std::vector<std::uint32_t> mirror;     // offset k -> the offset -k
  std::vector<std::int32_t> dx;          // per offset
  std::vector<PairGroup> groups;
  std::size_t ahead = 0;  // H: the farthest partner row, in visit rows
  std::vector<ThreadSums> threads;
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

// Own offsets summed in float before their sum joins the double total: float vectors are twice
// as wide, and a 16-term float sum adds at most ~4 ulps to a force that then accumulates in double.
constexpr std::size_t offsets_per_flush = 16;

// The forward offsets grouped by partner row, for the stencil's offsets and grid shape. Flush
// points depend on the plan only, never on which groups a row skips, so every row of every rank
// sums its own terms in the same partial sums.
void plan_pairs(const Stencil& st, Scratch& s) {
  const std::array<std::size_t, 4> shape{st.offsets(), st.row_length(), std::size_t(st.n[1]), std::size_t(st.n[2])};
  if (s.plan_of == shape && !s.groups.empty()) return;
  s.plan_of = shape;
  const std::size_t K = st.offsets();
  s.mirror.assign(K, 0);
  s.dx.assign(K, 0);
  std::map<std::array<int, 3>, std::uint32_t> index;
  for (std::size_t k = 0; k < K; ++k) index[st.offset[k]] = std::uint32_t(k);
  std::map<std::array<int, 2>, std::vector<std::uint32_t>> by_row;  // (dy, dz) -> forward offsets, dx ascending
  for (std::size_t k = 0; k < K; ++k) {
    const auto& o = st.offset[k];
    const auto m = index.find({-o[0], -o[1], -o[2]});
    if (m == index.end()) throw std::logic_error("stencil: an offset without its mirror");
    s.mirror[k] = m->second;
    s.dx[k] = o[0];
    if (o[1] > 0 || (o[1] == 0 && (o[2] > 0 || (o[2] == 0 && o[0] > 0)))) by_row[{o[1], o[2]}].push_back(std::uint32_t(k));
  }
  s.forward.clear();
  s.groups.clear();
  s.ahead = 0;
  const auto nz = std::size_t(st.n[2]);
  std::size_t since_flush = 0;
  for (auto& [d, ks] : by_row) {
    std::sort(ks.begin(), ks.end(), [&](auto a, auto b) { return st.offset[a][0] < st.offset[b][0]; });
    if (since_flush + ks.size() > offsets_per_flush && !s.groups.empty()) {
      s.groups.back().flush_own = true;
      since_flush = 0;
    }
    // A group whose rows are |dz| >= n_z layers apart never has both ends on the grid (a body
    // thinner than the reach): it adds nothing to the ring's reach.
    const bool on_some_row = std::abs(d[1]) < std::int64_t(nz);
    PairGroup g{d[0], d[1], on_some_row ? std::size_t(std::int64_t(d[1]) + std::int64_t(nz) * d[0]) : 0, std::uint32_t(s.forward.size()), 0,
                false};
    s.forward.insert(s.forward.end(), ks.begin(), ks.end());
    g.last = std::uint32_t(s.forward.size());
    s.ahead = std::max(s.ahead, g.ahead);
    s.groups.push_back(g);
    since_flush += ks.size();
  }
  if (!s.groups.empty()) s.groups.back().flush_own = true;
}

// Everything one row's pass reads: the grids, the per-offset constants and the plan.
struct RowPass {
  const float *ux, *uy, *uz;  // padded grids
  const std::uint8_t* nf;     // padded no-fail flags, or null
  const float *ex, *ey, *ez, *len, *cw;
  const std::int64_t* shift;
  const std::int32_t* dx;
  const std::uint32_t* forward;
  const PairGroup* groups;
  std::size_t G, nx, pad;  // groups, lanes per row (whole vectors), the stencil's reach
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

// One source row: its forward bonds, group by group, vectorised over the row. `self` is the
// row's double sums, partner[g] the partner row's for group g (null where that row is off the
// grid, so the group has no bonds). Returns the bonds it broke; the offsets where any broke go
// to `broke` (count in n_broke) for the state pass.
template <bool NoFail>
[[gnu::always_inline]] inline int row_pairs(const RowPass& p, std::int64_t base, const std::uint8_t* state, double* self, double* const* partner,
                                            float* acc, std::uint32_t* broke, std::size_t& n_broke) {
  const std::size_t nx = p.nx, wide = nx + 2 * p.pad;
  float* ox = acc;
  float* oy = ox + nx;
  float* oz = oy + nx;
  float* tx = oz + nx;  // the partner row's terms at lane x + dx, with pad lanes either side
  float* ty = tx + wide;
  float* tz = ty + wide;
  for (std::size_t x = 0; x < nx; ++x) ox[x] = oy[x] = oz[x] = 0;
  int snapped = 0;
  for (std::size_t g = 0; g < p.G; ++g) {
    const PairGroup& grp = p.groups[g];
    double* far = partner[g];
    if (far) {
      for (std::size_t x = 0; x < wide; ++x) tx[x] = ty[x] = tz[x] = 0;
      for (std::uint32_t q = grp.first; q < grp.last; ++q) {
        const std::uint32_t k = p.forward[q];
        const std::uint8_t* st = state + std::size_t(k) * nx;
        const std::int64_t t = base + p.shift[k];
        const float e0 = p.ex[k], e1 = p.ey[k], e2 = p.ez[k], L = p.len[k], cwk = p.cw[k];
        float* fx = tx + std::int64_t(p.pad) + p.dx[k];
        float* fy = ty + std::int64_t(p.pad) + p.dx[k];
        float* fz = tz + std::int64_t(p.pad) + p.dx[k];
        int snapped_k = 0;
#pragma omp simd reduction(+ : snapped_k)
        for (std::size_t x = 0; x < nx; ++x) {
          const Lane l = lane<NoFail>(p, base, t, x, st[x], e0, e1, e2, L);
          snapped_k += l.snap;
          const int now = l.alive & (l.snap ^ 1);
          const float kb = now ? l.bond.force_factor(cwk) : 0.0f;
          const float px = kb * (e0 + l.h0), py = kb * (e1 + l.h1), pz = kb * (e2 + l.h2);
          ox[x] += px;
          oy[x] += py;
          oz[x] += pz;
          fx[x] -= px;
          fy[x] -= py;
          fz[x] -= pz;
        }
        if (snapped_k) {
          broke[n_broke++] = k;
          snapped += snapped_k;
        }
      }
      for (std::size_t x = 0; x < nx; ++x) {
        far[x] += double(tx[p.pad + x]);
        far[nx + x] += double(ty[p.pad + x]);
        far[2 * nx + x] += double(tz[p.pad + x]);
      }
    }
    if (grp.flush_own) {
      for (std::size_t x = 0; x < nx; ++x) {
        self[x] += double(ox[x]);
        self[nx + x] += double(oy[x]);
        self[2 * nx + x] += double(oz[x]);
        ox[x] = oy[x] = oz[x] = 0;
      }
    }
  }
  return snapped;
}

// The bonds of source row `base` along forward offset k that broke in this pass, decided again
// the same way, cleared at both ends: `state` is the row's byte row for k, `mirror` the partner
// row's for -k.
template <bool NoFail>
[[gnu::always_inline]] inline void clear_broken(const RowPass& p, std::int64_t base, std::uint32_t k, std::uint8_t* state, std::uint8_t* mirror) {
  const std::int64_t t = base + p.shift[k];
  for (std::size_t x = 0; x < p.nx; ++x) {
    const int b = state[x];
    if (lane<NoFail>(p, base, t, x, b, p.ex[k], p.ey[k], p.ez[k], p.len[k]).snap) {
      state[x] = std::uint8_t(b & ~1);
      mirror[std::int64_t(x) + p.dx[k]] &= std::uint8_t(~1);
    }
  }
}

// Built for AVX-512, AVX2 and the baseline, picked at load time, so a portable build runs at the
// width of the machine: float vectors are what the row loop is made of. A pass's state writes
// run in the same instruction set as its force loop, so they decide breaks with the same bits.
[[gnu::target_clones("avx512f", "avx2", "default")]] int row_pairs_plain(const RowPass& p, std::int64_t base, const std::uint8_t* state,
                                                                         double* self, double* const* partner, float* acc,
                                                                         std::uint32_t* broke, std::size_t& n_broke) {
  return row_pairs<false>(p, base, state, self, partner, acc, broke, n_broke);
}
[[gnu::target_clones("avx512f", "avx2", "default")]] int row_pairs_no_fail(const RowPass& p, std::int64_t base, const std::uint8_t* state,
                                                                           double* self, double* const* partner, float* acc,
                                                                           std::uint32_t* broke, std::size_t& n_broke) {
  return row_pairs<true>(p, base, state, self, partner, acc, broke, n_broke);
}
[[gnu::target_clones("avx512f", "avx2", "default")]] void clear_broken_plain(const RowPass& p, std::int64_t base, std::uint32_t k,
                                                                             std::uint8_t* state, std::uint8_t* mirror) {
  clear_broken<false>(p, base, k, state, mirror);
}
[[gnu::target_clones("avx512f", "avx2", "default")]] void clear_broken_no_fail(const RowPass& p, std::int64_t base, std::uint32_t k,
                                                                               std::uint8_t* state, std::uint8_t* mirror) {
  clear_broken<true>(p, base, k, state, mirror);
}

std::size_t forces(double c, double s0, Body& body, const VectorField& u, VectorField& f, Scratch& s) {
  Stencil& st = body.stencil;
  // Chosen once per pass: the no-fail test costs two byte loads per bond when there is a grid.
  const bool no_fail = !st.no_fail.empty();
  const auto row_pairs_of = no_fail ? row_pairs_no_fail : row_pairs_plain;
  const auto clear_broken_of = no_fail ? clear_broken_no_fail : clear_broken_plain;
  pack(body, u, s);
  plan_pairs(st, s);
  const std::size_t K = st.offsets(), nx = st.row_length(), n_real = std::size_t(st.n[0]), ns = st.sites();
  const auto ny = std::size_t(st.n[1]), nz = std::size_t(st.n[2]);
  const std::size_t v0 = st.first_visit(), v1 = st.last_visit(), H = s.ahead, G = s.groups.size();
  const std::size_t slot = 3 * nx, wide = nx + 2 * std::size_t(st.pad);
  const int threads = omp_get_max_threads();
  if (s.threads.size() < std::size_t(threads)) s.threads.resize(std::size_t(threads));
  for (auto& t : s.threads) {
    if (t.ring.size() != (H + 1) * slot) t.ring.resize((H + 1) * slot);
    t.acc.resize(3 * (nx + wide) + 2 * Stencil::lanes);
    t.broke_row.resize(K);
    t.partner.resize(s.groups.size());
  }
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
                  s.len.data(),  s.cw.data(),  st.shift.data(),    s.dx.data(),       s.forward.data(), s.groups.data(),
                  G,             nx,           std::size_t(st.pad), float(s0)};
  const std::int32_t* site_point = st.site_point.data();
  std::size_t broken = 0;
#pragma omp parallel reduction(+ : broken)
  {
    ThreadSums& my = s.threads[std::size_t(omp_get_thread_num())];
    const auto T = std::size_t(omp_get_num_threads()), id = std::size_t(omp_get_thread_num());
    const std::size_t c0 = v0 + (v1 - v0) * id / T, c1 = v0 + (v1 - v0) * (id + 1) / T;
    // Rows below c0 that reach into it: the previous thread's (evaluated again, their bonds'
    // states left to it) or, below the rank's first row, the ghosts' (whose states are this
    // rank's to keep, so the first thread writes them).
    const std::size_t start = c0 > H ? c0 - H : 0, writes_from = id == 0 ? start : c0;
    std::fill(my.ring.begin(), my.ring.end(), 0.0);
    my.broke.clear();
    for (std::size_t v = start; v < c1; ++v) {
      const std::size_t r = st.row_of_visit(v), y = v / nz, z = v % nz;
      const std::int64_t base = st.row_site(r);
      double* self = my.ring.data() + (v % (H + 1)) * slot;
      for (std::size_t g = 0; g < G; ++g) {
        const PairGroup& grp = s.groups[g];
        const bool on_grid = y + std::size_t(grp.dy) < ny && std::int64_t(z) + grp.dz >= 0 && std::int64_t(z) + grp.dz < std::int64_t(nz);
        my.partner[g] = on_grid ? my.ring.data() + ((v + grp.ahead) % (H + 1)) * slot : nullptr;
      }
      std::size_t n_broke = 0;
      const int snapped = row_pairs_of(p, base, st.state.data() + r * K * nx, self, my.partner.data(), my.acc.data(), my.broke_row.data(), n_broke);
      if (v >= writes_from) {
        broken += 2 * std::size_t(snapped);  // both directions of each pair
        for (std::size_t b = 0; b < n_broke; ++b) my.broke.emplace_back(v, my.broke_row[b]);
      }
      if (v >= c0) {
        for (std::size_t x = 0; x < n_real; ++x) {
          const auto i = site_point[base + std::int64_t(x)];
          if (i < 0) continue;
          f[0][std::size_t(i)] = self[x];
          f[1][std::size_t(i)] = self[nx + x];
          f[2][std::size_t(i)] = self[2 * nx + x];
        }
      }
      std::fill(self, self + slot, 0.0);  // the ring's slot for row v + H + 1
    }
#pragma omp barrier
    for (const auto& [v, k] : my.broke) {
      const std::size_t r = st.row_of_visit(v), y = v / nz, z = v % nz;
      const std::size_t rt = (y + std::size_t(st.offset[k][1])) + ny * std::size_t(std::int64_t(z) + st.offset[k][2]);
      clear_broken_of(p, st.row_site(r), k, st.state.data() + (r * K + k) * nx, st.state.data() + (rt * K + s.mirror[k]) * nx);
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
