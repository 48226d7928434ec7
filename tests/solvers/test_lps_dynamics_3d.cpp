// Dynamic LPS in 3D (seed 000 Sec. 6 on full balls): the critical stretch in 3D, the nonlocal
// traction patch tests on the compacted body, incremental mask updates against a rebuild, and
// Newmark against velocity Verlet, on a 10 mm glass cube.
#include <catch2/catch.hpp>
#include <algorithm>
#include <cmath>
#include <string>
#include <variant>
#include <vector>
#include "../support/newmark_verlet.hpp"
import peridot.problem;

using namespace peridot;

namespace {

constexpr double side = 0.01, h = 1e-3, delta = 3e-3;

// The cube [0, 10 mm]^3, h = 1 mm, delta = 3h, GMLS; `loads` is the boundaries block.
Problem cube(const std::string& loads, const std::string& solver = "{type: explicit, end_time: 1.0e-6}", double G0 = 0) {
  const std::string deck = R"(
name: cube
dimension: 3
geometry: {body: {box: {min: [0.0, 0.0, 0.0], max: [0.01, 0.01, 0.01]}}}
discretization: {spacing: 1.0e-3, horizon_factor: 3, quadrature: gmls}
material: {model: lps, kinematics: solid, youngs_modulus: 72.0e9, poisson_ratio: 0.23, density: 2440.0, fracture_energy: )" +
                           std::to_string(G0) + R"(}
boundaries: )" + loads + R"(
solver: )" + solver + "\n";
  return parse_deck(deck, "cube");
}

// 2 MPa along z on the top and bottom faces, through (4.6) on the exterior points beyond them.
const std::string tension = R"(
  - {name: top, type: traction, region: {box: {min: [-0.01, -0.01, 0.01], max: [0.02, 0.02, 0.02]}}, normal: 2.0e6}
  - {name: bottom, type: traction, region: {box: {min: [-0.01, -0.01, -0.01], max: [0.02, 0.02, 0.0]}}, normal: 2.0e6})";

double norm3(const VectorField& f, std::size_t i) { return std::sqrt(f[0][i] * f[0][i] + f[1][i] * f[1][i] + f[2][i] * f[2][i]); }

// Max |f| over the points whose ball misses at most one face: the exactness argument needs the
// missing region symmetric about the normal, which edges and corners break.
double max_residual_off_edges(const Body& body, const VectorField& f) {
  double worst = 0;
  std::size_t counted = 0;
  for (std::size_t i = 0; i < body.size(); ++i) {
    int faces = 0;
    for (int k = 0; k < 3; ++k) {
      const double x = body.points.x[std::size_t(k)][i];
      faces += x < delta || x > side - delta;
    }
    if (faces > 1) continue;
    worst = std::max(worst, norm3(f, i));
    ++counted;
  }
  REQUIRE(counted > 100);
  return worst;
}

}  // namespace

TEST_CASE("in 3D s0 is the ball form sqrt(5 G0 / (9 K delta)) with K = lambda + 2 mu / 3") {
  // Evaluated by hand: Kalthoff-Winkler steel (E = 191 GPa, nu = 1/4, G0 = 42408 J/m^2,
  // delta = 2 mm; K = 127.33 GPa) and the glass of Table 1 (72 GPa, 0.23, 3.8 J/m^2, delta = 3 mm;
  // K = 44.44 GPa).
  CHECK(Lps::critical_stretch(42408, 2e-3, lame(191e9, 0.25, Kinematics::solid), 3) == Approx(9.6184e-3).epsilon(1e-4));
  CHECK(Lps::critical_stretch(3.8, 3e-3, lame(72e9, 0.23, Kinematics::solid), 3) == Approx(1.2583e-4).epsilon(1e-4));
  // A 3D deck gets it: the glass cube's bonds carry the 3D value, not eq. (6.3)'s 2D one.
  const auto d = lps_dynamic_body(cube(tension, "{type: explicit, end_time: 1.0e-6}", 3.8));
  CHECK(d.model.s0 == Approx(1.2583e-4).epsilon(1e-4));
}

TEST_CASE("uniaxial tension of a 3D LPS body is an exact equilibrium of the dynamic operator") {
  auto d = lps_dynamic_body(cube(tension));
  REQUIRE(d.body.dim() == 3);
  REQUIRE(d.body.size() == 1000);
  const double E = 72e9, nu = 0.23, sigma = 2e6;
  VectorField u = zero_field(d.body.size()), f = zero_field(d.body.size());
  for (std::size_t i = 0; i < d.body.size(); ++i) {
    u[0][i] = -nu * sigma / E * d.body.points.x[0][i];
    u[1][i] = -nu * sigma / E * d.body.points.x[1][i];
    u[2][i] = sigma / E * d.body.points.x[2][i];
  }
  d.model.internal_forces(d.body, u, f);
  const double scale = sigma / h;  // the size of the terms that cancel
  double loaded = 0;
  for (std::size_t i = 0; i < d.body.size(); ++i) loaded = std::max(loaded, std::abs(f[2][i]));
  CHECK(loaded > 0.1 * scale);  // the elastic forces alone are far from zero near the loaded faces
  d.model.add_loads(0.0, f);
  CHECK(max_residual_off_edges(d.body, f) < 1e-9 * scale);
}

TEST_CASE("simple shear of a 3D LPS body loaded on four faces is an exact equilibrium") {
  // sigma_xz = tau: traction +-tau x on the z faces and +-tau z on the x faces; the y faces are free.
  const std::string shear = R"(
  - {name: top, type: traction, region: {box: {min: [-0.01, -0.01, 0.01], max: [0.02, 0.02, 0.02]}}, value: [1.0e6, 0.0, 0.0]}
  - {name: bottom, type: traction, region: {box: {min: [-0.01, -0.01, -0.01], max: [0.02, 0.02, 0.0]}}, value: [-1.0e6, 0.0, 0.0]}
  - {name: right, type: traction, region: {box: {min: [0.01, -0.01, 0.0], max: [0.02, 0.02, 0.01]}}, value: [0.0, 0.0, 1.0e6]}
  - {name: left, type: traction, region: {box: {min: [-0.01, -0.01, 0.0], max: [0.0, 0.02, 0.01]}}, value: [0.0, 0.0, -1.0e6]})";
  auto d = lps_dynamic_body(cube(shear));
  const double tau = 1e6, mu = 72e9 / (2 * 1.23);
  VectorField u = zero_field(d.body.size()), f = zero_field(d.body.size());
  for (std::size_t i = 0; i < d.body.size(); ++i) {
    u[0][i] = tau / (2 * mu) * d.body.points.x[2][i];
    u[2][i] = tau / (2 * mu) * d.body.points.x[0][i];
  }
  d.model.internal_forces(d.body, u, f);
  d.model.add_loads(0.0, f);
  CHECK(max_residual_off_edges(d.body, f) < 1e-9 * tau / h);
}

TEST_CASE("in 3D masks refreshed after breaks give the forces of a rebuild") {
  auto d = lps_dynamic_body(cube(tension, "{type: explicit, end_time: 1.0e-6}", 3.8));
  // A displacement jump across z = 5.1 mm breaks every bond that crosses it.
  VectorField u = zero_field(d.body.size());
  for (std::size_t i = 0; i < d.body.size(); ++i) u[2][i] = d.body.points.x[2][i] > 0.0051 ? 1e-5 : 0.0;
  const std::size_t broken = d.model.break_bonds(d.body, u);
  CHECK(broken > 1000);
  VectorField w = zero_field(d.body.size()), f1 = zero_field(d.body.size()), f2 = zero_field(d.body.size());
  for (std::size_t i = 0; i < d.body.size(); ++i)
    w[0][i] = 1e-6 * std::sin(300 * d.body.points.x[0][i] + 500 * d.body.points.x[1][i] + 700 * d.body.points.x[2][i]);
  d.model.internal_forces(d.body, w, f1);
  d.model.add_loads(0.0, f1);
  Lps fresh = d.model;
  fresh.prepare(d.body);
  fresh.internal_forces(d.body, w, f2);
  fresh.add_loads(0.0, f2);
  double diff = 0, size = 0;
  for (std::size_t i = 0; i < d.body.size(); ++i) {
    const double dx = f1[0][i] - f2[0][i], dy = f1[1][i] - f2[1][i], dz = f1[2][i] - f2[2][i];
    diff = std::max(diff, std::sqrt(dx * dx + dy * dy + dz * dz));
    size = std::max(size, norm3(f2, i));
  }
  CHECK(diff == 0.0);
  CHECK(size > 0);
  CHECK(d.model.break_bonds(d.body, u) == 0);  // both directions went together
}

TEST_CASE("in 3D Newmark and Verlet converge to each other at second order", "[slow]") {
  // A step load excites every frequency; the two schemes' phase errors differ by O(dt^2).
  const auto difference = [](const std::string& dt) {
    return newmark_verlet::relative_difference(cube(tension, "{type: explicit, end_time: 2.0e-6, dt: " + dt + "}"),
                                               cube(tension, "{type: newmark, end_time: 2.0e-6, dt: " + dt + ", tolerance: 1.0e-12}"), 2e-6);
  };
  const double coarse = difference("2.0e-8"), fine = difference("1.0e-8");
  INFO("relative difference " << coarse << " at dt = 20 ns, " << fine << " at 10 ns");
  CHECK(fine < coarse / 3);
  CHECK(fine < 2e-3);
}
