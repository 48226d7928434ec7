#include <catch2/catch.hpp>
#include <array>
#include <cmath>
#include <numbers>
import peridot.models;

using namespace peridot;

namespace {

const ElasticConstants steel = lame(1.0, 0.3, Kinematics::plane_strain);

// -div sigma by central differences of the closed-form stress, step s, over the solution's
// dimensions.
std::array<double, 3> minus_div_sigma(const ElasticSolution& e, Vec3 x, double s) {
  std::array<double, 3> f{0, 0, 0};
  for (int b = 0; b < e.dim; ++b) {
    Vec3 lo = x, hi = x;
    lo[b] -= s;
    hi[b] += s;
    const auto s0 = e.stress(lo), s1 = e.stress(hi);
    for (int a = 0; a < 3; ++a) f[std::size_t(a)] -= (s1[std::size_t(3 * a + b)] - s0[std::size_t(3 * a + b)]) / (2 * s);
  }
  return f;
}

// Radial traction sigma_rr at angle t on the circle of radius r about the origin.
double sigma_rr(const ElasticSolution& e, double r, double t) {
  const std::array<double, 3> n{std::cos(t), std::sin(t), 0};
  const auto T = e.traction({r * n[0], r * n[1], 0}, n);
  return T[0] * n[0] + T[1] * n[1];
}

}  // namespace

TEST_CASE("the manufactured solution's body force equals -div sigma of its own field, computed numerically") {
  const auto e = manufactured_sine(0.4, steel);
  for (Vec3 x : {Vec3{0.3, -0.7, 0}, Vec3{1.1, 0.2, 0}, Vec3{-1.4, 1.3, 0}}) {
    const auto f = e.body_force(x);
    const auto d = minus_div_sigma(e, x, 1e-4);
    CHECK(f[0] == Approx(d[0]).epsilon(1e-6).margin(1e-9));
    CHECK(f[1] == Approx(d[1]).epsilon(1e-6).margin(1e-9));
  }
  // and the patch test field is in equilibrium with no body force.
  const auto p = linear_patch(steel);
  const auto d = minus_div_sigma(p, {0.2, 0.5, 0}, 1e-3);
  CHECK(std::abs(d[0]) < 1e-9);
  CHECK(std::abs(d[1]) < 1e-9);
}

TEST_CASE("the 3D manufactured solution's body force equals -div sigma of its own field, and its field is the 2D one's extension") {
  const auto c = lame(1.0, 0.3, Kinematics::solid);
  const auto e = manufactured_sine(0.4, c, 3);
  for (Vec3 x : {Vec3{0.3, -0.7, 0.5}, Vec3{1.1, 0.2, -1.2}, Vec3{-1.4, 1.3, 0.9}}) {
    const auto f = e.body_force(x);
    const auto d = minus_div_sigma(e, x, 1e-4);
    for (int a = 0; a < 3; ++a) CHECK(f[std::size_t(a)] == Approx(d[std::size_t(a)]).epsilon(1e-6).margin(1e-9));
    // Every component depends on z, and the dilatation does not vanish.
    CHECK(std::abs(e.dilatation(x)) > 1e-3);
  }
  // The field against its closed form, u = (sin sin sin, -cos cos sin, cos sin cos) of A x.
  const Vec3 x{0.3, -0.7, 0.5};
  const double A = 0.4;
  const auto u = e.displacement(x);
  CHECK(u[0] == Approx(std::sin(A * 0.3) * std::sin(-A * 0.7) * std::sin(A * 0.5)).epsilon(1e-14));
  CHECK(u[1] == Approx(-std::cos(A * 0.3) * std::cos(-A * 0.7) * std::sin(A * 0.5)).epsilon(1e-14));
  CHECK(u[2] == Approx(std::cos(A * 0.3) * std::sin(-A * 0.7) * std::cos(A * 0.5)).epsilon(1e-14));
  // The 2D solution is the paper's (Sec. 5.2): u = (sin Ax sin Ay, -cos Ax cos Ay), with the
  // body force 2 (lambda + 2 mu) A^2 u.
  const auto e2 = manufactured_sine(A, steel);
  const auto u2 = e2.displacement(x);
  CHECK(u2[0] == Approx(std::sin(A * 0.3) * std::sin(-A * 0.7)).epsilon(1e-14));
  CHECK(u2[1] == Approx(-std::cos(A * 0.3) * std::cos(-A * 0.7)).epsilon(1e-14));
  CHECK(u2[2] == 0.0);
  const double k = 2 * (steel.lambda + 2 * steel.mu) * A * A;
  CHECK(e2.body_force(x)[0] == Approx(k * u2[0]).epsilon(1e-13));
  CHECK(e2.body_force(x)[1] == Approx(k * u2[1]).epsilon(1e-13));
  // and the 3D patch field is in equilibrium with no body force, with a full gradient.
  const auto p = linear_patch(c, 3);
  const auto dp = minus_div_sigma(p, {0.2, 0.5, -0.3}, 1e-3);
  for (double v : dp) CHECK(std::abs(v) < 1e-9);
  CHECK(p.dilatation({0.2, 0.5, -0.3}) == Approx(7.0));
}

TEST_CASE("Kirsch's hole is traction free, sigma_rr(a) = 0, and far away the stress is sigma0 along x") {
  const double a = 0.2, s0 = 1.0;
  const auto e = kirsch_hole(a, s0, steel);
  // Its gradient is a fourth-order finite difference with step 1e-3 a: round-off of about
  // 1e-16 / 1e-3 a and truncation of about 1e-12 bound what can be asked, 1e-9 sigma0.
  for (double t = 0; t < 2 * std::numbers::pi; t += 0.37) {
    INFO("theta = " << t);
    CHECK(std::abs(sigma_rr(e, a, t)) < 1e-9 * s0);
    const std::array<double, 3> n{std::cos(t), std::sin(t), 0};
    const auto T = e.traction({a * n[0], a * n[1], 0}, n);
    CHECK(std::abs(-T[0] * n[1] + T[1] * n[0]) < 1e-9 * s0);  // no shear on the hole either
  }
  const auto far = e.stress({1e4, 3e3, 0});
  CHECK(far[0] == Approx(s0).epsilon(1e-6));
  CHECK(std::abs(far[4]) < 1e-6);
  // Stress concentration 3 sigma0 at the top of the hole.
  CHECK(e.stress({0, a, 0})[0] == Approx(3 * s0).epsilon(1e-9));
  const auto d = minus_div_sigma(e, {0.5, 0.3, 0}, 1e-5);
  CHECK(std::abs(d[0]) < 1e-6);
  CHECK(std::abs(d[1]) < 1e-6);
}

TEST_CASE("the hollow disk carries sigma_rr(R0) = -p0 on the pressurised hole and sigma_rr(R1) = 0 outside") {
  const double R0 = 1.0, R1 = 1.5, p0 = 0.1;
  const auto e = hollow_disk(R0, R1, p0, steel);
  for (double t = 0; t < 2 * std::numbers::pi; t += 0.5) {
    CHECK(sigma_rr(e, R0, t) == Approx(-p0).epsilon(1e-12));
    CHECK(std::abs(sigma_rr(e, R1, t)) < 1e-12);
  }
  const auto d = minus_div_sigma(e, {1.2, 0.3, 0}, 1e-5);
  CHECK(std::abs(d[0]) < 1e-6);
  CHECK(std::abs(d[1]) < 1e-6);
}

TEST_CASE("the circular inclusion is hydrostatic inside, continuous in traction across r = a, and in equilibrium") {
  const double a = 0.2, P = 1.0;
  const auto inner = lame(2.0, 0.25, Kinematics::plane_strain);
  const auto e = circular_inclusion(a, P, inner, steel);
  const auto s = e.stress({0.05, 0.03, 0});
  CHECK(s[0] == Approx(P).epsilon(1e-12));
  CHECK(s[4] == Approx(P).epsilon(1e-12));
  CHECK(std::abs(s[1]) < 1e-12);
  for (double t = 0; t < 2 * std::numbers::pi; t += 0.7) {
    const double in = sigma_rr(e, a * (1 - 1e-9), t), out = sigma_rr(e, a * (1 + 1e-9), t);
    CHECK(in == Approx(out).epsilon(1e-6));
  }
  const auto d = minus_div_sigma(e, {0.5, 0.3, 0}, 1e-5);
  CHECK(std::abs(d[0]) < 1e-6);
  CHECK(std::abs(d[1]) < 1e-6);
}

TEST_CASE("the spherical inclusion is hydrostatic inside, continuous in displacement and traction across r = a, and in equilibrium") {
  const double a = 0.2, P = 1.0;
  const auto matrix = lame(1.0, 0.3, Kinematics::solid), inner = lame(2.0, 0.25, Kinematics::solid);
  const auto e = spherical_inclusion(a, P, inner, matrix);
  REQUIRE(e.dim == 3);
  const auto s = e.stress({0.05, 0.03, -0.04});
  for (int k : {0, 4, 8}) CHECK(s[std::size_t(k)] == Approx(P).epsilon(1e-12));
  for (int k : {1, 2, 5}) CHECK(std::abs(s[std::size_t(k)]) < 1e-12);
  // Across the sphere, in directions off every axis: u and the whole traction sigma n agree.
  for (double t = 0.3; t < std::numbers::pi; t += 0.9)
    for (double f = 0.1; f < 2 * std::numbers::pi; f += 1.3) {
      const Vec3 n{std::sin(t) * std::cos(f), std::sin(t) * std::sin(f), std::cos(t)};
      const auto at = [&](double r) { return Vec3{r * n[0], r * n[1], r * n[2]}; };
      const auto u0 = e.displacement(at(a * (1 - 1e-9))), u1 = e.displacement(at(a * (1 + 1e-9)));
      const auto t0 = e.traction(at(a * (1 - 1e-9)), {n[0], n[1], n[2]}), t1 = e.traction(at(a * (1 + 1e-9)), {n[0], n[1], n[2]});
      for (std::size_t k = 0; k < 3; ++k) {
        CHECK(u0[k] == Approx(u1[k]).margin(1e-9));
        CHECK(t0[k] == Approx(t1[k]).margin(1e-6));
      }
    }
  // The gradient is the field's, by central differences, and sigma of it is divergence free.
  for (const Vec3& x : {Vec3{0.05, -0.1, 0.08}, Vec3{0.4, 0.3, -0.2}}) {
    const auto g = e.field(x).grad;
    for (int b = 0; b < 3; ++b) {
      Vec3 lo = x, hi = x;
      lo[b] -= 1e-6;
      hi[b] += 1e-6;
      const auto u0 = e.displacement(lo), u1 = e.displacement(hi);
      for (int c = 0; c < 3; ++c) CHECK(g[std::size_t(3 * c + b)] == Approx((u1[std::size_t(c)] - u0[std::size_t(c)]) / 2e-6).margin(1e-7));
    }
    const auto d = minus_div_sigma(e, x, 1e-5);
    for (std::size_t k = 0; k < 3; ++k) CHECK(std::abs(d[k]) < 1e-6);
  }
}
