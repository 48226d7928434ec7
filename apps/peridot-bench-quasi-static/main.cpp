// peridot-bench-quasi-static: one Newton iteration of the RNP quasi-static solver on an
// N x N plate (left edge clamped, a body force on the right strip): the model's tangent, the
// value refill of the sparse pattern, the bare factorisation and solve, the residual, and
// the whole Newton step; peak resident memory. Seed 002's performance targets.
#include <sys/resource.h>

#include <CLI/CLI.hpp>
#include <Eigen/Core>
#include <chrono>
#include <cstdio>
#include <string>
#include <vector>
#include <fmt/core.h>
import peridot.implicit;

using namespace peridot;

namespace {

double peak_rss_mib() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_maxrss) / 1024.0;
}

template <class F>
double seconds(F&& f) {
  const auto t0 = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

int main(int argc, char** argv) {
  int n = 316;  // 316^2 = 99,856 nodes
  double m = 3;
  std::string solver = "auto";
  CLI::App app{"peridot-bench-quasi-static: one RNP Newton iteration on an N x N plate"};
  app.add_option("--nodes-per-side", n, "N (N^2 nodes)")->check(CLI::Range(8, 4000));
  app.add_option("--m", m, "delta / h")->check(CLI::Range(1.0, 12.0));
  app.add_option("--linear-solver", solver, "auto | umfpack | cg")->check(CLI::IsMember({"auto", "umfpack", "cg"}));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  const double h = 1.0 / n, delta = m * h;
  Body body;
  double t_setup = seconds([&] {
    body.points = lattice(rectangle({0, 0, 0}, {1, 1, 0}), {.spacing = h});
    body.bonds = build_bonds(body.points, {.horizon = delta});
    body.density = 1;
  });
  const auto model = Rnp::make(2, 30000, 1, delta);
  std::vector<Boundary> bcs{
      {"clamp", BoundaryKind::displacement, select_points(body.points, rectangle({-1, -1, 0}, {h, 2, 0})), {0, 0, 0}, {true, true, false}, {}},
      {"load", BoundaryKind::body_force, select_points(body.points, rectangle({1 - delta, -1, 0}, {2, 2, 0})), {1e3, 0, 0}, {true, true, false}, {}}};
  QuasiStaticOptions o;
  o.steps = 1;
  o.max_iterations = 1;
  o.tolerance = 1e-300;  // exactly one iteration: time it, never converge
  o.min_increment = 1;   // and no step cutting after it
  o.linear_solver = solver == "umfpack" ? QsLinearSolver::umfpack : solver == "cg" ? QsLinearSolver::cg : QsLinearSolver::automatic;
  std::unique_ptr<QuasiStaticSolver<Rnp>> qs;
  t_setup += seconds([&] { qs = std::make_unique<QuasiStaticSolver<Rnp>>(body, model, bcs, o); });
  fmt::print("peridot-bench-quasi-static: {} nodes, {} directed bonds ({:.1f} per node), delta = {:g} h, {} unknowns, set-up {:.2f} s\n",
             body.size(), body.bonds.size(), double(body.bonds.size()) / double(body.size()), m, qs->system().unknowns(), t_setup);
  // The pieces of one Newton iteration, timed one by one at u = 0.
  VectorField u = zero_field(body.size()), f = zero_field(body.size());
  TangentBlocks K;
  NewtonSystem sys(body, [&] {
    std::vector<std::uint8_t> fixed(body.size() * 2, 0);
    for (auto i : bcs[0].points) fixed[2 * std::size_t(i)] = fixed[2 * std::size_t(i) + 1] = 1;
    return fixed;
  }());
  const double t_tangent = seconds([&] { model.tangent(body, u, K); });
  const double t_fill = seconds([&] { sys.assemble(K); });
  Eigen::VectorXd rhs = Eigen::VectorXd::Ones(long(sys.unknowns()));
  std::string used;
  double t_first = seconds([&] { (void)sys.solve(rhs, o.linear_solver, used); });  // symbolic analysis + factorisation
  double t_factor = seconds([&] { (void)sys.solve(rhs, o.linear_solver, used); });  // what every later iteration pays
  const double t_force = seconds([&] { model.forces(body, u, f); });
  fmt::print("  tangent blocks {:.3f} s, value refill {:.3f} s: assembly {:.3f} s\n", t_tangent, t_fill, t_tangent + t_fill);
  fmt::print("  {}: first solve (analysis + factorisation) {:.3f} s, later factorisation + solve {:.3f} s; residual {:.3f} s\n", used, t_first,
             t_factor, t_force);
  fmt::print("  assembly / factorisation = {:.3f}\n", (t_tangent + t_fill) / t_factor);
  // The whole first Newton iteration through the solver (it stops after one by design).
  double t_step = seconds([&] {
    try {
      qs->run(u);
    } catch (const std::exception&) {
    }
  });
  // Again: the solver keeps its symbolic analysis, as every later Newton iteration does.
  u = zero_field(body.size());
  const double t_again = seconds([&] {
    try {
      qs->run(u);
    } catch (const std::exception&) {
    }
  });
  fmt::print("  whole Newton iteration in the solver (tangent, refill, factorisation, solve, line search, residuals): first {:.3f} s, "
             "later {:.3f} s = {:.3f} x the bare factorisation\n",
             t_step, t_again, t_again / t_factor);
  fmt::print("  peak resident memory {:.0f} MiB\n", peak_rss_mib());
  return 0;
}
