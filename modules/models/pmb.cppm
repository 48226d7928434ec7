module;
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>
export module peridot.models:pmb;
import :body;
import :elastic;

export namespace peridot {

// Prototype microelastic brittle (PMB) bond-based model (Silling & Askari 2005).
// Pair force density f = c s w_j (y / |y|), s = (|y| - |xi|) / |xi|, broken for good once
// s > s0 unless either end is in a no-fail region.
struct Pmb {
  double c = 0;   // micromodulus [N/m^6] (2D: [N/m^5] per unit thickness)
  double s0 = 0;  // critical stretch [-]

  // Micromodulus and critical stretch matched to E and G0 for a ball of radius delta:
  //  3D (nu = 1/4):           c = 18K/(pi delta^4), s0 = sqrt(5 G0 / (9 K delta)), K = E/(3(1-2nu))
  //                           (Silling & Askari 2005, eqs. 24 and 29)
  //  2D plane stress (1/3):   c = 9E/(pi delta^3),  s0 = sqrt(4 pi G0 / (9 E delta))
  //  2D plane strain (1/4):   c = 48E/(5 pi delta^3), s0 = sqrt(5 pi G0 / (12 E delta))
  //                           (Ha & Bobaru 2010; energy matching per unit thickness)
  static Pmb from_elastic(double youngs_modulus, double fracture_energy, double horizon, Kinematics k);

  ForceReport forces(Body& body, const VectorField& u, VectorField& f) const;
  double strain_energy(const Body& body, const VectorField& u) const;  // [J] (2D: J/m)
  double stable_time_step(const Body& body) const;                     // [s]
  // g_b = c s w_b per directed bond (0 when broken): the pair force density on i, whose
  // direction is the current bond y / |y|. Stresses and fluxes are built from these.
  void pair_forces(const Body& body, const VectorField& u, std::vector<double>& g) const;

  // Scratch for packed current positions, reused across steps (sized once, never per step).
  mutable std::vector<double> packed_;
};

}  // namespace peridot

namespace peridot {

Pmb Pmb::from_elastic(double E, double G0, double delta, Kinematics k) {
  if (!(E > 0) || !(G0 >= 0) || !(delta > 0)) throw std::invalid_argument("pmb: need E > 0, G0 >= 0, horizon > 0");
  constexpr double pi = std::numbers::pi;
  switch (k) {
    case Kinematics::plane_stress:
      return {9 * E / (pi * delta * delta * delta), std::sqrt(4 * pi * G0 / (9 * E * delta))};
    case Kinematics::plane_strain:
      return {48 * E / (5 * pi * delta * delta * delta), std::sqrt(5 * pi * G0 / (12 * E * delta))};
    case Kinematics::bar: throw std::invalid_argument("pmb: the 1D bar is not implemented for PMB");
    case Kinematics::solid: {
      const double K = E / (3 * (1 - 2 * 0.25));
      return {18 * K / (pi * std::pow(delta, 4)), std::sqrt(5 * G0 / (9 * K * delta))};
    }
  }
  return {};
}

namespace {

// The hot loop. Each point sums its own bonds, so there is no write to another point and
// no atomics; both directions of a bond see bit-identical stretches (x_i - x_j = -(x_j - x_i)
// in IEEE arithmetic), so they break together and the result is independent of threads.
// Current positions y = x + u packed per point (stride S = 2 in 2D, 4 in 3D): one cache line
// per partner instead of one per coordinate array, which is what bounds this loop.
template <int D>
constexpr int stride = D == 2 ? 2 : 4;

template <int D>
void pack_positions(const Body& body, const VectorField& u, std::vector<double>& y) {
  const auto n = static_cast<std::int64_t>(body.size());
  y.resize(std::size_t(n) * stride<D>);
  const auto& x = body.points.x;
#pragma omp parallel for schedule(static)
  for (std::int64_t i = 0; i < n; ++i)
    for (int k = 0; k < D; ++k) y[std::size_t(i) * stride<D> + k] = x[k][i] + u[k][i];
}

// The hot loop. Each point sums its own bonds, so there is no write to another point and
// no atomics; both directions of a bond see bit-identical stretches (y_i - y_j = -(y_j - y_i)
// in IEEE arithmetic), so they break together and the result is independent of threads.
template <int D>
std::size_t pmb_forces(const Pmb& m, Body& body, const std::vector<double>& y, VectorField& f) {
  auto& bl = body.bonds;
  const std::int64_t* off = bl.offset.data();
  const std::int32_t* nb = bl.neighbor.data();
  const double* len = bl.length.data();
  const double* w = bl.weight.data();
  const double* yp = y.data();
  std::uint8_t* intact = bl.intact.data();
  const std::uint8_t* nofail = body.no_fail.empty() ? nullptr : body.no_fail.data();
  const double c = m.c, s0 = m.s0;
  const auto n = static_cast<std::int64_t>(body.size());
  constexpr int S = stride<D>;
  std::size_t broken = 0;
#pragma omp parallel for schedule(static) reduction(+ : broken)
  for (std::int64_t i = 0; i < n; ++i) {
    double yi[3] = {}, fi[3] = {};
    for (int k = 0; k < D; ++k) yi[k] = yp[i * S + k];
    const bool nfi = nofail && nofail[i];
    for (std::int64_t b = off[i]; b < off[i + 1]; ++b) {
      const std::int32_t j = nb[b];
      double d[3], r2 = 0;
      for (int k = 0; k < D; ++k) {
        d[k] = yp[std::int64_t(j) * S + k] - yi[k];
        r2 += d[k] * d[k];
      }
      const double r = std::sqrt(r2);
      const double L = len[b];
      std::uint8_t alive = intact[b];
      // s > s0 written as r > (1 + s0) L: one sqrt and one division per bond.
      if (r > (1 + s0) * L && alive && !nfi && !(nofail && nofail[j])) {
        intact[b] = alive = 0;
        ++broken;
      }
      const double k_b = alive ? c * w[b] * (r - L) / (L * r) : 0.0;
      for (int k = 0; k < D; ++k) fi[k] += k_b * d[k];
    }
    for (int k = 0; k < D; ++k) f[k][i] = fi[k];
  }
  return broken;
}

}  // namespace

ForceReport Pmb::forces(Body& body, const VectorField& u, VectorField& f) const {
  std::size_t broken = 0;
  if (body.dim() == 2) {
    pack_positions<2>(body, u, packed_);
    broken = pmb_forces<2>(*this, body, packed_, f);
  } else {
    pack_positions<3>(body, u, packed_);
    broken = pmb_forces<3>(*this, body, packed_, f);
  }
  // Each broken bond is counted from both ends.
  return {broken / 2};
}

namespace {

// s = (|y| - |xi|) / |xi| of bond b of i on current positions (outside the hot loop).
double stretch(const Body& body, const VectorField& u, std::size_t i, std::int64_t b) {
  const auto& x = body.points.x;
  const auto& bl = body.bonds;
  const auto j = std::size_t(bl.neighbor[b]);
  double r2 = 0;
  for (int k = 0; k < 3; ++k) {
    const double y = (x[k][j] - x[k][i]) + (u[k][j] - u[k][i]);
    r2 += y * y;
  }
  return (std::sqrt(r2) - bl.length[b]) / bl.length[b];
}

}  // namespace

double Pmb::strain_energy(const Body& body, const VectorField& u) const {
  const auto& bl = body.bonds;
  const auto n = static_cast<std::int64_t>(body.size());
  std::vector<double> per_point(body.size());
#pragma omp parallel for schedule(static)
  for (std::int64_t i = 0; i < n; ++i) {
    double e = 0;
    for (std::int64_t b = bl.offset[i]; b < bl.offset[i + 1]; ++b) {
      if (!bl.intact[b]) continue;
      const double s = stretch(body, u, std::size_t(i), b);
      e += 0.25 * c * s * s * bl.length[b] * bl.weight[b];
    }
    per_point[i] = e * body.points.volume[i];
  }
  double total = 0;  // serial sum: identical for every thread count
  for (double e : per_point) total += e;
  return total;
}

double Pmb::stable_time_step(const Body& body) const {
  const auto& bl = body.bonds;
  double dt = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < body.size(); ++i) {
    double k = 0;
    for (std::int64_t b = bl.offset[i]; b < bl.offset[i + 1]; ++b) k += c * bl.weight[b] / bl.length[b];
    if (k > 0) dt = std::min(dt, std::sqrt(2 * body.density / k));
  }
  return dt;
}

void Pmb::pair_forces(const Body& body, const VectorField& u, std::vector<double>& g) const {
  const auto& bl = body.bonds;
  const auto n = static_cast<std::int64_t>(body.size());
  g.assign(bl.size(), 0.0);
#pragma omp parallel for schedule(static)
  for (std::int64_t i = 0; i < n; ++i)
    for (std::int64_t b = bl.offset[i]; b < bl.offset[i + 1]; ++b)
      if (bl.intact[b]) g[std::size_t(b)] = c * stretch(body, u, std::size_t(i), b) * bl.weight[b];
}

}  // namespace peridot
