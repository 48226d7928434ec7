// The lean bond list PMB runs on (partner, float weight, mask) against the full list
// (partner, xi, |xi|, double weight, mask) as a second code path: the same bonds, the same
// breaks, forces within the float rounding of the weights.
#include <catch2/catch.hpp>
#include <cmath>
#include <vector>
#include "../support/same.hpp"
import peridot.analysis;

using namespace peridot;

namespace {

// 2^-24: the relative rounding of a double to the nearest float.
constexpr double float_rounding = 5.9604644775390625e-8;

Body perturbed_body(int dim, bool lean) {
  Body b;
  const auto shape = dim == 2 ? subtract(rectangle({0, 0, 0}, {0.04, 0.02, 0}), disk({0.02, 0.01, 0}, 0.004))
                              : box({0, 0, 0}, {0.012, 0.008, 0.006});
  b.points = lattice(shape, {.spacing = 5e-4, .perturbation = 0.2, .seed = 11});
  b.bonds = build_bonds(b.points, {.horizon = 3 * 5e-4, .partial_volume = true, .lean = lean});
  const Crack crack = dim == 2 ? Crack{CrackSegment{{0.0, 0.0101, 0}, {0.012, 0.0101, 0}}}
                               : Crack{CrackRectangle{{-0.001, 0.0041, -0.001}, {0.007, 0, 0}, {0, 0, 0.008}}};
  cut_bonds(b.points, b.bonds, {crack});
  b.density = 2440;
  return b;
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

TEST_CASE("PMB on a lean list breaks the same bonds, forces within 2^-24") {
  for (int dim : {2, 3}) {
    Body full = perturbed_body(dim, false), lean = perturbed_body(dim, true);
    const double delta = 3 * 5e-4;
    const auto pmb = Pmb::from_elastic(72e9, 3.8, delta, dim == 2 ? Kinematics::plane_stress : Kinematics::solid);
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
  const auto pmb = Pmb::from_elastic(72e9, 3.8, 1.5e-3, Kinematics::plane_stress);
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
