#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <vector>
#include "../support/osb_plate.hpp"
import peridot.quadrature;
import peridot.implicit;

using namespace peridot;

namespace {

using osb_plate::Plate, osb_plate::plate, osb_plate::disp, osb_plate::trac;

// Relative nodal errors (66) of a solve against a closed-form displacement, in percent.
struct Spread {
  double lo_u = 1e300, hi_u = 0, lo_v = 1e300, hi_v = 0, max_v = 0, lambda = 0;
};

template <class Ref>
Spread spread(const Plate& p, const OsbStaticResult& r, Ref ref) {
  Spread s;
  for (std::size_t i = 0; i < p.body.size(); ++i) {
    if (p.body.points.role[i] != Role::interior) continue;
    const auto u0 = ref(p.body.points.position(i));
    const double eu = std::abs(r.u[0][i] - u0[0]) / std::abs(u0[0]) * 100;
    s.lo_u = std::min(s.lo_u, eu), s.hi_u = std::max(s.hi_u, eu);
    if (u0[1] != 0) {
      const double ev = std::abs(r.u[1][i] - u0[1]) / std::abs(u0[1]) * 100;
      s.lo_v = std::min(s.lo_v, ev), s.hi_v = std::max(s.hi_v, ev);
    }
    s.max_v = std::max(s.max_v, std::abs(r.u[1][i]));
  }
  for (double l : r.multipliers) s.lambda = std::max(s.lambda, std::abs(l));
  return s;
}

constexpr double pbar = 1e6, E = 1e9, nu = 0.2;

OsbStaticProblem traction_problem(int order) {
  OsbStaticProblem prob;
  prob.taylor_order = order;
  auto& e = prob.conditions.edge;
  e[int(Edge::left)] = {disp(0), trac(0)};
  e[int(Edge::bottom)] = {trac(0), disp(0)};
  e[int(Edge::right)] = {trac(pbar), trac(0)};
  return prob;
}

}  // namespace

TEST_CASE("Ex. 1 traction: the corrected error is uniform and equals Table 2", "[osb][slow]") {
  // Seed 004 Table 2 (percent), printed to two decimals; the error is the same at every node.
  const double mbar[] = {3, 4, 5, 6}, table_u[] = {0.43, 0.09, 0.04, 0.02}, table_v[] = {2.15, 0.45, 0.18, 0.09};
  for (int order = 1; order <= 3; ++order)
    for (int k = 0; k < 4; ++k) {
      auto p = plate(mbar[k], true);
      const auto r = solve_osb_static(p.body, p.model, traction_problem(order));
      const auto s = spread(p, r, [](const Vec3& x) { return std::array<double, 2>{pbar / E * (x[0] + 0.15), -nu * pbar / E * (x[1] + 0.1)}; });
      INFO("order " << order << ", mbar " << mbar[k] << ": eu " << s.lo_u << ".." << s.hi_u << ", ev " << s.lo_v << ".." << s.hi_v);
      CHECK(std::round(s.hi_u * 100) / 100 == Approx(table_u[k]).margin(1e-12));
      CHECK(std::round(s.hi_v * 100) / 100 == Approx(table_v[k]).margin(1e-12));
      CHECK(s.hi_u - s.lo_u < 1e-5 * s.hi_u);  // uniform up to the round-off of a cond ~ 1e4 solve
      CHECK(s.hi_v - s.lo_v < 1e-5 * s.hi_v);
      // Multipliers vanish on the patch test; loads are p / h = 1e8 N/m^3.
      CHECK(s.lambda < 1e-9 * pbar / 0.01);
      CHECK(r.residual < 1e-12);
    }
}

TEST_CASE("Ex. 2 shear: v vanishes and the u error equals Table 3", "[osb][slow]") {
  const double G = E / (2 * (1 + nu));
  const double mbar[] = {3, 4, 5, 6}, table[] = {0.73, 0.15, 0.06, 0.03};
  for (int order = 1; order <= 2; ++order)
    for (int k = 0; k < 4; ++k) {
      auto p = plate(mbar[k], true);
      OsbStaticProblem prob;
      prob.taylor_order = order;
      auto& e = prob.conditions.edge;
      e[int(Edge::bottom)] = {disp(0), disp(0)};
      e[int(Edge::top)] = {trac(pbar), trac(0)};
      e[int(Edge::left)] = {trac(0), trac(-pbar)};
      e[int(Edge::right)] = {trac(0), trac(pbar)};
      const auto r = solve_osb_static(p.body, p.model, prob);
      const auto s = spread(p, r, [&](const Vec3& x) { return std::array<double, 2>{pbar / G * (x[1] + 0.1), 0.0}; });
      INFO("order " << order << ", mbar " << mbar[k] << ": eu " << s.lo_u << ".." << s.hi_u << ", max |v| " << s.max_v);
      CHECK(std::round(s.hi_u * 100) / 100 == Approx(table[k]).margin(1e-12));
      CHECK(s.hi_u - s.lo_u < 1e-5 * s.hi_u);  // uniform up to the round-off of a cond ~ 1e4 solve
      CHECK(s.max_v < 1e-12 * pbar / G * 0.2);
      CHECK(s.lambda < 1e-9 * pbar / 0.01);
    }
}

TEST_CASE("Taylor weights reproduce the paper's boundary-node and corner stencils", "[osb]") {
  // Eq. (58): a boundary node half a cell out, n_max = 2.
  const auto w = taylor_weights(2, {{0, 0}, {-1, 0}, {-2, 0}}, {0.5, 0});
  CHECK(w[0] == Approx(15.0 / 8));
  CHECK(w[1] == Approx(-5.0 / 4));
  CHECK(w[2] == Approx(3.0 / 8));
  // Eq. (42) substituted into (37) at the corner offset (1, 1): u_i = u_j + u_x + u_y + (u_xx + 2 u_xy + u_yy) / 2
  // on the stencil j, j1 = (-1, 0), j2 = (0, -1), j3 = (-2, 0), j4 = (-1, -1), j5 = (0, -2).
  const auto c = taylor_weights(2, {{0, 0}, {-1, 0}, {0, -1}, {-2, 0}, {-1, -1}, {0, -2}}, {1, 1});
  // By hand from (42): j: 1 + 3/2 + 3/2 + 1/2 + 1 + 1/2 = 6; j1: -2 - 1 - 1 = -4; j2: -4; j3: 1/2 + 1/2 = 1; j4: 1; j5: 1.
  const double expect[] = {6, -4, -4, 1, 1, 1};
  for (int k = 0; k < 6; ++k) CHECK(c[std::size_t(k)] == Approx(expect[k]).margin(1e-12));
}
