#include <catch2/catch.hpp>
#include <cmath>
#include <numbers>
#include <string>
import peridot.io;

using namespace peridot;

namespace {

const std::string decks = std::string(PERIDOT_SOURCE_DIR) + "/data/decks/lps/";

// Runs a static LPS deck at N cells per side of [-pi/2, pi/2]^2.
StaticErrors run(const std::string& deck, int cells, double horizon_factor = 3.5, double poisson = 0.3, double perturbation = 0.0) {
  Problem p = read_deck(decks + deck);
  p.lattice.spacing = std::numbers::pi / cells;
  p.horizon = horizon_factor * p.lattice.spacing;
  p.material.poisson_ratio = poisson;
  p.lattice.perturbation = perturbation;
  const StaticSetup s = setup_static(p);
  const StaticResult r = solve_static_lps(s.body, s.model, s.problem, s.options);
  REQUIRE(r.residual < 1e-10);
  return static_errors(s, r);
}

double order(double e_coarse, double e_fine) { return std::log2(e_coarse / e_fine); }

}  // namespace

TEST_CASE("the linear patch test with Dirichlet data is exact to 1e-10 on uniform and perturbed grids") {
  for (double factor : {3.5, 3.9})
    for (double nu : {0.3, 0.49}) {
      INFO("delta/h = " << factor << ", nu = " << nu);
      const auto e = run("patch_dirichlet.yaml", 16, factor, nu);
      CHECK(e.u_relative < 1e-10);
      CHECK(e.theta_relative < 1e-10);
    }
  const auto p = run("patch_dirichlet.yaml", 16, 3.5, 0.3, 0.2);
  CHECK(p.u_relative < 1e-10);
  CHECK(p.theta_relative < 1e-10);
}

TEST_CASE("the linear patch test with a traction edge is exact to 1e-10 on uniform grids") {
  for (double factor : {3.5, 3.9})
    for (double nu : {0.3, 0.49}) {
      INFO("delta/h = " << factor << ", nu = " << nu);
      const auto e = run("patch_top_traction.yaml", 16, factor, nu);
      CHECK(e.u_relative < 1e-10);
      CHECK(e.theta_relative < 1e-10);
    }
}

TEST_CASE("static LPS convergence figures (diagnostic)", "[.][diag]") {
  for (const char* deck : {"patch_corner.yaml", "sine_dirichlet.yaml", "sine_top_traction.yaml", "sine_corner.yaml"})
    for (double pert : {0.0, 0.2}) {
      double pu = 0, pt = 0;
      for (int n : {16, 32, 64}) {
        const auto e = run(deck, n, 3.5, 0.3, pert);
        if (pu > 0) WARN(deck << " pert " << pert << " N " << n << " eu " << e.u << " et " << e.theta << " order u " << order(pu, e.u) << " theta " << order(pt, e.theta));
        else WARN(deck << " pert " << pert << " N " << n << " eu " << e.u << " et " << e.theta);
        pu = e.u, pt = e.theta;
      }
    }
}
