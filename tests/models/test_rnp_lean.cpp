// RNP on a lean list (partner, float weight, state) in single precision (lean_kernel.cpp),
// against the double pass on the full list as a second code path: forces within the float
// analysis, break decisions that differ only within it of break_factor r_c, and the AVX2,
// AVX-512VL and portable kernels giving the same bits.
#include <omp.h>

#include <catch2/catch.hpp>
#include <cmath>
#include <vector>
#include "../support/lean_checks.hpp"
#include "../support/max_abs.hpp"
#include "../support/same.hpp"
import peridot.models;

using namespace peridot;

namespace {

// 2^-24: the relative rounding of a double to the nearest float.
constexpr double float_rounding = 5.9604644775390625e-8;
constexpr double spacing = 5e-4, delta = 3 * spacing;

Body body_of(int dim, bool lean) {
  Body b;
  const auto shape = dim == 2 ? subtract(rectangle({0, 0, 0}, {0.04, 0.02, 0}), disk({0.02, 0.01, 0}, 0.004))
                              : box({0, 0, 0}, {0.012, 0.008, 0.006});
  b.points = lattice(shape, {.spacing = spacing, .perturbation = 0.2, .seed = 5});
  b.bonds = build_bonds(b.points, {.horizon = delta, .partial_volume = true, .lean = lean});
  b.density = 2440;
  return b;
}

Rnp model(int dim, double break_factor) {
  Rnp m = Rnp::from_elastic(72e9, 3.8, delta, dim == 2 ? Kinematics::plane_stress : Kinematics::solid, dim, RnpInfluence::linear);
  m.break_factor = break_factor;
  return m;
}

// A smooth field whose bond strains reach about 2 r_c / sqrt(delta): sqrt|xi| S up to about
// twice r_c, so the exponential runs over [-4, 0] and bonds soften, plus an opening of
// `jump` r_c / sqrt(delta) delta across x = 0.0036 m.
VectorField field(const Body& b, const Rnp& m, double jump) {
  const double Sc = m.critical_r() / std::sqrt(delta), k1 = 200, k2 = 150, k3 = 300;
  VectorField u = zero_field(b.size());
  for (std::size_t i = 0; i < b.size(); ++i) {
    const double x = b.points.x[0][i], y = b.points.x[1][i];
    u[0][i] = 2 * Sc / k1 * std::sin(k1 * y) + (x > 0.0036 ? jump * Sc * delta : 0.0);
    u[1][i] = 2 * Sc / k2 * std::sin(k2 * x);
    if (b.dim() == 3) u[2][i] = 2 * Sc / k3 * std::sin(k3 * x + 100 * y);
  }
  return u;
}

// sqrt|xi| S of bond b from i, in double from the positions.
double root_r2(const Body& b, const VectorField& u, std::size_t i, std::int64_t bond) {
  const auto j = std::size_t(b.bonds.neighbor[std::size_t(bond)]);
  double L2 = 0, d = 0;
  for (int k = 0; k < 3; ++k) {
    const double xi = b.points.x[k][j] - b.points.x[k][i];
    L2 += xi * xi, d += xi * (u[k][j] - u[k][i]);
  }
  return std::sqrt(std::sqrt(L2)) * std::abs(d / L2);
}

}  // namespace

TEST_CASE("RNP's single-precision lean kernel stays within its float analysis of the double full list") {
  for (int dim : {2, 3}) {
    INFO("dimension " << dim);
    Body full = body_of(dim, false), lean = body_of(dim, true);
    REQUIRE(lean.bonds.lean());
    const Rnp m = model(dim, 0);  // soften only: the exponential's whole range
    const VectorField u = field(full, m, 0);
    VectorField f_full = zero_field(full.size()), f_lean = zero_field(lean.size());
    m.forces(full, u, f_full);
    m.forces(lean, u, f_lean);
    REQUIRE(m.softening_bonds(full, u) > 100);
    // Per bond, with g_b = k0 w J S exp(-x), x = beta |xi| S^2, from the full list (|d(S e^-x)/dS| <= 1):
    //  - eta from float u / q is off by at most 2 sqrt(3) |u|max 2^-24, and the float dot product
    //    by 3 |eta| ulps, so S by (4 |u|max + 3 |eta|) 2^-24 / L;
    //  - the bond vector is within 2 sqrt(3) q < 4 delta 2^-24 (fixed point, then float), which
    //    moves S by (|eta| / L + 2 |S|) times 4 delta 2^-24 / L and the direction by 4 delta 2^-24 / L;
    //  - the float weight, a dozen float operations and exp_neg's few ulps add ~24 ulps of g_b,
    //    x's own rounding x ulps; two-term float sums before the double ones 2 more:
    //   |f_lean - f_full| <= 2^-24 sum_b ((28 + 12 delta / L + 4 x) |g_b| + k0 w J (4 |u|max + 3 |eta| + 4 delta |eta| / L) / L).
    std::vector<double> g;
    m.pair_forces(full, u, g);
    const double umax = max_abs(u), k0 = m.prefactor * 2 * m.C * m.beta;
    double worst = 0, largest_bound = 0, largest_total = 0;
    for (std::size_t i = 0; i < full.size(); ++i) {
      double bound = 0, total = 0;
      for (auto b = full.bonds.begin(i); b < full.bonds.end(i); ++b) {
        const auto j = std::size_t(full.bonds.neighbor[std::size_t(b)]);
        const double L = full.bonds.length[std::size_t(b)], w = full.bonds.weight[std::size_t(b)];
        const double eta = std::hypot(u[0][j] - u[0][i], u[1][j] - u[1][i], u[2][j] - u[2][i]);
        const double r = root_r2(full, u, i, b), x = m.beta * r * r;
        bound += (28 + 12 * delta / L + 4 * x) * std::abs(g[std::size_t(b)]) + k0 * w * m.J(L) * (4 * umax + 3 * eta + 4 * delta * eta / L) / L;
        total += std::abs(g[std::size_t(b)]);
      }
      bound *= float_rounding;
      largest_bound = std::max(largest_bound, bound);
      largest_total = std::max(largest_total, total);
      for (int k = 0; k < dim; ++k) {
        REQUIRE(std::abs(f_lean[k][i] - f_full[k][i]) <= bound);
        worst = std::max(worst, std::abs(f_lean[k][i] - f_full[k][i]) / bound);
      }
    }
    INFO("largest error / bound " << worst);
    CHECK(worst > 0);  // the paths do differ: this is not one code path compared with itself
    CHECK(largest_bound <= 1e-4 * largest_total);  // and the analysis bounds something: far below the forces (~200 ulps)
    // The observers read a lean list in double, from the positions and the float weights.
    CHECK(std::abs(m.strain_energy(lean, u) - m.strain_energy(full, u)) <= 2 * float_rounding * m.strain_energy(full, u));
    CHECK(m.softening_bonds(lean, u) == m.softening_bonds(full, u));
  }
}

TEST_CASE("RNP's single-precision lean kernel breaks the full list's bonds but within its float analysis of break_factor r_c") {
  for (int dim : {2, 3}) {
    INFO("dimension " << dim);
    Body full = body_of(dim, false), lean = body_of(dim, true);
    const Rnp m = model(dim, 1.5);
    const VectorField u = field(full, m, 6);
    VectorField f = zero_field(full.size());
    const auto broken_full = m.forces(full, u, f).newly_broken_directed;
    const auto broken_lean = m.forces(lean, u, f).newly_broken_directed;
    REQUIRE(broken_full > 100);
    // sqrt|xi| S is off by a few 2^-24 relative plus (4 |u|max + 3 |eta|) 2^-24 / L (above):
    // 1e-5 of the threshold leaves a wide margin.
    const double limit = m.break_factor * m.critical_r();
    std::size_t differ = 0;
    for (std::size_t i = 0; i < full.size(); ++i)
      for (auto b = full.bonds.begin(i); b < full.bonds.end(i); ++b)
        if (full.bonds.intact[std::size_t(b)] != lean.bonds.intact[std::size_t(b)]) {
          REQUIRE(std::abs(root_r2(full, u, i, b) - limit) <= 1e-5 * limit);
          ++differ;
        }
    lean_checks::check_break_counts(broken_lean, broken_full, differ);
  }
}

TEST_CASE("RNP's AVX-512VL, AVX2 and portable lean kernels give the same bits on any thread count") {
  if (!lean_checks::vector_kernels_run()) return;
  for (int dim : {2, 3}) {
    INFO("dimension " << dim);
    Rnp portable = model(dim, 1.5);
    portable.lean_vector = 0;
    Body reference = body_of(dim, true);
    const VectorField u = field(reference, portable, 6);
    VectorField f_ref = zero_field(reference.size());
    const auto broken_ref = portable.forces(reference, u, f_ref).newly_broken_directed;
    REQUIRE(broken_ref > 100);
    const int threads = omp_get_max_threads();
    for (int level : {1, -1})
      for (int t : {threads, 1}) {
        INFO("kernel level " << level << " (-1: the fastest) on " << t << " threads");
        Rnp m = portable;
        m.lean_vector = level;
        Body b = body_of(dim, true);
        VectorField f = zero_field(b.size());
        omp_set_num_threads(t);
        const auto broken = m.forces(b, u, f).newly_broken_directed;
        omp_set_num_threads(threads);
        CHECK(broken == broken_ref);
        CHECK(same::difference(b.bonds.intact, reference.bonds.intact, "intact") == "");
        CHECK(same::difference(f, f_ref, "f") == "");
      }
  }
}

TEST_CASE("RNP spares the bonds of no-fail points past break_factor r_c, in double and in single precision, and breaks the others") {
  for (int dim : {2, 3}) {
    for (bool lean : {false, true}) {
      INFO("dimension " << dim << (lean ? ", single precision on a lean list" : ", double on a full list"));
      Body b = body_of(dim, lean);
      // A strip along the bottom, across the opening's jump.
      for (std::size_t i = 0; i < b.size(); ++i) b.no_fail.push_back(b.points.x[1][i] < 0.002 ? 1 : 0);
      const Rnp m = model(dim, 1.5);
      const VectorField u = field(b, m, 6);
      VectorField f = zero_field(b.size());
      m.forces(b, u, f);
      const double limit = m.break_factor * m.critical_r();
      std::size_t spared = 0, broken = 0;
      for (std::size_t i = 0; i < b.size(); ++i)
        for (auto bond = b.bonds.begin(i); bond < b.bonds.end(i); ++bond) {
          const auto j = std::size_t(b.bonds.neighbor[std::size_t(bond)]);
          if (root_r2(b, u, i, bond) <= (1 + 1e-5) * limit) continue;  // past the threshold beyond the float analysis
          if (b.no_fail[i] || b.no_fail[j]) {
            REQUIRE(b.bonds.intact[std::size_t(bond)] == 1);
            ++spared;
          } else {
            REQUIRE(b.bonds.intact[std::size_t(bond)] == 0);
            ++broken;
          }
        }
      CHECK(spared > 10);
      CHECK(broken > 100);
    }
  }
}
