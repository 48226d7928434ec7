#include <cstdio>
#include <stdexcept>
#include <string>
#include <algorithm>
#include <type_traits>
#include <variant>
#include <fmt/core.h>

#include "commands.hpp"
import peridot.problem;

int check_command(const std::string& deck) {
  using namespace peridot;
  try {
    const Problem p = read_deck(deck);
    const auto composed = compose(p);
    if (const auto* st = std::get_if<StaticSetup>(&composed)) check_petsc_options(*st);
    fmt::print("{}: ok: {} ({}D): {}\n", deck, p.name, p.dim, combination_of(p).what);
    std::visit(
        [&](const auto& s) {
          const double bytes = double(s.body.bond_bytes()), mib = 1024.0 * 1024.0;
          const std::size_t directed = s.body.directed_bonds();
          const char* layout = s.body.on_stencil() ? "lattice stencil: a state byte per point and offset"
                               : s.body.bonds.lean() ? "lean list: partner, float weight, mask"
                                                     : "list: partner, xi, |xi|, weight, mask";
          fmt::print("  {} points, {} directed bonds ({:.1f} per point), {:.1f} bytes per bond ({}), {:.1f} MiB of bonds\n", s.body.size(),
                     directed, double(directed) / double(std::max<std::size_t>(s.body.size(), 1)),
                     directed ? bytes / double(directed) : 0.0, layout, bytes / mib);
          fmt::print("  about {:.0f} bytes per point for positions, volumes and fields ({:.1f} MiB); run estimate {:.1f} MiB\n",
                     bytes_per_point, bytes_per_point * double(s.body.size()) / mib, (bytes + bytes_per_point * double(s.body.size())) / mib);
          if constexpr (std::is_same_v<std::decay_t<decltype(s)>, StaticSetup>) {
            fmt::print("  {}\n", summary(s.quadrature));
            if (s.options.solver == LinearSolver::petsc)
              fmt::print("  linear solve on PETSc: {}{}\n", s.body.size() * 3 < std::size_t(s.options.petsc.direct_below) ? "LU (MUMPS)" : "GMRES + BoomerAMG",
                         s.options.petsc.options.empty() ? "" : ", then solver.petsc_options '" + s.options.petsc.options + "'");
          } else if constexpr (std::is_same_v<std::decay_t<decltype(s)>, OsbStaticSetup>) {
            fmt::print("  OSB: {} fictitious layers; {} real unknowns (u, v, theta)\n", s.layers,
                       3 * std::size_t(std::count(s.body.points.role.begin(), s.body.points.role.end(), Role::interior)));
          } else if constexpr (std::is_same_v<std::decay_t<decltype(s)>, NewmarkSetup>) {
            fmt::print("  {}\n", summary(s.quadrature));
            fmt::print("  implicit Newmark: dt = {:.4e} s to t = {:.4e} s; s0 = {:.4e}\n", s.options.dt, s.options.end_time, s.model.s0);
          } else if constexpr (std::is_same_v<std::decay_t<decltype(s)>, QuasiStaticSetup>) {
            fmt::print("  RNP: C = {:.6g}, beta = {:.6g}; {} load steps\n", s.model.C, s.model.beta, s.solver.options.steps);
          } else {
            fmt::print("  dt = {:.4e} s (stable estimate {:.4e} s), {} steps\n", s.time_step.dt, s.time_step.estimate, s.time_step.steps);
            if (s.time_step.above_estimate()) fmt::print(stderr, "warning: solver.dt exceeds the stable estimate\n");
          }
        },
        composed);
    return exit_ok;
  } catch (const std::exception& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return exit_input_error;
  }
}
