#include <catch2/catch.hpp>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>
#include "../support/rnp_path.hpp"
import peridot.problem;

using namespace peridot;

// Seed 002 at the decks' own (paper) resolution: minutes each on 2 cores.

namespace {

rnp_path::Path run_deck(const std::string& name) {
  const auto path = rnp_path::run(name);
  for (const auto& r : path.steps)
    WARN(name << ": load " << r.load << ", Newton " << r.iterations << " (" << r.linear_solver << "), max damage " << r.max_damage
              << ", softening bonds " << r.softening_bonds << ", cuts " << r.cuts << ", " << r.seconds << " s");
  return path;
}

using rnp_path::first_softening;

}  // namespace

TEST_CASE("Sec. 6.2.3: the pre-cracked plate under soft loading grows unstably once softening starts (h = 0.2, delta = 4h)") {
  const auto path = run_deck("precracked_soft.yaml");
  WARN(path.message);
  REQUIRE(path.failed);
  const double soft = first_softening(path);
  REQUIRE(soft > 0);
  CHECK(path.steps.back().load < soft + 0.3);
}

TEST_CASE("Sec. 6.2.4: the pre-cracked plate under hard loading grows stably over several steps (h = 0.2, delta = 8h)") {
  const auto path = run_deck("precracked_hard.yaml");
  INFO(path.message);
  CHECK_FALSE(path.failed);
  const double soft = first_softening(path);
  REQUIRE(soft > 0);
  std::size_t after = 0;
  for (const auto& r : path.steps) after += r.load >= soft;
  CHECK(after >= 5);
}

TEST_CASE("Sec. 6.2.2: the tension specimen under soft loading softens and then fails unstably (h = 1, delta = 4h)") {
  const auto path = run_deck("tension_specimen_soft.yaml");
  WARN(path.message);
  CHECK(path.failed);
  CHECK(first_softening(path) > 0);
}
