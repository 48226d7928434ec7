#include <catch2/catch.hpp>
#include <array>
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
  CHECK(f.M[4] == Approx(m / (2 * sxx)).epsilon(1e-13));
  CHECK(std::abs(f.M[1]) < 1e-14);
  CHECK(std::abs(f.M[3]) < 1e-14);
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
  plain.M = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  CHECK(std::abs(lps_dilatation(b, l, plain, i, u) - 2.4) > 0.1);
}

// ---- 3D ----

namespace {

// A 9x9x9 lattice, delta = 2.5 h, unit volumes as weights.
Body hand_sized_3d() {
  Body b;
  b.points = lattice(box({0, 0, 0}, {9, 9, 9}), {.spacing = 1.0});
  b.bonds = build_bonds(b.points, {.horizon = 2.5});
  return b;
}

}  // namespace

TEST_CASE("the pseudo-inverse of a symmetric 3x3 matrix inverts regular matrices and rank-deficient ones in the Moore-Penrose sense") {
  const std::array<double, 9> a{4, 1, 0, 1, 3, 1, 0, 1, 2};
  const auto inv = pseudo_inverse_sym3(a);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      double v = 0;
      for (int k = 0; k < 3; ++k) v += a[std::size_t(3 * r + k)] * inv[std::size_t(3 * k + c)];
      CHECK(v == Approx(r == c ? 1.0 : 0.0).margin(1e-14));
    }
  // Rank two: a = 2 e1 e1^T + 5 v v^T with v = (0, 0.6, 0.8); pinv = e1 e1^T / 2 + v v^T / 5.
  const std::array<double, 9> r2{2, 0, 0, 0, 5 * 0.36, 5 * 0.48, 0, 5 * 0.48, 5 * 0.64};
  const auto p = pseudo_inverse_sym3(r2);
  const std::array<double, 9> expected{0.5, 0, 0, 0, 0.36 / 5, 0.48 / 5, 0, 0.48 / 5, 0.64 / 5};
  for (std::size_t k = 0; k < 9; ++k) CHECK(p[k] == Approx(expected[k]).margin(1e-14));
  for (double v : pseudo_inverse_sym3({})) CHECK(v == 0.0);
}

TEST_CASE("the 3D model has the paper's constants for d = 3: C_alpha = 3, C_beta = 30 and m = pi delta^4 for K = 1/r") {
  const auto l = Lps::homogeneous(3, 2.0, 1, {1, 1});
  CHECK(l.c_alpha == 3);
  CHECK(l.c_beta == 30);
  // m = int_B (1/r) r^2 dV = 4 pi int_0^delta r^3 dr.
  CHECK(l.m == Approx(std::numbers::pi * 16));
}

TEST_CASE("in 3D, M_i (eq. 4.8) of a full ball on the unit lattice is the closed-form lattice sum") {
  Body b = hand_sized_3d();
  const auto l = Lps::homogeneous(3, 2.5, b.size(), {1, 1});
  const std::size_t i = b.size() / 2;  // (4.5, 4.5, 4.5)
  const auto f = lps_frame(b, l, i);
  CHECK_FALSE(f.has_missing);
  CHECK_FALSE(f.has_normal);
  // The 80 offsets with |o|^2 <= 6.25, grouped by |o|^2 = 1, 2, 3, 4, 5, 6 (6, 12, 8, 6, 24, 24
  // of them). Sum of x^2 / |o| per group: 2, 8/sqrt 2, 8/sqrt 3, 8/2, 40/sqrt 5, 48/sqrt 6.
  REQUIRE(b.bonds.count(i) == 80);
  const double sxx = 2 + 8 / std::sqrt(2.0) + 8 / std::sqrt(3.0) + 4 + 40 / std::sqrt(5.0) + 48 / std::sqrt(6.0);
  const double m = std::numbers::pi * std::pow(2.5, 4);
  for (int k : {0, 4, 8}) CHECK(f.M[std::size_t(k)] == Approx(m / (3 * sxx)).epsilon(1e-13));
  for (int k : {1, 2, 3, 5, 6, 7}) CHECK(std::abs(f.M[std::size_t(k)]) < 1e-14);
}

TEST_CASE("in 3D the corrected dilatation is exact for linear displacements on an obliquely cut ball, and the normal points to the missing side") {
  Body b = hand_sized_3d();
  const auto l = Lps::homogeneous(3, 2.5, b.size(), {1, 1});
  const std::size_t i = b.size() / 2;
  for (auto k = b.bonds.begin(i); k < b.bonds.end(i); ++k)
    if (b.bonds.xi[0][k] + 0.5 * b.bonds.xi[1][k] - 0.3 * b.bonds.xi[2][k] > 0.7) b.bonds.intact[k] = 0;
  const double G[9] = {0.3, -1.2, 0.5, 0.7, 2.1, -0.4, 1.1, 0.2, -0.9};  // div u = 1.5
  VectorField u = zero_field(b.size());
  for (std::size_t j = 0; j < b.size(); ++j)
    for (int a = 0; a < 3; ++a)
      u[std::size_t(a)][j] = G[3 * a] * b.points.x[0][j] + G[3 * a + 1] * b.points.x[1][j] + G[3 * a + 2] * b.points.x[2][j] + 0.1 * a;
  const auto f = lps_frame(b, l, i);
  CHECK(lps_dilatation(b, l, f, i, u) == Approx(1.5).epsilon(1e-12));
  // Without M_i the cut ball is off by 2.4e-2 here (1.6 %), ten orders above the corrected one.
  LpsFrame plain = f;
  plain.M = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  CHECK(std::abs(lps_dilatation(b, l, plain, i, u) - 1.5) > 1e-3);
  // A flat cut z > 0: the normal is +z.
  Body c = hand_sized_3d();
  for (auto k = c.bonds.begin(i); k < c.bonds.end(i); ++k)
    if (c.bonds.xi[2][k] > 0) c.bonds.intact[k] = 0;
  const auto g = lps_frame(c, l, i);
  REQUIRE(g.has_normal);
  CHECK(g.n[0] == Approx(0.0).margin(1e-12));
  CHECK(g.n[1] == Approx(0.0).margin(1e-12));
  CHECK(g.n[2] == Approx(1.0));
}
