import peridot.solvers;
#include <fmt/core.h>
int main() {
  auto pc = peridot::lattice(peridot::rectangle({0, 0, 0}, {0.1, 0.04, 0}), {.spacing = 5e-4});
  auto bonds = peridot::build_bonds(pc, {.horizon = 2e-3});
  fmt::print("{} points {} bonds\n", pc.size(), bonds.size());
}
