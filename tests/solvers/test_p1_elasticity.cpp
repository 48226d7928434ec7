#include <catch2/catch.hpp>
#include <cmath>
#include <numbers>
#include <vector>
import peridot.implicit;

using namespace peridot;

namespace {

// Max nodal error against u = (sin(pi x) sin(pi y), x y (1 - x)(1 - y)) on the clamped unit
// square; f = -div sigma of that field, written out by hand for lambda = mu = 1.
double p1_error(int n) {
  const double pi = std::numbers::pi;
  P1Problem p;
  p.material = {1.0, 1.0};
  p.clamped = [](const Vec3& x) { return x[0] < 1e-12 || x[0] > 1 - 1e-12 || x[1] < 1e-12 || x[1] > 1 - 1e-12; };
  // sigma = lambda tr(eps) I + 2 mu eps; -div sigma = -(lambda + mu) grad div u - mu lap u.
  p.body_force = [pi](const Vec3& x) {
    const double X = x[0], Y = x[1];
    const double uxx = -pi * pi * std::sin(pi * X) * std::sin(pi * Y), uxy = pi * pi * std::cos(pi * X) * std::cos(pi * Y);
    const double uyy = -pi * pi * std::sin(pi * X) * std::sin(pi * Y);
    const double vxx = -2 * Y * (1 - Y), vyy = -2 * X * (1 - X), vxy = (1 - 2 * X) * (1 - 2 * Y);
    const double ddx = uxx + vxy, ddy = uxy + vyy;  // grad div u
    return std::array<double, 2>{-(2 * ddx + (uxx + uyy)), -(2 * ddy + (vxx + vyy))};
  };
  const auto mesh = structured_triangles({0, 0, 0}, {1, 1, 0}, n, n);
  const auto u = solve_p1_elasticity(mesh, p);
  double err = 0;
  for (std::size_t i = 0; i < mesh.nodes.size(); ++i) {
    const double X = mesh.nodes[i][0], Y = mesh.nodes[i][1];
    err = std::max({err, std::abs(u[i][0] - std::sin(pi * X) * std::sin(pi * Y)), std::abs(u[i][1] - X * Y * (1 - X) * (1 - Y))});
  }
  return err;
}

}  // namespace

TEST_CASE("P1 triangles converge at second order at the nodes to a manufactured elastic solution", "[slow]") {
  const double e16 = p1_error(16), e32 = p1_error(32), e64 = p1_error(64);
  INFO("errors " << e16 << ", " << e32 << ", " << e64);
  CHECK(std::log2(e16 / e32) > 1.8);
  CHECK(std::log2(e32 / e64) > 1.8);
  CHECK(e64 < 1e-3);
}

TEST_CASE("P1 interpolation reproduces a linear field inside the mesh and refuses points outside it") {
  const auto mesh = structured_triangles({0, 0, 0}, {2, 1, 0}, 4, 2, false);
  CHECK(mesh.nodes.size() == 15);
  CHECK(mesh.triangles.size() == 16);
  std::vector<std::array<double, 2>> u(mesh.nodes.size());
  for (std::size_t i = 0; i < u.size(); ++i) u[i] = {3 * mesh.nodes[i][0] - mesh.nodes[i][1], 0.5 * mesh.nodes[i][1]};
  const auto v = interpolate(mesh, u, {1.3, 0.7, 0});
  CHECK(v[0] == Approx(3 * 1.3 - 0.7));
  CHECK(v[1] == Approx(0.35));
  CHECK_THROWS(interpolate(mesh, u, {3, 0.5, 0}));
}
