#include <catch2/catch.hpp>
#include <cmath>
#include <numbers>
import peridot.models;

using namespace peridot;

namespace {

// A 9x9 lattice, delta = 2.5 h, unit volumes as weights.
Body hand_sized() {
  Body b;
  b.points = lattice(rectangle({0, 0, 0}, {9, 9, 0}), {.spacing = 1.0});
  b.bonds = build_bonds(b.points, {.horizon = 2.5});
  return b;
}

std::size_t centre(const Body& b) { return b.size() / 2; }  // (4.5, 4.5)

}  // namespace

TEST_CASE("the pseudo-inverse of a symmetric 2x2 matrix inverts regular matrices and rank-one ones in the Moore-Penrose sense") {
  const auto inv = pseudo_inverse_sym2({2, 1, 1, 3});
  CHECK(inv[0] == Approx(0.6));
  CHECK(inv[1] == Approx(-0.2));
  CHECK(inv[3] == Approx(0.4));
  // Rank one: a = 4 v v^T with v = (0.6, 0.8); pinv = v v^T / 4.
  const auto p = pseudo_inverse_sym2({4 * 0.36, 4 * 0.48, 4 * 0.48, 4 * 0.64});
  CHECK(p[0] == Approx(0.36 / 4));
  CHECK(p[1] == Approx(0.48 / 4));
  CHECK(p[3] == Approx(0.64 / 4));
  CHECK(pseudo_inverse_sym2({0, 0, 0, 0})[0] == 0.0);
}

TEST_CASE("two-point moduli are harmonic means (eqs. 5.3-5.5)") {
  const auto l = Lps::make(2, 1.0, {1.0, 3.0}, {2.0, 6.0});
  CHECK(l.lambda_ij(0, 1) == Approx(1.5));
  CHECK(l.mu_ij(0, 1) == Approx(3.0));
  // (5.4) is symmetric in x and y.
  CHECK(l.lambda_ij(1, 0) == l.lambda_ij(0, 1));
  CHECK(l.mu_ij(1, 0) == l.mu_ij(0, 1));
  CHECK(l.m == Approx(2 * std::numbers::pi / 3));
  CHECK_THROWS_WITH(Lps::make(2, 1.0, {1.0}, {-1.0}), Catch::Contains("mu > 0"));
}

TEST_CASE("M_i (eq. 4.8) of a full ball on the unit lattice is the closed-form lattice sum, and a full symmetric ball has no normal") {
  Body b = hand_sized();
  const auto l = Lps::homogeneous(2, 2.5, b.size(), {1, 1});
  const auto i = centre(b);
  const auto f = lps_frame(b, l, i);
  CHECK_FALSE(f.has_missing);
  CHECK_FALSE(f.has_normal);
  // The partners of a lattice point at delta = 2.5 with unit weights are the 20 offsets (a, b) != 0
  // with a^2 + b^2 <= 6.25: (+-1, 0) and (0, +-1), (+-1, +-1), (+-2, 0) and (0, +-2), (+-2, +-1) and
  // (+-1, +-2). With K = 1/|xi|, sum K x^2 = 2 + 4/sqrt(2) + 4 + (16 + 4)/sqrt(5) = 6 + 2 sqrt(2) + 4 sqrt(5),
  // the same for y^2 and 0 for xy by symmetry, so (4.8) gives M = m / (2 (6 + 2 sqrt(2) + 4 sqrt(5))) I
  // (the continuum ball would give I: 2/m int_B K x^2 = 1).
  REQUIRE(b.bonds.count(i) == 20);
  const double sxx = 6 + 2 * std::sqrt(2.0) + 4 * std::sqrt(5.0);
  const double m = 2 * std::numbers::pi * 2.5 * 2.5 * 2.5 / 3;
  CHECK(f.M[0] == Approx(m / (2 * sxx)).epsilon(1e-13));
  CHECK(f.M[3] == Approx(m / (2 * sxx)).epsilon(1e-13));
  CHECK(std::abs(f.M[1]) < 1e-14);
  CHECK(std::abs(f.M[2]) < 1e-14);
}

TEST_CASE("the numerical normal (eq. 4.9) points towards the missing partners") {
  Body b = hand_sized();
  const auto l = Lps::homogeneous(2, 2.5, b.size(), {1, 1});
  const auto i = centre(b);
  for (auto k = b.bonds.begin(i); k < b.bonds.end(i); ++k)
    if (b.bonds.xi[1][k] > 0) b.bonds.intact[k] = 0;  // everything above is outside
  const auto f = lps_frame(b, l, i);
  REQUIRE(f.has_normal);
  CHECK(f.n[0] == Approx(0.0).margin(1e-12));
  CHECK(f.n[1] == Approx(1.0));
  CHECK(f.p[0] * f.n[0] + f.p[1] * f.n[1] == Approx(0.0).margin(1e-12));
}

TEST_CASE("an isolated point (every bond broken) gets M = 0 and no normal instead of a failure") {
  Body b = hand_sized();
  const auto l = Lps::homogeneous(2, 2.5, b.size(), {1, 1});
  const auto i = centre(b);
  for (auto k = b.bonds.begin(i); k < b.bonds.end(i); ++k) b.bonds.intact[k] = 0;
  const auto f = lps_frame(b, l, i);
  CHECK(f.has_missing);
  CHECK_FALSE(f.has_normal);
  for (double m : f.M) CHECK(m == 0.0);
}

TEST_CASE("the corrected dilatation (eqs. 4.7-4.8) is exact for linear displacements on a truncated ball") {
  // Through lps_dilatation, the function the static solver uses for collar points.
  Body b = hand_sized();
  const auto l = Lps::homogeneous(2, 2.5, b.size(), {1, 1});
  const auto i = centre(b);
  for (auto k = b.bonds.begin(i); k < b.bonds.end(i); ++k)
    if (b.bonds.xi[0][k] + 0.5 * b.bonds.xi[1][k] > 0.7) b.bonds.intact[k] = 0;  // an oblique cut
  const double G[4] = {0.3, -1.2, 0.7, 2.1};  // u = G x + c, div u = 2.4
  VectorField u = zero_field(b.size());
  for (std::size_t j = 0; j < b.size(); ++j) {
    const double x = b.points.x[0][j], y = b.points.x[1][j];
    u[0][j] = G[0] * x + G[1] * y + 0.25;
    u[1][j] = G[2] * x + G[3] * y - 1.5;
  }
  CHECK(lps_dilatation(b, l, lps_frame(b, l, i), i, u) == Approx(2.4).epsilon(1e-12));
  // Without the correction M_i the truncated ball misses div u: the check above can fail.
  LpsFrame plain = lps_frame(b, l, i);
  plain.M = {1, 0, 0, 1};
  CHECK(std::abs(lps_dilatation(b, l, plain, i, u) - 2.4) > 0.1);
}
