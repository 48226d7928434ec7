// peridot-bench: explicit-solver throughput on the crack-branching decks at 1 and 2 threads.
// Prints seconds per step, directed bond evaluations per second (each bond counted from
// both ends, as CabanaPD counts) and resident bytes per bond.
#include <omp.h>

#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <variant>
#include <vector>
#include <fmt/core.h>
import peridot.problem;

using namespace peridot;

namespace {

void bench(const std::string& deck, std::size_t steps, const std::vector<int>& threads) {
  const Problem p = read_deck(deck);
  const auto t_setup = std::chrono::steady_clock::now();
  Setup base = setup(p);
  const double setup_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_setup).count();
  const double directed = double(base.body.bonds.size());
  fmt::print("{}: {} points, {:.0f} directed bonds ({:.1f} per point), {:.1f} bytes per bond, setup {:.2f} s\n", p.name,
             base.body.size(), directed, directed / double(base.body.size()), base.body.bonds.bytes_per_bond(), setup_s);
  steps = std::min(steps, base.time_step.steps);
  for (int n : threads) {
    omp_set_num_threads(n);
    Setup s = base;  // fresh bonds: every run breaks the same bonds
    const auto& pmb = std::get<Pmb>(s.model);
    ExplicitSolver solver(s.body, pmb, s.boundaries, s.time_step);
    State state(s.body.size());
    solver.initialize(state);
    const auto t0 = std::chrono::steady_clock::now();
    for (std::size_t k = 0; k < steps; ++k) solver.step(state);
    const double sec = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / double(steps);
    fmt::print("  threads {}: {:.4f} s/step, {:.3e} directed bond evaluations/s ({} steps, {} bonds broken)\n", n, sec,
               directed / sec, steps, solver.broken_bonds());
    std::fflush(stdout);
  }
}

}  // namespace

int main(int argc, char** argv) {
  std::size_t steps = 955;
  std::vector<std::string> decks;
  CLI::App app{"peridot-bench: explicit PMB throughput at 1 and 2 threads (default decks: crack_branching_3d and _2d)"};
  app.add_option("decks", decks, "YAML decks")->check(CLI::ExistingFile);
  app.add_option("--steps", steps, "steps per timing (at most the deck's)")->check(CLI::Range(std::size_t(1), std::size_t(1000000)));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  if (decks.empty())
    decks = {std::string(PERIDOT_SOURCE_DIR) + "/data/decks/crack_branching_3d.yaml",
             std::string(PERIDOT_SOURCE_DIR) + "/data/decks/crack_branching_2d.yaml"};
  try {
    for (const auto& d : decks) bench(d, steps, {1, 2});
  } catch (const std::exception& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return 2;
  }
  return 0;
}
