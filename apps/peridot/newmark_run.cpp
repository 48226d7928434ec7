// peridot run on an implicit Newmark deck (dynamic LPS fracture, seed 000 Sec. 6): one
// matrix-free solve per step plus a re-solve per round of new breaks, with the same observers
// as an explicit run and the solver's work in the CSV history.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>
#include <fmt/core.h>

#include "commands.hpp"
#include "newmark_run.hpp"
#include "observers.hpp"
#include "progress.hpp"
import peridot.problem;

using namespace peridot;

void print_lps_setup(const Problem& p, const Body& body, const Lps& model) {
  fmt::print("peridot: {} (2D, {}, dynamic LPS)\n", p.name, to_string(p.material.kinematics));
  fmt::print("  points {}  bonds {} (directed {})  h = {:.4g} m  delta = {:.4g} m  weights: {}\n", body.size(), body.bonds.size() / 2,
             body.bonds.size(), p.lattice.spacing, p.horizon, p.quadrature_kind == QuadratureKind::gmls ? "GMLS" : "nodal volumes");
  fmt::print("  LPS: lambda = {:.6g} Pa, mu = {:.6g} Pa{}; {} traction load(s)\n", model.lambda.empty() ? 0.0 : model.lambda[0],
             model.mu.empty() ? 0.0 : model.mu[0], model.s0 > 0 ? fmt::format(", bonds break at s0 = {:.4e}", model.s0) : ", no fracture",
             model.tractions.size());
}

int simulate_newmark(const Problem& p, NewmarkSetup& s, const RunArgs& args) {
  const auto dir = std::filesystem::path(args.out_dir ? *args.out_dir : p.output.directory.string());
  NewmarkSolver<Lps> solver(s.body, s.model, s.boundaries, s.options);
  if (!args.quiet) {
    print_lps_setup(p, s.body, s.model);
    fmt::print("  implicit Newmark (beta = 1/4, gamma = 1/2): dt = {:.4e} s for {} steps to t = {:.4e} s; BiCGSTAB tolerance {:g}\n",
               s.options.dt, solver.steps(), s.options.end_time, s.options.tolerance);
  }
  State state(s.body.size());
  solver.initialize(state);
  Observers observers(p, s.body, dir, live_options(args, p.name));
  Progress progress(solver.steps(), !args.quiet);
  const auto t0 = std::chrono::steady_clock::now();
  const auto wall = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
  const auto strain = [&] { return solver.model().strain_energy(s.body, state.u); };
  long iterations = 0, sub_iterations = 0;
  int max_iterations = 0;
  try {
    observers.observe(state, 0.0, solver.broken_bonds(), strain, false, 0.0);
    for (std::size_t k = 0; k < solver.steps(); ++k) {
      solver.step(state);
      const auto& r = solver.last();
      iterations += r.iterations;
      sub_iterations += r.sub_iterations;
      max_iterations = std::max(max_iterations, r.iterations);
      observers.add_solver_work(r.iterations, r.sub_iterations);
      observers.observe(state, 0.0, solver.broken_bonds(), strain, k + 1 == solver.steps(), wall());
      progress.update(state.step, state.time, solver.broken_bonds());
    }
  } catch (const std::exception& e) {
    progress.finish();
    observers.finish(false, e.what());
    throw;
  }
  progress.finish();
  observers.finish(true, "");
  if (!args.quiet) {
    const double steps = double(std::max<std::size_t>(state.step, 1));
    observers.print_done(state, wall(), solver.broken_bonds(),
                         fmt::format("  BiCGSTAB: {:.2f} iterations per step (most {}), {} re-solves after breaks", double(iterations) / steps,
                                     max_iterations, sub_iterations));
  }
  return exit_ok;
}
