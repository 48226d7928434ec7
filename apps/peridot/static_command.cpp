#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>
#include <fmt/core.h>

#include "commands.hpp"
#include "guarded.hpp"
#include "static_run.hpp"
import peridot.io;

using namespace peridot;

double fitted_order(const std::vector<double>& h, const std::vector<double>& e) {
  double mh = 0, me = 0;
  for (std::size_t k = 0; k < h.size(); ++k) mh += std::log(h[k]) / h.size(), me += std::log(e[k]) / h.size();
  double num = 0, den = 0;
  for (std::size_t k = 0; k < h.size(); ++k) {
    num += (std::log(h[k]) - mh) * (std::log(e[k]) - me);
    den += (std::log(h[k]) - mh) * (std::log(h[k]) - mh);
  }
  return num / den;
}

StaticRun run_static_once(const Problem& p) {
  const auto t0 = std::chrono::steady_clock::now();
  StaticRun run{setup_static(p), {}, {}, 0};
  run.setup_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  run.result = solve_static_lps(run.setup.body, run.setup.model, run.setup.problem, run.setup.options);
  run.errors = static_errors(run.setup, run.result);
  return run;
}

void write_static_vtu(const std::filesystem::path& dir, const Problem& p, const StaticRun& run) {
  const auto& pc = run.setup.body.points;
  std::vector<double> ux(pc.size()), uy(pc.size()), theta0(pc.size()), role(pc.size());
  for (std::size_t i = 0; i < pc.size(); ++i) {
    const auto u0 = run.setup.reference.displacement(pc.position(i));
    ux[i] = u0[0];
    uy[i] = u0[1];
    theta0[i] = pc.role[i] == Role::ghost ? 0.0 : run.setup.reference.dilatation(pc.position(i));
    role[i] = double(static_cast<int>(pc.role[i]));
  }
  const NamedField fields[] = {
      {"displacement", 3, {run.result.u[0], run.result.u[1], {}}},
      {"dilatation", 1, {run.result.theta, {}, {}}},
      {"reference_displacement", 3, {ux, uy, {}}},
      {"reference_dilatation", 1, {theta0, {}, {}}},
      {"role", 1, {role, {}, {}}},
  };
  write_vtu(dir / (p.name + ".vtu"), pc, fields);
}

void print_static(const StaticRun& r) {
  fmt::print("  {}\n", summary(r.setup.quadrature));
  fmt::print("  unknowns {}  nonzeros {}  setup {:.3f} s (weights {:.3f} s)  assembly {:.3f} s  solve {:.3f} s  residual {:.2e}\n",
             r.result.unknowns, r.result.nonzeros, r.setup_seconds, r.setup.quadrature.seconds, r.result.assembly_seconds,
             r.result.solve_seconds, r.result.residual);
  fmt::print("  L2 error vs {}: u {:.6e} (relative {:.3e}), theta {:.6e} (relative {:.3e})\n", r.setup.reference.name, r.errors.u,
             r.errors.u_relative, r.errors.theta, r.errors.theta_relative);
}

int converge_command(const ConvergeArgs& args) {
  Problem base;
  const int input = guarded([&] {
    base = read_deck(args.deck);
    if (base.solver_kind != SolverKind::static_linear) throw DeckError(args.deck + ": converge needs a static deck (solver.type: static)");
    if (args.cells.size() < 2) throw DeckError("--cells: give at least two resolutions");
    return int(exit_ok);
  });
  if (input != exit_ok) return exit_input_error;
  const double factor = base.horizon / base.lattice.spacing;
  const auto box = base.body.bounds();
  const double width = box.hi[0] - box.lo[0];
  const auto dir = std::filesystem::path(args.out_dir ? *args.out_dir : base.output.directory.string());
  return guarded([&] {
    std::filesystem::create_directories(dir);
    const auto csv_path = dir / (base.name + "_convergence.csv");
    std::ofstream csv(csv_path);
    csv << "cells,h,delta,points,unknowns,error_u,error_theta,order_u,order_theta,weights_s,assembly_s,solve_s\n";
    fmt::print("{}: delta = {:g} h, reference {}\n", base.name, factor, base.statics.reference.type);
    fmt::print("  {:>6} {:>12} {:>14} {:>14} {:>8} {:>8} {:>9} {:>9} {:>9}\n", "cells", "h", "error u", "error theta", "order u",
               "order th", "weights", "assembly", "solve");
    double prev_u = 0, prev_t = 0, prev_h = 0;
    std::vector<double> hs, eus, ets;
    for (int n : args.cells) {
      Problem p = base;
      p.lattice.spacing = width / n;
      p.horizon = factor * p.lattice.spacing;
      const auto r = run_static_once(p);
      const double ou = prev_h > 0 ? std::log(prev_u / r.errors.u) / std::log(prev_h / p.lattice.spacing) : NAN;
      const double ot = prev_h > 0 ? std::log(prev_t / r.errors.theta) / std::log(prev_h / p.lattice.spacing) : NAN;
      fmt::print("  {:>6} {:>12.5e} {:>14.6e} {:>14.6e} {:>8.3f} {:>8.3f} {:>8.3f}s {:>8.3f}s {:>8.3f}s\n", n, p.lattice.spacing, r.errors.u,
                 r.errors.theta, ou, ot, r.setup.quadrature.seconds, r.result.assembly_seconds, r.result.solve_seconds);
      std::fflush(stdout);
      csv << fmt::format("{},{:.9e},{:.9e},{},{},{:.9e},{:.9e},{:.6f},{:.6f},{:.4f},{:.4f},{:.4f}\n", n, p.lattice.spacing, p.horizon,
                         r.setup.body.size(), r.result.unknowns, r.errors.u, r.errors.theta, ou, ot, r.setup.quadrature.seconds,
                         r.result.assembly_seconds, r.result.solve_seconds);
      prev_u = r.errors.u, prev_t = r.errors.theta, prev_h = p.lattice.spacing;
      hs.push_back(p.lattice.spacing), eus.push_back(r.errors.u), ets.push_back(r.errors.theta);
    }
    fmt::print("  least-squares order over all levels: u {:.3f}, theta {:.3f}\n", fitted_order(hs, eus), fitted_order(hs, ets));
    fmt::print("  output: {}\n", csv_path.string());
    return int(exit_ok);
  });
}
