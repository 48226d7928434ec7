// A deck run through the library with an observer of one's own: prints the largest
// displacement of each reported step. Usage: peridot-example deck.yaml [every] [--whole] [--steps N]
//
// The observer reads its part of the body on every rank (PartSample) and reduces over the
// ranks, so under mpirun no rank gathers the body for it. With --whole it reads the whole body
// on rank 0 instead (Sample), which rank 0 then gathers from the ranks on every reported step:
// simpler to write, and the same lines.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>
#include <fmt/core.h>
import peridot.run;

namespace {

double length(const peridot::VectorField& u, std::size_t i) { return std::hypot(u[0][i], u[1][i], u[2][i]); }

void print_line(const peridot::State& s, double most, std::size_t broken) {
  fmt::print("step {:>6}  t = {:.4e}  max |u| = {:.6e} m  broken bonds {}\n", s.step, s.time, most, broken);
}

void print_end(const peridot::RunEnd& end) { fmt::print("{} after {} steps\n", end.ok ? "finished" : end.message, end.steps); }

struct LargestDisplacement {
  void observe(const peridot::PartSample& s) {
    double most = 0;
    for (auto i : s.owned) most = std::max(most, length(s.state.u, std::size_t(i)));
    most = s.max(most);  // every rank calls it
    root = s.rank == 0;
    if (root) print_line(s.state, most, s.record->broken_bonds);
  }
  void finish(const peridot::RunEnd& end) {
    if (root) print_end(end);
  }
  bool root = true;  // rank 0 prints
};

struct LargestDisplacementOnRoot {
  void observe(const peridot::Sample& s) {
    double most = 0;
    for (std::size_t i = 0; i < s.body.size(); ++i) most = std::max(most, length(s.state.u, i));
    print_line(s.state, most, s.record.broken_bonds);
  }
  void finish(const peridot::RunEnd& end) { print_end(end); }
};

}  // namespace

int main(int argc, char** argv) try {
  // Positional: the deck, the cadence; options anywhere after the deck.
  std::vector<const char*> positional;
  bool whole = false;
  peridot::RunOptions options;
  for (int k = 1; k < argc; ++k) {
    if (std::strcmp(argv[k], "--whole") == 0) whole = true;
    else if (std::strcmp(argv[k], "--steps") == 0 && k + 1 < argc) options.max_steps = std::strtoul(argv[++k], nullptr, 10);
    else positional.push_back(argv[k]);
  }
  if (positional.empty() || positional.size() > 2) return fmt::print(stderr, "usage: peridot-example deck.yaml [every] [--whole] [--steps N]\n"), 2;
  const std::size_t every = positional.size() > 1 ? std::strtoul(positional[1], nullptr, 10) : 100;
  peridot::Simulation simulation(peridot::read_deck(positional[0]), options);
  if (whole) simulation.add_observer(LargestDisplacementOnRoot{}, every);
  else simulation.add_observer(LargestDisplacement{}, every);
  return simulation.run().exit_status();
} catch (const std::exception& e) {
  fmt::print(stderr, "error: {}\n", e.what());
  return peridot::is_input_error(e) ? 2 : 1;
}
