#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>
#include <fmt/core.h>

#include "commands.hpp"
import peridot.run;

int check_command(const std::string& deck) {
  using namespace peridot;
  try {
    const Simulation simulation(read_deck(deck));
    const auto& p = simulation.problem();
    fmt::print("{}: ok: {} ({}D): {}\n", deck, p.name, p.dim, combination_of(p).what);
    std::vector<std::string> warnings;
    for (const auto& line : simulation.check_report(warnings)) fmt::print("{}\n", line);
    for (const auto& w : warnings) fmt::print(stderr, "warning: {}\n", w);
    return exit_ok;
  } catch (const std::exception& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return exit_input_error;
  }
}
