// Seed 000 (Yu, You & Trask 2021) Sec. 5, full sweeps. Each study writes
// <build>/studies/<name>.csv; tools/plot_convergence.py draws them.
#include <catch2/catch.hpp>
#include <cmath>
#include <string>
#include <utility>

#include "../support/static_study.hpp"
import peridot.problem;

using study::Variant;

namespace {

std::string tag(const std::string& deck, const Variant& v) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "_d%.1f_nu%.2f_p%.1f", v.horizon_factor, v.poisson, v.perturbation);
  return deck.substr(0, deck.find('.')) + buf;
}

}  // namespace

TEST_CASE("Sec. 5.1: the patch test is exact with Dirichlet data (uniform and perturbed) and with a traction edge (uniform)") {
  for (double d : {3.5, 3.9})
    for (double nu : {0.3, 0.49})
      for (int n : {16, 32, 64}) {
        INFO("delta/h " << d << " nu " << nu << " N " << n);
        const auto a = study::run("patch_dirichlet.yaml", n, {d, nu, 0.0});
        const auto b = study::run("patch_dirichlet.yaml", n, {d, nu, 0.2});
        const auto c = study::run("patch_top_traction.yaml", n, {d, nu, 0.0});
        CHECK(a.errors.u_relative < 1e-12);
        CHECK(b.errors.u_relative < 1e-12);
        CHECK(c.errors.u_relative < 1e-12);
        CHECK(c.errors.theta_relative < 1e-12);
      }
}

TEST_CASE("Sec. 5.1: with a traction edge meeting a corner the patch test converges at first order on uniform grids (setting 3)") {
  for (double d : {3.5, 3.9})
    for (double nu : {0.3, 0.49}) {
      const Variant uni{d, nu, 0.0};
      const auto corner = study::refine("patch_corner.yaml", {16, 32, 64, 128}, uni, tag("patch_corner.yaml", uni));
      CHECK(study::order(corner, false) >= 0.9);
    }
}

// The paper reports O(h) for u with a traction edge on perturbed grids (setting 2) and orders
// 0.75 (u) and 0.5 (theta) with the corner (setting 3). Measured here, RMS over 4 clouds per
// level, N = 16..128: setting 2 u 0.63-0.77; setting 3 u 0.71-0.93, theta 0.62-0.70. Setting 2
// is not reproduced; this case states the paper's claim unchanged and fails on it.
TEST_CASE("Sec. 5.1: on perturbed grids the patch test with traction edges converges at the paper's orders (settings 2 and 3)") {
  for (double d : {3.5, 3.9})
    for (double nu : {0.3, 0.49}) {
      const Variant per{d, nu, 0.2, NAN, 4};  // perturbed: RMS over 4 random clouds per level
      INFO("delta/h " << d << " nu " << nu);
      const auto top = study::refine("patch_top_traction.yaml", {16, 32, 64, 128}, per, tag("patch_top_traction.yaml", per));
      CHECK(study::order(top, false) >= 0.9);
      const auto cper = study::refine("patch_corner.yaml", {16, 32, 64, 128}, per, tag("patch_corner.yaml", per));
      CHECK(study::order(cper, false) >= 0.75);
      CHECK(study::order(cper, true) >= 0.5);
    }
}

TEST_CASE("Sec. 5.2: the manufactured solution converges at second order with Dirichlet data and first order with tractions") {
  for (double d : {3.5, 3.9})
    for (double nu : {0.3, 0.49})
      for (double pert : {0.0, 0.2}) {
        const Variant v{d, nu, pert, NAN, 4};
        INFO("delta/h " << d << " nu " << nu << " perturbation " << pert);
        const auto dir = study::refine("sine_dirichlet.yaml", {16, 32, 64, 128}, v, tag("sine_dirichlet.yaml", v));
        CHECK(study::order(dir, false) >= 1.8);
        CHECK(study::order(dir, true) >= 1.8);
        for (const char* deck : {"sine_top_traction.yaml", "sine_corner.yaml"}) {
          const auto l = study::refine(deck, {16, 32, 64, 128}, v, tag(deck, v));
          CHECK(study::order(l, false) >= 0.9);
          CHECK(study::order(l, true) >= 0.9);
        }
      }
}

TEST_CASE("Sec. 5.3: displacements converge at order 0.8 or better around a free hole and in a pressurised hollow disk") {
  for (const char* deck : {"kirsch_hole.yaml", "hollow_disk.yaml"})
    for (double nu : {0.3, 0.49})
      for (double pert : {0.0, 0.2}) {
        const Variant v{3.5, nu, pert, NAN, 4};
        const auto l = study::refine(deck, {16, 32, 64, 128}, v, tag(deck, v));
        WARN(deck << " nu " << nu << " perturbation " << pert << ": order u " << study::order(l, false) << ", theta "
                  << study::order(l, true));
        CHECK(study::order(l, false) >= 0.8);
      }
}

TEST_CASE("Sec. 5.4: displacements converge at order 0.8 or better across a composite inclusion") {
  // (nu1, nu2) = (0.25, 0.25), (0.49, 0.49), (0.49, 0.25): inclusion, matrix.
  for (auto [nu1, nu2] : {std::pair{0.25, 0.25}, std::pair{0.49, 0.49}, std::pair{0.49, 0.25}})
    for (double pert : {0.0, 0.2}) {
      const Variant v{3.5, nu2, pert, nu1, 4};
      const auto l = study::refine("inclusion.yaml", {16, 32, 64, 128}, v, tag("inclusion.yaml", v) + "_nu1_" + std::to_string(nu1));
      WARN("inclusion nu1 " << nu1 << " nu2 " << nu2 << " perturbation " << pert << ": order u " << study::order(l, false)
                            << ", theta " << study::order(l, true));
      CHECK(study::order(l, false) >= 0.8);
    }
}
