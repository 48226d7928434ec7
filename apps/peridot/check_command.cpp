#include <cstdio>
#include <stdexcept>
#include <string>
#include <variant>
#include <fmt/core.h>

#include "commands.hpp"
import peridot.io;

int check_command(const std::string& deck) {
  using namespace peridot;
  try {
    const Problem p = read_deck(deck);
    if (p.solver_kind == SolverKind::static_linear) {
      const StaticSetup s = setup_static(p);
      fmt::print("{}: ok: {} (static LPS), {} points, {}\n", deck, p.name, s.body.size(), summary(s.quadrature));
      return exit_ok;
    }
    const Setup s = setup(p);
    fmt::print("{}: ok: {} ({}D), {} points, {} bonds, dt = {:.4e} s (stable estimate {:.4e} s), {} steps\n", deck, p.name, p.dim,
               s.body.size(), s.body.bonds.size() / 2, s.time_step.dt, s.time_step.estimate, s.time_step.steps);
    if (s.time_step.above_estimate()) fmt::print(stderr, "warning: solver.dt exceeds the stable estimate\n");
    return exit_ok;
  } catch (const std::exception& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return exit_input_error;
  }
}
