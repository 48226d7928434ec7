// A deck run through the library with an observer of one's own: prints the largest
// displacement of each reported step. Usage: peridot-example deck.yaml [every]
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fmt/core.h>
import peridot.run;

struct LargestDisplacement {
  void observe(const peridot::Sample& s) {
    double most = 0;
    for (std::size_t i = 0; i < s.body.size(); ++i)
      most = std::max(most, std::hypot(s.state.u[0][i], s.state.u[1][i], s.state.u[2][i]));
    fmt::print("step {:>6}  t = {:.4e}  max |u| = {:.6e} m  broken bonds {}\n", s.state.step, s.state.time, most, s.record.broken_bonds);
  }
  void finish(const peridot::RunEnd& end) { fmt::print("{} after {} steps\n", end.ok ? "finished" : end.message, end.steps); }
};

int main(int argc, char** argv) try {
  if (argc < 2) return fmt::print(stderr, "usage: peridot-example deck.yaml [every]\n"), 2;
  peridot::Simulation simulation(peridot::read_deck(argv[1]));
  simulation.add_observer(LargestDisplacement{}, argc > 2 ? std::strtoul(argv[2], nullptr, 10) : 100);
  return simulation.run().exit_status();
} catch (const std::exception& e) {
  fmt::print(stderr, "error: {}\n", e.what());
  return peridot::is_input_error(e) ? 2 : 1;
}
