// peridot run on a quasi-static deck: load control with Newton (or Ceres), observers at each
// converged load step and a per-step CSV of the nonlinear solve.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>
#include <fmt/core.h>

#include "commands.hpp"
#include "observers.hpp"
#include "quasi_static_run.hpp"
import peridot.problem;

using namespace peridot;

namespace {

// Whole rows only: a row that a full disk cuts short is removed and the run fails naming the file.
struct LoadStepCsv {
  RecordFile f;
  explicit LoadStepCsv(const std::filesystem::path& file) : f(file) {
    f.append("step,load_factor,iterations,residual_0,residual,reference_force,max_damage,softening_bonds,cuts,linear_solver,seconds,"
             "condition_number\n");
  }
  void row(const LoadStepReport& r) {
    f.append(fmt::format("{},{:.9e},{},{:.6e},{:.6e},{:.6e},{:.9e},{},{},{},{:.4f},{:.6e}\n", r.step, r.load, r.iterations, r.residual0,
                         r.residual, r.reference, r.max_damage, r.softening_bonds, r.cuts, r.linear_solver, r.seconds, r.condition));
  }
};

}  // namespace

int simulate_quasi_static(const Problem& p, QuasiStaticSetup& s, const RunArgs& args) {
  const auto dir = std::filesystem::path(args.out_dir ? *args.out_dir : p.output.directory.string());
  const auto& m = s.model;
  if (!args.quiet) {
    fmt::print("peridot: {} ({}D quasi-static RNP, {})\n", p.name, p.dim, s.solver.options.nonlinear == QsNonlinear::ceres ? "Ceres" : "Newton");
    fmt::print("  points {}  bonds {} (directed {})  h = {:.4g} m  delta = {:.4g} m\n", s.body.size(), s.body.bonds.size() / 2,
               s.body.bonds.size(), p.lattice.spacing, p.horizon);
    fmt::print("  RNP: C = {:.6g}, beta = {:.6g}, r_c = {:.6g}, small-strain micromodulus {:.6g}; {} load steps\n", m.C, m.beta, m.critical_r(),
               m.micromodulus(), s.solver.options.steps);
  }
  QuasiStaticSolver solver(s.body, m, s.boundaries, s.solver.options);
  State state(s.body.size());
  Observers observers(p, s.body, dir, live_options(args, p.name),
                      [&](const VectorField& u, std::vector<double>& d) { m.damage(s.body, u, d); },
                      [&](const VectorField& u, StressField& tau) { tau = stress_field(m, s.body, u); });
  LoadStepCsv csv(dir / (p.name + "_load_steps.csv"));
  const auto t0 = std::chrono::steady_clock::now();
  const auto wall = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
  const auto strain = [&] { return m.strain_energy(s.body, state.u); };
  std::vector<LoadStepReport> reports;
  try {
    observers.observe(state, 0.0, 0, strain, false, 0.0);
    const auto on_step = [&](const LoadStepReport& r, const VectorField& u) {
      state.u = u;
      state.step = r.step;
      state.time = r.load;  // the record's "time" of a quasi-static run is the load factor
      csv.row(r);
      observers.observe(state, 0.0, r.softening_bonds, strain, r.load >= 1 - 1e-12, wall());
      if (!args.quiet)
        fmt::print("  step {:>4}  load {:.6f}  iterations {:>2} ({})  |R| {:.2e} -> {:.2e}  max damage {:.4f}  softening bonds {}{}\n", r.step,
                   r.load, r.iterations, r.linear_solver, r.residual0, r.residual, r.max_damage, r.softening_bonds,
                   r.cuts ? fmt::format("  ({} cuts)", r.cuts) : "");
      std::fflush(stdout);
    };
    reports = solver.run(state.u, on_step);
  } catch (const std::exception& e) {
    observers.finish(false, e.what());
    throw;
  }
  observers.finish(true, "");
  if (!args.quiet) {
    int iterations = 0;
    for (const auto& r : reports) iterations += r.iterations;
    fmt::print("  done: {} load steps, {} nonlinear iterations in {:.3f} s\n", reports.size(), iterations, wall());
    for (const auto& o : observers.outputs()) fmt::print("  output: {}\n", o);
    fmt::print("  output: {}\n", (dir / (p.name + "_load_steps.csv")).string());
  }
  return exit_ok;
}
