// The lean bond list PMB runs on (partner, float weight, mask) against the full list
// (partner, xi, |xi|, double weight, mask) as a second code path: the same bonds; in double
// (Pmb::LeanKernel::exact) the same breaks and forces within the float rounding of the
// weights; in single precision (the default kernel) forces within its float analysis and
// breaks that differ only within it of s0; its AVX2 and portable versions the same bits.
#include <omp.h>

#include <catch2/catch.hpp>
#include <cmath>
#include <vector>
#include "../support/max_abs.hpp"
#include "../support/same.hpp"
import peridot.analysis;

using namespace peridot;

namespace {

// 2^-24: the relative rounding of a double to the nearest float.
constexpr double float_rounding = 5.9604644775390625e-8;

Body perturbed_body(int dim, bool lean, bool no_fail_strip = false) {
  Body b;
  const auto shape = dim == 2 ? subtract(rectangle({0, 0, 0}, {0.04, 0.02, 0}), disk({0.02, 0.01, 0}, 0.004))
                              : box({0, 0, 0}, {0.012, 0.008, 0.006});
  b.points = lattice(shape, {.spacing = 5e-4, .perturbation = 0.2, .seed = 11});
  b.bonds = build_bonds(b.points, {.horizon = 3 * 5e-4, .partial_volume = true, .lean = lean});
  const Crack crack = dim == 2 ? Crack{CrackSegment{{0.0, 0.0101, 0}, {0.012, 0.0101, 0}}}
                               : Crack{CrackRectangle{{-0.001, 0.0041, -0.001}, {0.007, 0, 0}, {0, 0, 0.008}}};
  cut_bonds(b.points, b.bonds, {crack});
  b.density = 2440;
  // A strip across the jump of `opening` below, whose over-stretched bonds must stay intact.
  if (no_fail_strip)
    for (std::size_t i = 0; i < b.size(); ++i) b.no_fail.push_back(b.points.x[1][i] < 0.002 ? 1 : 0);
  return b;
}

// A smooth field that stretches no bond near s0 (a = 0.2 of `opening`'s smooth part).
VectorField smooth(const Body& b, double delta) {
  VectorField u = zero_field(b.size());
  for (std::size_t i = 0; i < b.size(); ++i) {
    const double x = b.points.x[0][i], y = b.points.x[1][i];
    u[0][i] = 0.2e-4 * std::sin(200 * y) * delta;
    u[1][i] = 0.4e-4 * x * std::cos(150 * x);
    if (b.dim() == 3) u[2][i] = 0.3e-4 * std::sin(300 * x + 100 * y) * delta;
  }
  return u;
}

double stretch_of(const Body& b, const VectorField& u, std::size_t i, std::size_t j) {
  double L2 = 0, r2 = 0;
  for (int k = 0; k < 3; ++k) {
    const double xi = b.points.x[k][j] - b.points.x[k][i], y = xi + (u[k][j] - u[k][i]);
    L2 += xi * xi, r2 += y * y;
  }
  return (std::sqrt(r2) - std::sqrt(L2)) / std::sqrt(L2);
}

// A smooth field plus a jump across x = 0.3 L that stretches bonds well past s0.
VectorField opening(const Body& b, double s0, double delta) {
  VectorField u = zero_field(b.size());
  for (std::size_t i = 0; i < b.size(); ++i) {
    const double x = b.points.x[0][i], y = b.points.x[1][i];
    u[0][i] = 1e-4 * std::sin(200 * y) * delta + (x > 0.0036 ? 3 * s0 * delta : 0.0);
    u[1][i] = 2e-4 * x * std::cos(150 * x);
  }
  return u;
}

}  // namespace

TEST_CASE("a lean list keeps the full list's bonds in under 12 bytes each") {
  for (int dim : {2, 3}) {
    const Body full = perturbed_body(dim, false), lean = perturbed_body(dim, true);
    REQUIRE(lean.bonds.lean());
    REQUIRE_FALSE(full.bonds.lean());
    REQUIRE(same::difference(lean.bonds.offset, full.bonds.offset, "lean.bonds.offset") == "");
    REQUIRE(same::difference(lean.bonds.neighbor, full.bonds.neighbor, "lean.bonds.neighbor") == "");
    REQUIRE(same::difference(lean.bonds.intact, full.bonds.intact, "lean.bonds.intact") == "");
    REQUIRE(lean.bonds.broken() > 0);  // the pre-crack cut some
    for (std::size_t b = 0; b < full.bonds.size(); ++b) {
      REQUIRE(std::abs(lean.bonds.weight_of(std::int64_t(b)) - full.bonds.weight[b]) <= float_rounding * full.bonds.weight[b]);
      const auto i = std::size_t(std::upper_bound(full.bonds.offset.begin(), full.bonds.offset.end(), std::int64_t(b)) -
                                 full.bonds.offset.begin()) - 1;
      const Vec3 xi = bond_vector(lean.points, lean.bonds, i, std::int64_t(b));
      for (int k = 0; k < 3; ++k) REQUIRE(xi[std::size_t(k)] == full.bonds.xi[std::size_t(k)][b]);  // the same bits
    }
    CHECK(lean.bonds.bytes_per_bond() <= 12.0);
    CHECK(full.bonds.bytes_per_bond() >= 45.0);
  }
}

TEST_CASE("PMB's double-precision kernel on a lean list breaks the same bonds, forces within 2^-24") {
  for (int dim : {2, 3}) {
    Body full = perturbed_body(dim, false), lean = perturbed_body(dim, true);
    const double delta = 3 * 5e-4;
    auto pmb = Pmb::from_elastic(72e9, 3.8, delta, dim == 2 ? Kinematics::plane_stress : Kinematics::solid);
    pmb.lean_kernel = Pmb::LeanKernel::exact;
    const VectorField u = opening(full, pmb.s0, delta);
    VectorField f_full = zero_field(full.size()), f_lean = zero_field(lean.size());
    const auto broken_full = pmb.forces(full, u, f_full).newly_broken_directed;
    const auto broken_lean = pmb.forces(lean, u, f_lean).newly_broken_directed;
    REQUIRE(broken_full > 100);
    // Stretches are computed in double from the same positions either way: the same decisions.
    REQUIRE(broken_lean == broken_full);
    REQUIRE(same::difference(lean.bonds.intact, full.bonds.intact, "lean.bonds.intact") == "");
    // Each pair force carries one float-rounded weight: |f_lean - f_full| <= 2^-24 sum_b |f_b|,
    // bounded here by the sum over bonds of the pair-force magnitudes from the full list.
    std::vector<double> g;
    pmb.pair_forces(full, u, g);
    for (std::size_t i = 0; i < full.size(); ++i) {
      double bound = 0;
      for (auto b = full.bonds.begin(i); b < full.bonds.end(i); ++b) bound += std::abs(g[std::size_t(b)]);
      for (int k = 0; k < dim; ++k) REQUIRE(std::abs(f_lean[k][i] - f_full[k][i]) <= 1.01 * float_rounding * bound + 1e-300);
    }
    // Energies and stable steps from the two lists agree to the same rounding.
    CHECK(std::abs(pmb.strain_energy(lean, u) - pmb.strain_energy(full, u)) <= 2 * float_rounding * pmb.strain_energy(full, u));
    CHECK(std::abs(pmb.stable_time_step(lean) - pmb.stable_time_step(full)) <= float_rounding * pmb.stable_time_step(full));
  }
}

TEST_CASE("damage and the bulk stress read a lean list like a full one") {
  Body full = perturbed_body(2, false), lean = perturbed_body(2, true);
  auto pmb = Pmb::from_elastic(72e9, 3.8, 1.5e-3, Kinematics::plane_stress);
  pmb.lean_kernel = Pmb::LeanKernel::exact;
  const VectorField u = opening(full, pmb.s0, 1.5e-3);
  VectorField f = zero_field(full.size());
  pmb.forces(full, u, f);
  pmb.forces(lean, u, f);
  const auto phi_full = damage(full), phi_lean = damage(lean);
  std::vector<double> g_full, g_lean;
  pmb.pair_forces(full, u, g_full);
  pmb.pair_forces(lean, u, g_lean);
  const auto t_full = bulk_stress(full, g_full), t_lean = bulk_stress(lean, g_lean);
  double scale = 0;
  for (double v : t_full.xx) scale = std::max(scale, std::abs(v));
  for (std::size_t i = 0; i < full.size(); ++i) {
    REQUIRE(std::abs(phi_lean[i] - phi_full[i]) <= 4 * float_rounding);
    REQUIRE(std::abs(t_lean.xx[i] - t_full.xx[i]) <= 4 * float_rounding * scale);
    REQUIRE(std::abs(t_lean.xy[i] - t_full.xy[i]) <= 4 * float_rounding * scale);
  }
}

TEST_CASE("PMB's single-precision lean kernel stays within its float analysis of the double full list") {
  for (int dim : {2, 3}) {
    Body full = perturbed_body(dim, false), lean = perturbed_body(dim, true);
    const double delta = 3 * 5e-4;
    const auto pmb = Pmb::from_elastic(72e9, 3.8, delta, dim == 2 ? Kinematics::plane_stress : Kinematics::solid);
    REQUIRE(pmb.lean_kernel == Pmb::LeanKernel::single);  // the default
    const VectorField u = smooth(full, delta);
    VectorField f_full = zero_field(full.size()), f_lean = zero_field(lean.size());
    REQUIRE(pmb.forces(full, u, f_full).newly_broken_directed == 0);
    REQUIRE(pmb.forces(lean, u, f_lean).newly_broken_directed == 0);
    const double umax = max_abs(u);
    // Per bond (lean_kernel.cpp): eta from float u / q is off by at most 2 |u|max 2^-24, so s
    // by that over L; the bond vector is within 2 sqrt(3) q < 4 delta 2^-24 (both ends rounded to
    // fixed point, then to float), which moves the
    // force's direction by that over L and s by (|eta| / L + |s|) times it; the float weight and
    // the dozen float operations add ~16 ulps of the pair force; two-term float sums before the
    // double ones add 2 more. With g_b = c w s from the full list:
    //   |f_lean - f_full| <= 2^-24 sum_b ((24 + 8 delta / L) |g_b| + c w_b (2 |u|max + 8 delta |eta_b| / L) / L).
    std::vector<double> g;
    pmb.pair_forces(full, u, g);
    double worst = 0;
    for (std::size_t i = 0; i < full.size(); ++i) {
      double bound = 0;
      for (auto b = full.bonds.begin(i); b < full.bonds.end(i); ++b) {
        const auto j = std::size_t(full.bonds.neighbor[std::size_t(b)]);
        const double L = full.bonds.length[std::size_t(b)], cw = pmb.c * full.bonds.weight[std::size_t(b)];
        const double eta = std::hypot(u[0][j] - u[0][i], u[1][j] - u[1][i], u[2][j] - u[2][i]);
        bound += (24 + 8 * delta / L) * std::abs(g[std::size_t(b)]) + cw * (2 * umax + 8 * delta * eta / L) / L;
      }
      bound *= float_rounding;
      for (int k = 0; k < dim; ++k) {
        REQUIRE(std::abs(f_lean[k][i] - f_full[k][i]) <= bound);
        worst = std::max(worst, std::abs(f_lean[k][i] - f_full[k][i]) / bound);
      }
    }
    INFO("largest error / bound " << worst);
    CHECK(worst > 0);  // the paths do differ: this is not one code path compared with itself
  }
}

TEST_CASE("PMB's single-precision lean kernel breaks the full list's bonds, spares no-fail points") {
  for (int dim : {2, 3}) {
    Body full = perturbed_body(dim, false, true), lean = perturbed_body(dim, true, true);
    const double delta = 3 * 5e-4;
    const auto pmb = Pmb::from_elastic(72e9, 3.8, delta, dim == 2 ? Kinematics::plane_stress : Kinematics::solid);
    const VectorField u = opening(full, pmb.s0, delta);
    VectorField f = zero_field(full.size());
    const auto broken_full = pmb.forces(full, u, f).newly_broken_directed;
    const auto broken_lean = pmb.forces(lean, u, f).newly_broken_directed;
    REQUIRE(broken_full > 100);
    // Decisions may differ only where s lies within the float analysis of s0 (~1e-7 s0 plus the
    // eta and bond-vector terms above); 1e-5 s0 leaves a wide margin.
    std::size_t differ = 0, spared = 0;
    for (std::size_t i = 0; i < full.size(); ++i)
      for (auto b = full.bonds.begin(i); b < full.bonds.end(i); ++b) {
        const auto j = std::size_t(full.bonds.neighbor[std::size_t(b)]);
        const double s = stretch_of(full, u, i, j);
        if (full.bonds.intact[std::size_t(b)] != lean.bonds.intact[std::size_t(b)]) {
          REQUIRE(std::abs(s - pmb.s0) <= 1e-5 * pmb.s0);
          ++differ;
        }
        if ((full.no_fail[i] || full.no_fail[j]) && s > pmb.s0) {
          REQUIRE(lean.bonds.intact[std::size_t(b)] == 1);
          ++spared;
        }
      }
    CHECK(spared > 10);
    CHECK(broken_lean + differ >= broken_full);
    CHECK(broken_lean <= broken_full + differ);
  }
}

TEST_CASE("PMB's AVX-512VL and AVX2 lean kernels give the portable kernel's bits on any thread count") {
  if (!__builtin_cpu_supports("avx2") || !__builtin_cpu_supports("bmi2")) {
    WARN("this CPU has no AVX2: only the portable kernel runs here");
    return;
  }
  if (!__builtin_cpu_supports("avx512vl")) WARN("this CPU has no AVX-512VL: the default kernel is the AVX2 one");
  for (int dim : {2, 3}) {
    const double delta = 3 * 5e-4;
    const auto fastest = Pmb::from_elastic(72e9, 3.8, delta, dim == 2 ? Kinematics::plane_stress : Kinematics::solid);
    auto avx2 = fastest, portable = fastest;
    avx2.lean_kernel = Pmb::LeanKernel::avx2;
    portable.lean_kernel = Pmb::LeanKernel::portable;
    Body reference = perturbed_body(dim, true, true);
    const VectorField u = opening(reference, fastest.s0, delta);
    VectorField f_ref = zero_field(reference.size());
    const auto broken_ref = portable.forces(reference, u, f_ref).newly_broken_directed;
    REQUIRE(broken_ref > 100);
    const int threads = omp_get_max_threads();
    for (const Pmb* m : {&fastest, static_cast<const Pmb*>(&avx2)})
      for (int t : {threads, 1}) {
        INFO((m == &avx2 ? "AVX2" : "fastest") << " kernel on " << t << " threads");
        Body b = perturbed_body(dim, true, true);
        VectorField f = zero_field(b.size());
        omp_set_num_threads(t);
        const auto broken = m->forces(b, u, f).newly_broken_directed;
        omp_set_num_threads(threads);
        CHECK(broken == broken_ref);
        CHECK(same::difference(b.bonds.intact, reference.bonds.intact, "intact") == "");
        CHECK(same::difference(f, f_ref, "f") == "");
      }
  }
}
