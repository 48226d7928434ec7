module;
#include "lean_kernel.h"

export module peridot.models:pmb;
import peridot.std;
import :body;
import :elastic;
import :pmb_bond;
import :pmb_stencil;
import :lean_records;

export namespace peridot {

// Prototype microelastic brittle (PMB) bond-based model (Silling & Askari 2005). Runs on a CSR
// bond list or, for lattice bodies, on a stencil (Body::stencil; see pmb_stencil.cppm).
// Pair force density f = c s w_j (y / |y|), s = (|y| - |xi|) / |xi|, broken for good once
// s > s0 unless either end is in a no-fail region.
struct Pmb {
  double c = 0;   // micromodulus [N/m^6] (2D: [N/m^5] per unit thickness)
  double s0 = 0;  // critical stretch [-]
  // delta [m]; from_elastic sets it. It fixes the fixed-point quantum of the single-precision
  // lean-list kernel (below), which a model without it (0) does not run.
  double horizon = 0;

  // How a lean bond list's forces are computed:
  //  single: in float, eight bonds at a time (AVX-512VL or AVX2 where the CPU has them, else a
  //          portable kernel; all give the same bits), the stencil's stretch formula on a fixed-point bond
  //          vector; see lean_kernel.cpp and tests/models/test_pmb_lean.cpp for its bound;
  //  avx2, portable: the single-precision kernel's AVX2 build even where AVX-512VL is there, and
  //          its portable one, for tests;
  //  exact: in double, the full list's arithmetic (the same stretches and breaks).
  enum class LeanKernel { single, avx2, portable, exact };
  LeanKernel lean_kernel = LeanKernel::single;

  // Micromodulus and critical stretch matched to E and G0 for a ball of radius delta:
  //  3D (nu = 1/4):           c = 18K/(pi delta^4), s0 = sqrt(5 G0 / (9 K delta)), K = E/(3(1-2nu))
  //                           (Silling & Askari 2005, eqs. 24 and 29)
  //  2D plane stress (1/3):   c = 9E/(pi delta^3),  s0 = sqrt(4 pi G0 / (9 E delta))
  //  2D plane strain (1/4):   c = 48E/(5 pi delta^3), s0 = sqrt(5 pi G0 / (12 E delta))
  //                           (Ha & Bobaru 2010; energy matching per unit thickness)
  static Pmb from_elastic(double youngs_modulus, double fracture_energy, double horizon, Kinematics k);

  ForceReport forces(Body& body, const VectorField& u, VectorField& f) const;
  double strain_energy(const Body& body, const VectorField& u) const;  // [J] (2D: J/m)
  // Each point's share of it (V_i times its bonds' energy density), whose point_sum it is.
  void point_energies(const Body& body, const VectorField& u, std::vector<double>& e) const;
  double stable_time_step(const Body& body) const;                     // [s]
  // g_b = c s w_b per directed bond (0 when broken): the pair force density on i, whose
  // direction is the current bond y / |y|. Stresses and fluxes are built from these.
  void pair_forces(const Body& body, const VectorField& u, std::vector<double>& g) const;

  // Scratch for packed current positions, reused across steps (sized once, never per step).
  mutable LargeArray<double> packed_;
  mutable LargeArray<std::int32_t> lean_packed_;
  mutable stencil_kernel::Scratch stencil_;

 private:
  double list_stable_time_step(const Body& body, const BondList& bl) const;
};

}  // namespace peridot

namespace peridot {

Pmb Pmb::from_elastic(double E, double G0, double delta, Kinematics k) {
  if (!(E > 0) || !(G0 >= 0) || !(delta > 0)) throw std::invalid_argument("pmb: need E > 0, G0 >= 0, horizon > 0");
  constexpr double pi = std::numbers::pi;
  switch (k) {
    case Kinematics::plane_stress:
      return {9 * E / (pi * delta * delta * delta), std::sqrt(4 * pi * G0 / (9 * E * delta)), delta};
    case Kinematics::plane_strain:
      return {48 * E / (5 * pi * delta * delta * delta), std::sqrt(5 * pi * G0 / (12 * E * delta)), delta};
    case Kinematics::bar: throw std::invalid_argument("pmb: the 1D bar is not implemented for PMB");
    case Kinematics::solid: {
      const double K = E / (3 * (1 - 2 * 0.25));
      return {18 * K / (pi * std::pow(delta, 4)), critical_stretch_3d(G0, K, delta), delta};
    }
  }
  return {};
}

namespace {

// Positions packed per point, y = x + u then x (stride S = 4 in 2D, 8 in 3D): one cache line
// per partner instead of one per coordinate array, which is what bounds the loop. x is carried
// so lean bond lists need no stored xi or |xi|: L = |x_j - x_i| is the same bits a full list stores.
template <int D>
constexpr int stride = D == 2 ? 4 : 8;
template <int D>
constexpr int x_at = D == 2 ? 2 : 4;

template <int D>
void pack_positions(const Body& body, const VectorField& u, LargeArray<double>& y) {
  const auto n = static_cast<std::int64_t>(body.size());
  y.resize(std::size_t(n) * stride<D>);
  const auto& x = body.points.x;
#pragma omp parallel for schedule(static)
  for (std::int64_t i = 0; i < n; ++i)
    for (int k = 0; k < D; ++k) {
      y[std::size_t(i) * stride<D> + k] = x[k][i] + u[k][i];
      y[std::size_t(i) * stride<D> + x_at<D> + k] = x[k][i];
    }
}

// The hot loop. Each point sums its own bonds, so there is no write to another point and
// no atomics; both directions of a bond see bit-identical stretches (y_i - y_j = -(y_j - y_i)
// in IEEE arithmetic), so they break together and the result is independent of threads.
// The bond loop has no branch, so it vectorises over a point's bonds (gathers on AVX2/512);
// its sums then depend on the vector width of the build, never on the thread count.
// W is the stored weight type: float in lean lists, double in full ones.
template <int D, class W, bool NoFail>
std::size_t pmb_forces(const Pmb& m, Body& body, const LargeArray<double>& y, const W* w, VectorField& f) {
  auto& bl = body.bonds;
  const std::int64_t* off = bl.offset.data();
  const std::int32_t* nb = bl.neighbor.data();
  const double* yp = y.data();
  std::uint8_t* intact = bl.intact.data();
  const std::uint8_t* nofail = body.no_fail.data();
  const double c = m.c, stretched = 1 + m.s0;
  const auto n = static_cast<std::int64_t>(body.size());
  constexpr int S = stride<D>, X = x_at<D>;
  std::size_t broken = 0;
#pragma omp parallel for schedule(static) reduction(+ : broken)
  for (std::int64_t i = 0; i < n; ++i) {
    const double* pi = yp + i * S;
    const double y0 = pi[0], y1 = pi[1], y2 = D == 3 ? pi[2] : 0.0;
    const double x0 = pi[X], x1 = pi[X + 1], x2 = D == 3 ? pi[X + 2] : 0.0;
    const int nfi = NoFail ? nofail[i] : 0;
    double f0 = 0, f1 = 0, f2 = 0;
    int snapped = 0;
    const std::int64_t b0 = off[i], b1 = off[i + 1];
#pragma omp simd reduction(+ : f0, f1, f2, snapped)
    for (std::int64_t b = b0; b < b1; ++b) {
      const std::int32_t j = nb[b];
      const double* pj = yp + std::int64_t(j) * S;
      const double d0 = pj[0] - y0, d1 = pj[1] - y1, d2 = D == 3 ? pj[2] - y2 : 0.0;
      const double e0 = pj[X] - x0, e1 = pj[X + 1] - x1, e2 = D == 3 ? pj[X + 2] - x2 : 0.0;
      const double r = std::sqrt(d0 * d0 + d1 * d1 + d2 * d2), L = std::sqrt(e0 * e0 + e1 * e1 + e2 * e2);
      const int breakable = NoFail ? !(nfi | nofail[j]) : 1;
      // s > s0 written as r > (1 + s0) L: no division in the test.
      const int alive = intact[b];
      const int snap = alive & breakable & int(r > stretched * L);
      const int now = alive & (snap ^ 1);
      intact[b] = std::uint8_t(now);
      snapped += snap;
      const double k_b = now ? c * double(w[b]) * (r - L) / (L * r) : 0.0;
      f0 += k_b * d0;
      f1 += k_b * d1;
      f2 += k_b * d2;
    }
    broken += std::size_t(snapped);
    f[0][i] = f0;
    f[1][i] = f1;
    if constexpr (D == 3) f[2][i] = f2;
  }
  return broken;
}

template <int D, class W>
std::size_t pmb_forces(const Pmb& m, Body& body, const LargeArray<double>& y, const W* w, VectorField& f) {
  return body.no_fail.empty() ? pmb_forces<D, W, false>(m, body, y, w, f) : pmb_forces<D, W, true>(m, body, y, w, f);
}

// The single-precision lean-list pass (lean_records.cppm, lean_kernel.cpp).
std::size_t lean_single_pass(const Pmb& m, Body& body, const VectorField& u, LargeArray<std::int32_t>& packed, VectorField& f,
                             int vector) {
  pack_lean_records(body, u, m.horizon, packed, "pmb");
  return lean_rows(body, packed, f, [&](PeridotLeanPass& pass) {
    pass.c = float(m.c), pass.s0 = float(m.s0);
    return peridot_pmb_lean_rows(&pass, vector);
  });
}

template <int D>
std::size_t pmb_pass(const Pmb& m, Body& body, const VectorField& u, LargeArray<double>& packed, LargeArray<std::int32_t>& lean_packed,
                     VectorField& f) {
  const auto& bl = body.bonds;
  if (bl.lean() && m.lean_kernel != Pmb::LeanKernel::exact && m.horizon > 0)
    return lean_single_pass(m, body, u, lean_packed, f,
                            m.lean_kernel == Pmb::LeanKernel::single ? peridot_pmb_lean_vector()
                            : m.lean_kernel == Pmb::LeanKernel::avx2 ? std::min(1, peridot_pmb_lean_vector())
                                                                     : 0);
  pack_positions<D>(body, u, packed);
  // The weights' precision is the list's storage (float on lean lists), so the kernel is
  // instantiated on the weight type; the branch picks the instantiation once per pass.
  return bl.lean() ? pmb_forces<D>(m, body, packed, bl.weight_f.data(), f) : pmb_forces<D>(m, body, packed, bl.weight.data(), f);
}

}  // namespace

ForceReport Pmb::forces(Body& body, const VectorField& u, VectorField& f) const {
  return {body.visit_bonds(overloaded{
      [&](Stencil&) { return stencil_kernel::forces(c, s0, body, u, f, stencil_); },
      [&](BondList&) { return body.dim() == 2 ? pmb_pass<2>(*this, body, u, packed_, lean_packed_, f)
                                                   : pmb_pass<3>(*this, body, u, packed_, lean_packed_, f); }})};
}

namespace {

// s = (|y| - |xi|) / |xi| of bond b of i on current positions (outside the hot loop).
double stretch(const Body& body, const VectorField& u, std::size_t i, std::int64_t b) {
  const auto j = std::size_t(body.bonds.neighbor[std::size_t(b)]);
  const Vec3 xi = bond_vector(body.points, body.bonds, i, b);
  double r2 = 0;
  for (int k = 0; k < 3; ++k) {
    const double y = xi[std::size_t(k)] + (u[k][j] - u[k][i]);
    r2 += y * y;
  }
  return pmb_bond::stretch(r2, peridot::norm(xi));
}

}  // namespace

double Pmb::strain_energy(const Body& body, const VectorField& u) const {
  std::vector<double> per_point;
  point_energies(body, u, per_point);
  return point_sum(per_point);
}

void Pmb::point_energies(const Body& body, const VectorField& u, std::vector<double>& per_point) const {
  if (body.on_stencil()) return stencil_kernel::point_energies(c, body, u, per_point);
  const auto& bl = body.bonds;
  const auto n = static_cast<std::int64_t>(body.size());
  per_point.assign(body.size(), 0.0);
#pragma omp parallel for schedule(static)
  for (std::int64_t i = 0; i < n; ++i) {
    double e = 0;
    for (std::int64_t b = bl.offset[i]; b < bl.offset[i + 1]; ++b) {
      if (!bl.intact[b]) continue;
      const double s = stretch(body, u, std::size_t(i), b);
      e += pmb_bond::energy(c, s, peridot::norm(bond_vector(body.points, bl, std::size_t(i), b)), bl.weight_of(b));
    }
    per_point[std::size_t(i)] = e * body.points.volume[std::size_t(i)];
  }
}

double Pmb::stable_time_step(const Body& body) const {
  return body.visit_bonds(overloaded{[&](const Stencil&) { return stencil_kernel::stable_time_step(c, body); },
                                     [&](const BondList& bl) { return list_stable_time_step(body, bl); }});
}

double Pmb::list_stable_time_step(const Body& body, const BondList& bl) const {
  const auto n = static_cast<std::int64_t>(body.size());
  double dt = std::numeric_limits<double>::infinity();  // a min is exact: the same for any thread count
#pragma omp parallel for schedule(static) reduction(min : dt)
  for (std::int64_t i = 0; i < n; ++i) {
    double k = 0;
    for (std::int64_t b = bl.offset[i]; b < bl.offset[i + 1]; ++b)
      k += pmb_bond::stiffness(c, bl.weight_of(b), peridot::norm(bond_vector(body.points, bl, std::size_t(i), b)));
    if (k > 0) dt = std::min(dt, pmb_bond::stable_step(body.density, k));
  }
  return dt;
}

void Pmb::pair_forces(const Body& body, const VectorField& u, std::vector<double>& g) const {
  // Composition keeps decks that ask for stress off the stencil; this is a caller's error.
  body.visit_bonds(overloaded{[](const Stencil&) { throw std::invalid_argument("pmb: pair forces need a CSR bond list (discretization.bonds: list)"); },
                              [&](const BondList& bl) {
                                const auto n = static_cast<std::int64_t>(body.size());
                                g.assign(bl.size(), 0.0);
#pragma omp parallel for schedule(static)
                                for (std::int64_t i = 0; i < n; ++i)
                                  for (std::int64_t b = bl.offset[i]; b < bl.offset[i + 1]; ++b)
                                    if (bl.intact[b]) g[std::size_t(b)] = c * stretch(body, u, std::size_t(i), b) * bl.weight_of(b);
                              }});
}

}  // namespace peridot
