#include <catch2/catch.hpp>
#include <cmath>
#include <numbers>
#include <string>

#include "../support/static_study.hpp"
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

TEST_CASE("with a traction edge meeting a corner the patch test converges at first order (setting 3)") {
  const auto l = study::refine("patch_corner.yaml", {16, 32, 64}, {}, "patch_corner_reduced");
  CHECK(study::order(l, false) >= 0.9);
  CHECK(study::order(l, true) >= 0.6);
}

TEST_CASE("the manufactured solution with Dirichlet data converges at second order on uniform and perturbed grids") {
  for (double pert : {0.0, 0.2}) {
    INFO("perturbation " << pert);
    const auto l = study::refine("sine_dirichlet.yaml", {16, 32, 64}, {.perturbation = pert}, "sine_dirichlet_reduced");
    CHECK(study::order(l, false) >= 1.8);
    CHECK(study::order(l, true) >= 1.8);
  }
}

TEST_CASE("the manufactured solution with traction edges converges at first order (settings 2 and 3)") {
  for (const char* deck : {"sine_top_traction.yaml", "sine_corner.yaml"}) {
    INFO(deck);
    const auto l = study::refine(deck, {16, 32, 64}, {}, "sine_traction_reduced");
    CHECK(study::order(l, false) >= 0.9);
    CHECK(study::order(l, true) >= 0.9);
  }
}

TEST_CASE("displacements converge at order 0.8 or better around a free hole, a pressurised hole and an inclusion") {
  for (const char* deck : {"kirsch_hole.yaml", "hollow_disk.yaml", "inclusion.yaml"}) {
    const auto l = study::refine(deck, {16, 32, 64, 128}, {}, std::string(deck).substr(0, std::string(deck).find('.')) + "_reduced");
    INFO(deck << ": order u " << study::order(l, false) << ", order theta " << study::order(l, true));
    CHECK(study::order(l, false) >= 0.8);
    CHECK(study::order(l, true) > 0.3);
  }
}
