// peridot converge: a refinement study of a static deck through peridot::refine, the same
// code the test suite's studies run.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>
#include <fmt/core.h>

#include "commands.hpp"
#include "guarded.hpp"
import peridot.problem;

using namespace peridot;

int converge_command(const ConvergeArgs& args) {
  Problem base;
  const int input = guarded([&] {
    base = read_deck(args.deck);
    check_study(base, {.cells = args.cells, .clouds = args.clouds});
    return int(exit_ok);
  });
  if (input != exit_ok) return exit_input_error;
  const auto dir = std::filesystem::path(args.out_dir ? *args.out_dir : base.output.directory.string());
  return guarded([&] {
    fmt::print("{}: delta = {:g} h, reference {}{}\n", base.name, base.horizon / base.lattice.spacing, base.statics.reference.type,
               args.clouds > 1 ? fmt::format(", RMS over {} clouds per level", args.clouds) : "");
    fmt::print("  {:>6} {:>12} {:>14} {:>14} {:>8} {:>8} {:>9} {:>9} {:>9}\n", "cells", "h", "error u", "error theta", "order u",
               "order th", "weights", "assembly", "solve");
    std::vector<StudyLevel> seen;
    const auto levels = refine(base, {.cells = args.cells, .clouds = args.clouds}, [&](const StudyLevel& l) {
      const double ou = seen.empty() ? NAN : pairwise_order(seen.back(), l, false);
      const double ot = seen.empty() ? NAN : pairwise_order(seen.back(), l, true);
      fmt::print("  {:>6} {:>12.5e} {:>14.6e} {:>14.6e} {:>8.3f} {:>8.3f} {:>8.3f}s {:>8.3f}s {:>8.3f}s\n", l.cells, l.h, l.errors.u,
                 l.errors.theta, ou, ot, l.weights_seconds, l.assembly_seconds, l.solve_seconds);
      std::fflush(stdout);
      seen.push_back(l);
    });
    std::filesystem::create_directories(dir);
    const auto csv = dir / (base.name + "_convergence.csv");
    write_study_csv(csv, levels);
    fmt::print("  least-squares order over all levels: u {:.3f}, theta {:.3f}\n", fitted_order(levels, false), fitted_order(levels, true));
    fmt::print("  output: {}\n", csv.string());
    return int(exit_ok);
  });
}
