#include <catch2/catch.hpp>
#include <omp.h>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>
#include "../support/same.hpp"
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

// V_ji (-1 for no bond j -> i).
double weight_back(const BondList& bonds, std::size_t j, std::size_t i) {
  for (auto c = bonds.begin(j); c < bonds.end(j); ++c)
    if (std::size_t(bonds.neighbor[std::size_t(c)]) == i) return bonds.weight[std::size_t(c)];
  return -1;
}

// V_ij = V_ji for every bond of node i.
void check_symmetric_at(const BondList& bonds, std::size_t i) {
  for (auto b = bonds.begin(i); b < bonds.end(i); ++b)
    CHECK_THAT(weight_back(bonds, std::size_t(bonds.neighbor[std::size_t(b)]), i), WithinRel(bonds.weight[std::size_t(b)], 1e-12));
}

double sum_weights(const Grid& g, std::size_t i) {
  double s = 0;
  for (auto b = g.bonds.begin(i); b < g.bonds.end(i); ++b) s += g.bonds.weight[std::size_t(b)];
  return s;
}

}  // namespace

namespace {

// Seed 003 eq. (81) evaluated directly for node i of g: every triangle, its three points at
// barycentric (2/3, 1/6, 1/6) and permutations with weight |T| / 3 each (Sec. 7.1's second-order
// rule), the indicator of |x_q - x_i| <= eps and J = 1 - r/eps; returns V_ij for every node j
// (j = i: the node's own share) and marks the nodes of triangles with a point in the ball.
struct Direct {
  std::vector<double> V;
  std::vector<bool> partner;
};

Direct eq81(const Grid& g, double eps) {
  const std::size_t i = g.centre;
  Direct d{std::vector<double>(g.pc.size(), 0.0), std::vector<bool>(g.pc.size(), false)};
  for (const auto& t : g.pc.triangles) {
    const auto p0 = g.pc.position(std::size_t(t[0])), p1 = g.pc.position(std::size_t(t[1])), p2 = g.pc.position(std::size_t(t[2]));
    const double area = 0.5 * std::abs((p1[0] - p0[0]) * (p2[1] - p0[1]) - (p2[0] - p0[0]) * (p1[1] - p0[1]));
    for (int q = 0; q < 3; ++q) {
      double l[3] = {1.0 / 6, 1.0 / 6, 1.0 / 6};
      l[q] = 2.0 / 3;
      const double x = l[0] * p0[0] + l[1] * p1[0] + l[2] * p2[0], y = l[0] * p0[1] + l[1] * p1[1] + l[2] * p2[1];
      const double r = std::hypot(x - g.pc.position(i)[0], y - g.pc.position(i)[1]);
      if (r > eps) continue;
      for (int a = 0; a < 3; ++a) {
        d.V[std::size_t(t[a])] += (1 - r / eps) * l[a] * area / 3;
        d.partner[std::size_t(t[a])] = true;
      }
    }
  }
  d.partner[i] = false;
  return d;
}

}  // namespace

TEST_CASE("V_ij of an interior node is eq. (81), and with the node's own share the weights integrate J over the ball, pi eps^2 / 3", "[unit]") {
  const double eps = 0.05;
  for (int m : {4, 8, 12, 16}) {
    INFO("m = " << m);
    const auto g = grid(m, eps);
    REQUIRE_THAT(g.pc.position(g.centre)[0], WithinAbs(2 * eps, 1e-12));
    const auto d = eq81(g, eps);
    CHECK(g.bonds.count(g.centre) == std::size_t(std::count(d.partner.begin(), d.partner.end(), true)));
    const double largest = *std::max_element(d.V.begin(), d.V.end());
    for (auto b = g.bonds.begin(g.centre); b < g.bonds.end(g.centre); ++b) {
      const auto j = std::size_t(g.bonds.neighbor[std::size_t(b)]);
      CHECK(d.partner[j]);
      CHECK_THAT(g.bonds.weight[std::size_t(b)], WithinAbs(d.V[j], 1e-13 * largest));  // J = 1 - r/eps cancels at the rim
    }
    // Partition of unity: sum_j V_ij is the rule applied to J on the ball, int J = pi eps^2 / 3
    // (seed 003 Sec. 7.1). The indicator cuts elements where J = 1 - r/eps is already O(h / eps),
    // so its boundary layer costs O((h / eps)^2): 0.004 / m^2 at m = 4, 0.0001 to 0.002 / m^2 at
    // m = 8, 12, 16 (not monotone: the cut depends on where quadrature points fall).
    const double exact = std::numbers::pi * eps * eps / 3;
    const double error = std::abs(sum_weights(g, g.centre) + d.V[g.centre] - exact) / exact;
    INFO("relative error with the own share " << error << ", own share / h^2 " << d.V[g.centre] * m * m / (eps * eps));
    CHECK(error < 0.005 / (m * m));
  }
}

TEST_CASE("The neighbour set includes nodes outside the ball whose elements it cuts", "[unit]") {
  const double eps = 0.05;
  const auto g = grid(4, eps);
  std::size_t outside = 0, inside = 0;
  for (auto b = g.bonds.begin(g.centre); b < g.bonds.end(g.centre); ++b) (g.bonds.length[std::size_t(b)] > eps * (1 + 1e-12) ? outside : inside)++;
  // Inside: the lattice points (a, b) h != 0 with a^2 + b^2 <= 16 (h = eps / 4), counted here;
  // outside: the other nodes of triangles with a quadrature point in the ball, eq. (81) directly.
  std::size_t lattice_points = 0;
  for (int a = -4; a <= 4; ++a)
    for (int b = -4; b <= 4; ++b) lattice_points += (a != 0 || b != 0) && a * a + b * b <= 16;
  const auto d = eq81(g, eps);
  CHECK(inside == lattice_points);
  CHECK(inside + outside == std::size_t(std::count(d.partner.begin(), d.partner.end(), true)));
  CHECK(outside > 0);
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
    check_symmetric_at(g.bonds, g.centre);
  }
}

TEST_CASE("Near a boundary V_ij differs from V_ji", "[unit]") {
  const auto g = grid(4, 0.05);
  const std::size_t corner = 0;  // node (0, 0)
  const auto b = g.bonds.begin(corner);
  const auto j = std::size_t(g.bonds.neighbor[std::size_t(b)]);
  const double back = weight_back(g.bonds, j, corner);
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
  CHECK(same::difference(one.bonds.neighbor, three.bonds.neighbor, "one.bonds.neighbor") == "");
  CHECK(same::difference(one.bonds.weight, three.bonds.weight, "one.bonds.weight") == "");
}

TEST_CASE("Element bonds refuse clouds without triangles and bad horizons or orders", "[unit][input]") {
  auto pc = mesh_points(structured_triangles({0, 0, 0}, {1, 1, 0}, 4, 4));
  CHECK_THROWS_WITH(element_bonds(pc, {.horizon = 0}), Catch::Contains("horizon"));
  CHECK_THROWS_WITH(element_bonds(pc, {.horizon = 0.3, .order = 3}), Catch::Contains("allowed 1, 2, 4, 5"));
  pc.triangles.clear();
  CHECK_THROWS_WITH(element_bonds(pc, {.horizon = 0.3}), Catch::Contains("no mesh triangles or tetrahedra"));
}

namespace {

// A Kuhn-cut cube of side 4 eps in 4m cells per side, whose centre node is interior.
struct Grid3 {
  PointCloud pc;
  BondList bonds;
  std::size_t centre;
};

Grid3 grid3(int m, double eps, int order = 2, KernelShape kernel = KernelShape::linear) {
  const int cells = 4 * m;
  Grid3 g{mesh_points(structured_tetrahedra({0, 0, 0}, {4 * eps, 4 * eps, 4 * eps}, cells, cells, cells)), {}, 0};
  g.bonds = element_bonds(g.pc, {.horizon = eps, .order = order, .kernel = kernel});
  const auto c = std::size_t(2 * m), n = std::size_t(cells + 1);
  g.centre = (c * n + c) * n + c;
  return g;
}

// Seed 003 eq. (81) by brute force for node i: every tetrahedron, every point of the rule, no
// bucketing. V[j] for every node (V[i]: the node's own share); partner[j] marks the nodes of a
// tetrahedron with a point in the ball.
struct Direct3 {
  std::vector<double> V;
  std::vector<bool> partner;
};

Direct3 eq81_tets(const Grid3& g, double eps, int order, KernelShape kernel) {
  const std::size_t i = g.centre;
  const auto rule = tetrahedron_rule(order);
  const Vec3 xi = g.pc.position(i);
  Direct3 d{std::vector<double>(g.pc.size(), 0.0), std::vector<bool>(g.pc.size(), false)};
  for (const auto& t : g.pc.tetrahedra) {
    Vec3 p[4];
    for (std::size_t a = 0; a < 4; ++a) p[a] = g.pc.position(std::size_t(t[a]));
    double e[3][3];
    for (int r = 0; r < 3; ++r)
      for (int k = 0; k < 3; ++k) e[r][k] = p[r + 1][k] - p[0][k];
    const double volume = std::abs(e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1]) - e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0]) +
                                   e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0])) / 6;
    for (std::size_t q = 0; q < rule.weight.size(); ++q) {
      double x[3] = {0, 0, 0};
      for (std::size_t a = 0; a < 4; ++a)
        for (int k = 0; k < 3; ++k) x[k] += rule.lambda[q][a] * p[a][k];
      const double r = std::sqrt((x[0] - xi[0]) * (x[0] - xi[0]) + (x[1] - xi[1]) * (x[1] - xi[1]) + (x[2] - xi[2]) * (x[2] - xi[2]));
      if (r > eps) continue;
      const double J = kernel == KernelShape::linear ? 1 - r / eps : 1.0;
      for (std::size_t a = 0; a < 4; ++a) {
        d.V[std::size_t(t[a])] += J * rule.lambda[q][a] * rule.weight[q] * volume;
        d.partner[std::size_t(t[a])] = true;
      }
    }
  }
  d.partner[i] = false;
  return d;
}

double sum_weights3(const Grid3& g, std::size_t i) {
  double s = 0;
  for (auto b = g.bonds.begin(i); b < g.bonds.end(i); ++b) s += g.bonds.weight[std::size_t(b)];
  return s;
}

}  // namespace

TEST_CASE("Tetrahedron rules integrate polynomials of their degree exactly", "[unit]") {
  // On the reference tetrahedron: the integral of x^a y^b z^c is a! b! c! / (a + b + c + 3)!.
  const auto fact = [](int k) { double f = 1; for (int i = 2; i <= k; ++i) f *= i; return f; };
  for (int order : {1, 2, 5}) {
    const auto r = tetrahedron_rule(order);
    double wsum = 0;
    for (double w : r.weight) {
      CHECK(w > 0);
      wsum += w;
    }
    CHECK_THAT(wsum, WithinAbs(1.0, 1e-14));
    for (int a = 0; a <= order; ++a)
      for (int b = 0; a + b <= order; ++b)
        for (int c = 0; a + b + c <= order; ++c) {
          double q = 0;
          for (std::size_t k = 0; k < r.weight.size(); ++k)
            q += r.weight[k] / 6 * std::pow(r.lambda[k][1], a) * std::pow(r.lambda[k][2], b) * std::pow(r.lambda[k][3], c);
          INFO("order " << order << " x^" << a << " y^" << b << " z^" << c);
          CHECK_THAT(q, WithinRel(fact(a) * fact(b) * fact(c) / fact(a + b + c + 3), 1e-12));
        }
  }
  CHECK_THROWS_WITH(tetrahedron_rule(4), Catch::Contains("allowed 1, 2, 5"));
}

TEST_CASE("On tetrahedra V_ij of an interior node is eq. (81), and with its own share the weights integrate J over the ball, pi eps^3 / 3", "[unit]") {
  const double eps = 0.05;
  for (int m : {2, 3, 4}) {
    INFO("m = " << m);
    const auto g = grid3(m, eps);
    REQUIRE_THAT(g.pc.position(g.centre)[2], WithinAbs(2 * eps, 1e-12));
    const auto d = eq81_tets(g, eps, 2, KernelShape::linear);
    CHECK(g.bonds.count(g.centre) == std::size_t(std::count(d.partner.begin(), d.partner.end(), true)));
    const double largest = *std::max_element(d.V.begin(), d.V.end());
    for (auto b = g.bonds.begin(g.centre); b < g.bonds.end(g.centre); ++b) {
      const auto j = std::size_t(g.bonds.neighbor[std::size_t(b)]);
      CHECK(d.partner[j]);
      CHECK_THAT(g.bonds.weight[std::size_t(b)], WithinAbs(d.V[j], 1e-13 * largest));
    }
    // As in 2D, J = 1 - r/eps is O(h / eps) where the indicator cuts elements, so the rim
    // costs O((h / eps)^2). Measured: 1.3e-3, 1.4e-4, 6.3e-5 at m = 2, 3, 4 (0.0052 to 0.0010 / m^2).
    const double exact = std::numbers::pi * eps * eps * eps / 3;
    const double error = std::abs(sum_weights3(g, g.centre) + d.V[g.centre] - exact) / exact;
    INFO("relative error with the own share " << error);
    CHECK(error < 0.01 / (m * m));
  }
}

TEST_CASE("On tetrahedra with J = 1 the weights of a node, its own share included, integrate the ball's volume", "[unit]") {
  const double eps = 0.05;
  for (int m : {2, 4}) {
    const auto g = grid3(m, eps, 5, KernelShape::constant);
    const auto d = eq81_tets(g, eps, 5, KernelShape::constant);
    const double exact = 4 * std::numbers::pi * eps * eps * eps / 3;
    const double error = std::abs(sum_weights3(g, g.centre) + d.V[g.centre] - exact) / exact;
    // A boundary layer of elements the indicator cuts: O(h / eps). Measured with Keast's rule:
    // 0.015 at m = 2, 0.0042 at m = 4 (0.030 and 0.017 / m).
    INFO("m = " << m << " relative error " << error);
    CHECK(error < 0.06 / m);
  }
}

TEST_CASE("V_ij equals V_ji between interior nodes of Kuhn's cut, which is symmetric about every node", "[unit]") {
  const auto g = grid3(2, 0.05);
  check_symmetric_at(g.bonds, g.centre);
}

TEST_CASE("Element weights on tetrahedra do not depend on the thread count", "[unit]") {
  const int before = omp_get_max_threads();
  omp_set_num_threads(1);
  const auto one = grid3(2, 0.05);
  omp_set_num_threads(3);
  const auto three = grid3(2, 0.05);
  omp_set_num_threads(before);
  CHECK(same::difference(one.bonds.neighbor, three.bonds.neighbor, "one.bonds.neighbor") == "");
  CHECK(same::difference(one.bonds.weight, three.bonds.weight, "one.bonds.weight") == "");
}
