#include <catch2/catch.hpp>
#include <algorithm>
#include <cmath>
#include <string>

#include "../support/static_study.hpp"
import peridot.problem;

using namespace peridot;

namespace {

// Errors of a static deck at N cells per side of [-pi/2, pi/2]^2.
StaticErrors run(const std::string& deck, int cells, double horizon_factor = 3.5, double poisson = 0.3, double perturbation = 0.0) {
  return study::run(deck, cells, {horizon_factor, poisson, perturbation}).errors;
}

}  // namespace

// Exactness tolerance: measured relative errors are 3e-16 to 4e-16 at N = 16 (double round-off
// through a system of condition ~1e3); 1e-13 leaves a margin for perturbed grids and nu = 0.49.
TEST_CASE("the linear patch test with Dirichlet data is exact to 1e-13 on uniform and perturbed grids") {
  for (double factor : {3.5, 3.9})
    for (double nu : {0.3, 0.49}) {
      INFO("delta/h = " << factor << ", nu = " << nu);
      const auto e = run("patch_dirichlet.yaml", 16, factor, nu);
      CHECK(e.u_relative < 1e-13);
      CHECK(e.theta_relative < 1e-13);
    }
  const auto p = run("patch_dirichlet.yaml", 16, 3.5, 0.3, 0.2);
  CHECK(p.u_relative < 1e-13);
  CHECK(p.theta_relative < 1e-13);
}

TEST_CASE("the linear patch test with a traction edge is exact to 1e-13 on uniform grids") {
  for (double factor : {3.5, 3.9})
    for (double nu : {0.3, 0.49}) {
      INFO("delta/h = " << factor << ", nu = " << nu);
      const auto e = run("patch_top_traction.yaml", 16, factor, nu);
      CHECK(e.u_relative < 1e-13);
      CHECK(e.theta_relative < 1e-13);
    }
}

TEST_CASE("with a traction edge meeting a corner the patch test converges at first order (setting 3)", "[slow]") {
  const auto l = study::refine("patch_corner.yaml", {16, 32, 64}, {}, "patch_corner_reduced");
  CHECK(study::order(l, false) >= 0.9);
  CHECK(study::order(l, true) >= 0.6);
}

TEST_CASE("the manufactured solution with Dirichlet data converges at second order on uniform and perturbed grids", "[slow]") {
  for (double pert : {0.0, 0.2}) {
    INFO("perturbation " << pert);
    const auto l = study::refine("sine_dirichlet.yaml", {16, 32, 64}, {.perturbation = pert}, pert > 0 ? "sine_dirichlet_perturbed_reduced" : "sine_dirichlet_reduced");
    CHECK(study::order(l, false) >= 1.8);
    CHECK(study::order(l, true) >= 1.8);
  }
}

TEST_CASE("the manufactured solution with traction edges converges at first order (settings 2 and 3)", "[slow]") {
  for (const char* deck : {"sine_top_traction.yaml", "sine_corner.yaml"}) {
    INFO(deck);
    const auto l = study::refine(deck, {16, 32, 64}, {}, std::string(deck).substr(0, std::string(deck).find(".")) + "_reduced");
    CHECK(study::order(l, false) >= 0.9);
    CHECK(study::order(l, true) >= 0.9);
  }
}

// [paper]: about 20 s on 2 cores, most of it the N = 128 level; the default suite stops at N = 64
// below.
TEST_CASE("displacements converge at order 0.8 or better around a free hole, a pressurised hole and an inclusion", "[paper]") {
  for (const char* deck : {"kirsch_hole.yaml", "hollow_disk.yaml", "inclusion.yaml"}) {
    const auto l = study::refine(deck, {16, 32, 64, 128}, {}, std::string(deck).substr(0, std::string(deck).find('.')) + "_reduced");
    INFO(deck << ": order u " << study::order(l, false) << ", order theta " << study::order(l, true));
    CHECK(study::order(l, false) >= 0.8);
    // Seed 000 Secs. 5.3-5.4 report theta orders of about 1/2 (inclusion) to 0.7 (Kirsch, hollow
    // disk); measured here over N = 16-128: 0.55, 0.47, 0.50.
    CHECK(study::order(l, true) >= 0.4);
  }
}

TEST_CASE("over N = 24 to 96 displacements converge at order 0.8 or better around a free hole, a pressurised hole and an inclusion", "[slow]") {
  // Three levels, the finest 96 instead of 128 (about half the work), the paper case's
  // thresholds. Over N = 16 to 64 the orders are still pre-asymptotic (Kirsch u 0.77, hollow
  // disk theta 0.35); measured over 24 to 96: u 1.08, 1.00, 1.43 and theta 0.83, 0.59, 0.52
  // (Kirsch, hollow disk, inclusion).
  for (const char* deck : {"kirsch_hole.yaml", "hollow_disk.yaml", "inclusion.yaml"}) {
    const auto l = study::refine(deck, {24, 48, 96}, {}, std::string(deck).substr(0, std::string(deck).find('.')) + "_coarse");
    INFO(deck << ": order u " << study::order(l, false) << ", order theta " << study::order(l, true));
    CHECK(study::order(l, false) >= 0.8);
    CHECK(study::order(l, true) >= 0.4);
  }
}

namespace {

struct Profile {
  double max_error = 0, scale = 0;
  int extrema_numeric = 0, extrema_exact = 0;  // interior local extrema along the row
};

int local_extrema(const std::vector<double>& v) {
  int n = 0;
  for (std::size_t k = 1; k + 1 < v.size(); ++k) n += (v[k] - v[k - 1]) * (v[k + 1] - v[k]) < 0;
  return n;
}

// u_x along the lattice row nearest y = 0 for a matrix modulus E2 = Q E1.
Profile inclusion_profile(double Q) {
  Problem p = read_deck(study::deck_path("inclusion_robustness.yaml"));
  p.material.youngs_modulus = Q * p.inclusions[0].youngs_modulus;
  const auto s = setup_static(p);
  const auto r = solve_static_lps(s.body, s.model, s.problem, s.options);
  const auto& pc = s.body.points;
  std::vector<std::pair<double, std::size_t>> row;
  for (std::size_t i = 0; i < pc.size(); ++i)
    if (pc.role[i] == Role::interior && std::abs(pc.x[1][i] - 0.5 * p.lattice.spacing) < 1e-9) row.emplace_back(pc.x[0][i], i);
  std::sort(row.begin(), row.end());
  Profile out;
  std::vector<double> un, ue;
  for (const auto& [x, i] : row) {
    un.push_back(r.u[0][i]);
    ue.push_back(s.reference.displacement(pc.position(i))[0]);
    out.max_error = std::max(out.max_error, std::abs(un.back() - ue.back()));
    out.scale = std::max(out.scale, std::abs(ue.back()));
  }
  out.extrema_numeric = local_extrema(un);
  out.extrema_exact = local_extrema(ue);
  return out;
}

}  // namespace

// No oscillation: along y = 0 the numerical u_x has no local extremum that the exact profile
// lacks (a wiggle adds a pair), and it stays within 5% of the profile's maximum.
TEST_CASE("a stiff or soft inclusion (E2/E1 from 2^-8 to 2^8) gives no oscillation across the interface", "[slow]") {
  for (int e : {-8, -4, 0, 4, 8}) {
    const auto pr = inclusion_profile(std::ldexp(1.0, e));
    INFO("E2/E1 = 2^" << e << ": max error " << pr.max_error << " of " << pr.scale << ", extrema " << pr.extrema_numeric << " vs "
                       << pr.extrema_exact);
    CHECK(pr.extrema_numeric <= pr.extrema_exact);
    CHECK(pr.max_error <= 0.05 * pr.scale);
  }
}

TEST_CASE("Eigen's SparseLU and BiCGSTAB with ILUT give UMFPACK's solution of the static LPS system", "[slow]") {
  // Traction edges make the system non-symmetric; the three solvers share nothing but the matrix.
  Problem p = read_deck(study::deck_path("sine_top_traction.yaml"));
  const auto s = setup_static(p);
  StaticOptions o = s.options;
  o.solver = LinearSolver::umfpack;
  const auto ref = solve_static_lps(s.body, s.model, s.problem, o);
  double scale = 0;
  for (double v : ref.u[0]) scale = std::max(scale, std::abs(v));
  REQUIRE(scale > 0);
  for (auto solver : {LinearSolver::sparse_lu, LinearSolver::bicgstab_ilut}) {
    o.solver = solver;
    o.tolerance = 1e-12;
    const auto r = solve_static_lps(s.body, s.model, s.problem, o);
    double diff = 0;
    for (int c = 0; c < 2; ++c)
      for (std::size_t i = 0; i < r.u[c].size(); ++i) diff = std::max(diff, std::abs(r.u[c][i] - ref.u[c][i]));
    INFO("solver " << int(solver) << ": max |u - u_umfpack| = " << diff << " of " << scale << ", residual " << r.residual);
    CHECK(diff < (solver == LinearSolver::sparse_lu ? 1e-12 : 1e-8) * scale);
    CHECK(r.residual < (solver == LinearSolver::sparse_lu ? 1e-12 : 1e-10));
  }
}

TEST_CASE("PETSc's MUMPS and GMRES with BoomerAMG give UMFPACK's static LPS solution") {
  // pi/64 spacing: 12,288 unknowns, enough levels for the AMG. The PETSc paths number the
  // unknowns per point and share only the assembled matrix with UMFPACK.
  Problem p = read_deck(study::deck_path("sine_top_traction.yaml"));
  p.lattice.spacing /= 4;
  p.horizon /= 4;
  const auto s = setup_static(p);
  StaticOptions o = s.options;
  o.solver = LinearSolver::umfpack;
  const auto ref = solve_static_lps(s.body, s.model, s.problem, o);
  double scale_u = 0, scale_t = 0;
  for (int c = 0; c < 2; ++c)
    for (double v : ref.u[c]) scale_u = std::max(scale_u, std::abs(v));
  for (double v : ref.theta) scale_t = std::max(scale_t, std::abs(v));
  REQUIRE(ref.unknowns == 12288);
  REQUIRE(scale_u > 0);
  REQUIRE(scale_t > 0);
  for (const bool iterative : {false, true}) {
    o.solver = LinearSolver::petsc;
    o.petsc.direct_below = iterative ? 0 : 1 << 30;
    const auto r = solve_static_lps(s.body, s.model, s.problem, o);
    double du = 0, dt = 0;
    for (int c = 0; c < 2; ++c)
      for (std::size_t i = 0; i < r.u[c].size(); ++i) du = std::max(du, std::abs(r.u[c][i] - ref.u[c][i]));
    for (std::size_t i = 0; i < r.theta.size(); ++i) dt = std::max(dt, std::abs(r.theta[i] - ref.theta[i]));
    INFO(r.petsc.ksp << "/" << r.petsc.pc << " " << r.petsc.factor_package << ": " << r.iterations << " iterations, max |u - u_umfpack| = " << du
                     << " of " << scale_u << ", max |theta - theta_umfpack| = " << dt << " of " << scale_t << ", residual " << r.residual);
    CHECK(r.petsc.ksp == (iterative ? "gmres" : "preonly"));
    CHECK(r.petsc.pc == (iterative ? "hypre" : "lu"));
    CHECK(du < 1e-8 * scale_u);
    CHECK(dt < 1e-8 * scale_t);
    CHECK(r.residual < 1e-11);
    if (iterative) CHECK(r.iterations > 1);
  }
}

TEST_CASE("options a deck gives PETSc choose the solver, and bad ones are refused") {
  Problem p = read_deck(study::deck_path("sine_dirichlet.yaml"));
  const auto s = setup_static(p);
  StaticOptions o = s.options;
  o.petsc.options = "-ksp_type bcgs -pc_type jacobi -ksp_max_it 5000";
  const auto r = solve_static_lps(s.body, s.model, s.problem, o);
  CHECK(r.petsc.ksp == "bcgs");
  CHECK(r.petsc.pc == "jacobi");
  CHECK(r.iterations > 1);
  CHECK(r.residual < 1e-11);
  o.petsc.options = "-pc_type no_such_preconditioner";
  CHECK_THROWS_AS(parallel::check_ksp_options(o.petsc), std::invalid_argument);
  CHECK_THROWS_AS(solve_static_lps(s.body, s.model, s.problem, o), std::invalid_argument);
  o.petsc.options = "-ksp_type gmres -pc_type none -ksp_max_it 3";
  CHECK_THROWS_WITH(solve_static_lps(s.body, s.model, s.problem, o), Catch::Contains("did not converge"));
}

