// One deck, two bond layouts: the pre-cracked PMB plate run through the library on the lattice
// stencil (float displacements, a state byte per point and offset) and on the CSR list, in double
// throughout (discretization.list_precision: double) as a second code path, and in single
// precision (the default: float bond arithmetic on fixed-point bond vectors).
#include <catch2/catch.hpp>
#include <omp.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>
#include <peridot/run_record.hpp>
#include "../support/deck_text.hpp"
import peridot.run;

namespace fs = std::filesystem;

namespace {

// The history rows of a run, kept in memory by a user observer: nothing is written.
struct Rows {
  std::vector<peridot::RunRecord>* rows;
  void observe(const peridot::Sample& s) { rows->push_back(s.record); }
};

std::vector<peridot::RunRecord> run(const std::string& layout, const std::string& precision = "single") {
  const fs::path file = fs::path(PERIDOT_SOURCE_DIR) / "tests/apps/decks/restart_plate_2d.yaml";
  peridot::Problem p = peridot::parse_deck(deck_text::replaced(deck_text::file_text(file), "horizon_factor: 3",
                                                               "horizon_factor: 3\n  bonds: " + layout + "\n  list_precision: " + precision),
                                           file.string());
  p.output = peridot::OutputSpec{};
  omp_set_num_threads(2);
  std::vector<peridot::RunRecord> rows;
  peridot::Simulation simulation(std::move(p));
  simulation.add_observer(Rows{&rows}, 10);
  REQUIRE(simulation.run().exit_status() == 0);
  return rows;
}

// Float rounding of u and of the pair forces is ~1e-7 relative per bond and step; over 300 steps
// the energies stay within 1e-5 of the double-precision run. Break decisions differ only for
// bonds within ~1e-6 s0 of the threshold (pmb_stencil.cppm, pmb_lean_kernel.cpp), and none of
// this run's 3000 breaks comes that close: the same bonds break in the same steps.
void require_alike(const std::vector<peridot::RunRecord>& a, const std::vector<peridot::RunRecord>& exact) {
  REQUIRE(a.size() == 31);
  REQUIRE(exact.size() == 31);
  // The same bonds exist and the pre-crack cut the same ones.
  CHECK(std::abs(a[0].damage_fraction - exact[0].damage_fraction) <= 1e-12);
  for (std::size_t r = 1; r < 31; ++r) {
    INFO("step " << a[r].step);
    REQUIRE(a[r].step == exact[r].step);
    CHECK(a[r].broken_bonds == exact[r].broken_bonds);
    CHECK(std::abs(a[r].damage_fraction - exact[r].damage_fraction) <= 1e-12);  // weights summed in another order
    CHECK(std::abs(a[r].kinetic_energy - exact[r].kinetic_energy) <= 1e-5 * std::abs(exact[r].kinetic_energy));
    CHECK(std::abs(a[r].strain_energy - exact[r].strain_energy) <= 1e-5 * std::abs(exact[r].strain_energy));
    CHECK(std::abs(a[r].external_work - exact[r].external_work) <= 1e-5 * std::abs(exact[r].external_work));
  }
  CHECK(a.back().broken_bonds > 2000);  // fracture ran all along
  CHECK(a.back().kinetic_energy != exact.back().kinetic_energy);  // two code paths, not one compared with itself
}

}  // namespace

TEST_CASE("the plate runs alike on the lattice stencil and on the bond list in double", "[slow]") {
  require_alike(run("stencil"), run("list", "double"));
}

TEST_CASE("the plate runs alike on the bond list in single precision and in double", "[slow]") {
  require_alike(run("list", "single"), run("list", "double"));
}

TEST_CASE("a PMB list body beyond the single-precision kernel's fixed point is refused in the set-up, naming list_precision") {
  // delta = 3 mm: q = 2^-33 m, so the fixed point reaches 2^18 m = 262 km from the origin.
  const fs::path file = fs::path(PERIDOT_SOURCE_DIR) / "tests/apps/decks/restart_plate_2d.yaml";
  std::string text = deck_text::replaced(deck_text::file_text(file), "rectangle: {min: [0.0, 0.0], max: [0.1, 0.04]}",
                                         "rectangle: {min: [3.0e5, 0.0], max: [300000.1, 0.04]}");
  text = deck_text::replaced(text, "segment: {from: [0.0, 0.02], to: [0.05, 0.02]}", "segment: {from: [3.0e5, 0.02], to: [300000.05, 0.02]}");
  for (const std::string precision : {"single", "double"}) {
    INFO("list_precision " << precision);
    peridot::Problem p = peridot::parse_deck(
        deck_text::replaced(text, "horizon_factor: 3", "horizon_factor: 3\n  bonds: list\n  list_precision: " + precision), file.string());
    p.output = peridot::OutputSpec{};
    p.solver.end_time = 10 * p.solver.dt;
    if (precision == "single") {
      REQUIRE_THROWS_WITH(peridot::Simulation(std::move(p)), Catch::Contains("discretization.list_precision = 'single'") &&
                                                                 Catch::Contains("262144 m"));
    } else {
      peridot::Simulation simulation(std::move(p));
      CHECK(simulation.run().exit_status() == 0);
    }
  }
}
