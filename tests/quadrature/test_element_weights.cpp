#include <catch2/catch.hpp>
#include <omp.h>
#include <cmath>
#include <numbers>
#include <vector>
import peridot.quadrature;

using namespace peridot;
using Catch::Matchers::WithinAbs;
using Catch::Matchers::WithinRel;

namespace {

// Uniform grid of spacing eps / m on a square wide enough that its centre node is interior.
struct Grid {
  PointCloud pc;
  BondList bonds;
  std::size_t centre;
};

Grid grid(int m, double eps, int order = 2, KernelShape kernel = KernelShape::linear, bool lower_left = true) {
  const int cells = 4 * m;  // square of side 4 eps
  Grid g{mesh_points(structured_triangles({0, 0, 0}, {4 * eps, 4 * eps, 0}, cells, cells, lower_left)), {}, 0};
  g.bonds = element_bonds(g.pc, {.horizon = eps, .order = order, .kernel = kernel});
  g.centre = std::size_t(2 * m * (cells + 1) + 2 * m);
  return g;
}

double sum_weights(const Grid& g, std::size_t i) {
  double s = 0;
  for (auto b = g.bonds.begin(i); b < g.bonds.end(i); ++b) s += g.bonds.weight[std::size_t(b)];
  return s;
}

}  // namespace

TEST_CASE("V_ij of an interior node sums to the spec's fractions of the kernel integral pi eps^2 / 3", "[unit]") {
  // Spec 003 Sec. 2.3: J = 1 - r, 3-point rule, one diagonal per square; node i's own share excluded.
  const double eps = 0.05;
  const struct {
    int m;
    std::size_t partners;
    double ratio;
  } table[] = {{4, 72, 0.9476}, {8, 244, 0.9860}, {12, 518, 0.9936}, {16, 890, 0.9964}};
  for (const auto& row : table) {
    const auto g = grid(row.m, eps);
    REQUIRE_THAT(g.pc.position(g.centre)[0], WithinAbs(2 * eps, 1e-12));
    INFO("m = " << row.m);
    CHECK(g.bonds.count(g.centre) == row.partners);
    CHECK_THAT(sum_weights(g, g.centre) / (std::numbers::pi * eps * eps / 3), WithinAbs(row.ratio, 0.5e-4));
  }
}

TEST_CASE("The neighbour set includes nodes outside the ball whose elements it cuts", "[unit]") {
  const double eps = 0.05;
  const auto g = grid(4, eps);
  std::size_t outside = 0, inside = 0;
  for (auto b = g.bonds.begin(g.centre); b < g.bonds.end(g.centre); ++b) (g.bonds.length[std::size_t(b)] > eps * (1 + 1e-12) ? outside : inside)++;
  CHECK(inside == 48);  // nodes with |x_j - x_i| <= eps (spec table)
  CHECK(outside == 24);
}

TEST_CASE("With J = 1 the weights of a node, its own share included, integrate the ball's area", "[unit]") {
  // Partition of unity: sum over all vertices j of phi_j = 1 at each quadrature point, so the
  // sum is the quadrature of the indicator of the ball, which converges to pi eps^2.
  const double eps = 0.05;
  // The ball's edge cuts elements only through the indicator at quadrature points, so the
  // error is a boundary-layer one, O(h / eps), not monotone in h.
  for (int m : {4, 8, 16}) {
    const auto g = grid(m, eps, 2, KernelShape::constant);
    // Node i's own share: the quadrature points of its elements weighted by phi_i.
    const double h = eps / m;
    double own = 0;
    const auto rule = triangle_rule(2);
    for (const auto& t : g.pc.triangles)
      for (std::size_t a = 0; a < 3; ++a)
        if (std::size_t(t[a]) == g.centre)
          for (std::size_t q = 0; q < rule.weight.size(); ++q) own += rule.lambda[q][a] * rule.weight[q] * h * h / 2;
    const double error = std::abs(sum_weights(g, g.centre) + own - std::numbers::pi * eps * eps) / (std::numbers::pi * eps * eps);
    INFO("m = " << m << " relative error " << error);
    CHECK(error < 0.2 / m);
  }
}

TEST_CASE("V_ij equals V_ji between interior nodes of a uniform grid with one diagonal direction", "[unit]") {
  for (bool lower_left : {true, false}) {
    const auto g = grid(4, 0.05, 2, KernelShape::linear, lower_left);
    const auto i = g.centre;
    for (auto b = g.bonds.begin(i); b < g.bonds.end(i); ++b) {
      const auto j = std::size_t(g.bonds.neighbor[std::size_t(b)]);
      double back = -1;
      for (auto c = g.bonds.begin(j); c < g.bonds.end(j); ++c)
        if (std::size_t(g.bonds.neighbor[std::size_t(c)]) == i) back = g.bonds.weight[std::size_t(c)];
      CHECK_THAT(back, WithinRel(g.bonds.weight[std::size_t(b)], 1e-12));
    }
  }
}

TEST_CASE("Near a boundary V_ij differs from V_ji", "[unit]") {
  const auto g = grid(4, 0.05);
  const std::size_t corner = 0;  // node (0, 0)
  const auto b = g.bonds.begin(corner);
  const auto j = std::size_t(g.bonds.neighbor[std::size_t(b)]);
  double back = -1;
  for (auto c = g.bonds.begin(j); c < g.bonds.end(j); ++c)
    if (g.bonds.neighbor[std::size_t(c)] == 0) back = g.bonds.weight[std::size_t(c)];
  CHECK(std::abs(back - g.bonds.weight[std::size_t(b)]) > 1e-3 * g.bonds.weight[std::size_t(b)]);
}

TEST_CASE("Triangle rules integrate polynomials of their degree exactly", "[unit]") {
  // On the reference triangle (0,0), (1,0), (0,1): the integral of x^a y^b is a! b! / (a + b + 2)!.
  const auto fact = [](int k) { double f = 1; for (int i = 2; i <= k; ++i) f *= i; return f; };
  for (int order : {1, 2, 4, 5}) {
    const auto r = triangle_rule(order);
    double wsum = 0;
    for (double w : r.weight) wsum += w;
    CHECK_THAT(wsum, WithinAbs(1.0, 1e-14));
    for (int a = 0; a <= order; ++a)
      for (int b = 0; a + b <= order; ++b) {
        double q = 0;
        for (std::size_t k = 0; k < r.weight.size(); ++k) q += 0.5 * r.weight[k] * std::pow(r.lambda[k][1], a) * std::pow(r.lambda[k][2], b);
        INFO("order " << order << " x^" << a << " y^" << b);
        CHECK_THAT(q, WithinRel(fact(a) * fact(b) / fact(a + b + 2), 1e-12));
      }
  }
}

TEST_CASE("Element weights do not depend on the thread count", "[unit]") {
  // Each node's sum runs in a fixed quadrature-point order whatever the partition.
  const int before = omp_get_max_threads();
  omp_set_num_threads(1);
  const auto one = grid(4, 0.05);
  omp_set_num_threads(3);
  const auto three = grid(4, 0.05);
  omp_set_num_threads(before);
  CHECK(one.bonds.neighbor == three.bonds.neighbor);
  CHECK(one.bonds.weight == three.bonds.weight);
}

TEST_CASE("Element bonds refuse clouds without triangles and bad horizons or orders", "[unit][input]") {
  auto pc = mesh_points(structured_triangles({0, 0, 0}, {1, 1, 0}, 4, 4));
  CHECK_THROWS_WITH(element_bonds(pc, {.horizon = 0}), Catch::Contains("horizon"));
  CHECK_THROWS_WITH(element_bonds(pc, {.horizon = 0.3, .order = 3}), Catch::Contains("allowed 1, 2, 4, 5"));
  pc.triangles.clear();
  CHECK_THROWS_WITH(element_bonds(pc, {.horizon = 0.3}), Catch::Contains("no mesh triangles"));
}
