// A library user's part observer (PartSample) in-process on one process: its part is the whole
// body, every point owned once, and what it sums over its owned points is the run's own figure.
// On N ranks the example program checks it against one process (test_example).
#include <catch2/catch.hpp>

#include <unistd.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <algorithm>
#include <string>
#include <vector>
#include <peridot/run_record.hpp>
#include "../support/deck_text.hpp"
import peridot.run;

using namespace peridot;
namespace fs = std::filesystem;

namespace {

const fs::path plate_deck = fs::path(PERIDOT_SOURCE_DIR) / "data/decks/osb/explicit_plate.yaml";

struct Seen {
  std::vector<std::size_t> part_steps, whole_steps;
  bool every_point_once = true;
  bool rows_current = true;  // the history row it reads is its step's
  double worst = 0;  // |part's kinetic energy - the history row's| / the row's
  double largest = 0;
  int finished = 0;
};

// Sums 1/2 rho V |v|^2 over its owned points in its own order and reduces it over the ranks.
struct KineticFromParts {
  Seen* seen;
  void observe(const PartSample& s) {
    seen->part_steps.push_back(s.state.step);
    bool once = s.ranks == 1 && s.rank == 0 && s.points == s.body.size() && s.owned.size() == s.body.size() && s.ids.size() == s.body.size();
    for (std::size_t k = 0; once && k < s.owned.size(); ++k) once = s.owned[k] == std::int64_t(k) && s.ids[k] == std::int64_t(k);
    seen->every_point_once = seen->every_point_once && once;
    ExactSum kinetic;
    const auto& v = s.state.v;
    for (auto i : s.owned) {
      const auto j = std::size_t(i);
      kinetic += 0.5 * s.body.density * s.body.points.volume[j] * (v[0][j] * v[0][j] + v[1][j] * v[1][j] + v[2][j] * v[2][j]);
    }
    const double total = s.sum(kinetic);
    REQUIRE(s.record != nullptr);
    seen->rows_current = seen->rows_current && s.record->step == s.state.step;
    seen->largest = std::max(seen->largest, s.record->kinetic_energy);
    if (s.record->kinetic_energy > 0) seen->worst = std::max(seen->worst, std::abs(total - s.record->kinetic_energy) / s.record->kinetic_energy);
    else if (total != 0) seen->worst = 1;
  }
  void finish(const RunEnd& end) { seen->finished += end.ok ? 1 : 100; }
};

struct Steps {
  Seen* seen;
  void observe(const Sample& s) { seen->whole_steps.push_back(s.state.step); }
};

}  // namespace

TEST_CASE("A part observer on one process owns every point once, is due on its own cadence with its step's history row, and its exact "
          "sum of kinetic energy is the row's") {
  const fs::path dir = fs::temp_directory_path() / ("peridot_part_observers_" + std::to_string(getpid()));
  fs::remove_all(dir);
  auto text = deck_text::file_text(plate_deck);
  text = deck_text::replaced(text, "end_time: 4.0e-4", "end_time: 1.0e-4");
  text = deck_text::replaced(text, "  vtu: {every: 400, stress: true}\n  png: {every: 400, field: stress_xx}\n", "");
  text = deck_text::replaced(text, "directory: out", "directory: " + dir.string());
  Seen seen;
  Simulation simulation(parse_deck(text, plate_deck.string()));
  simulation.add_observer(KineticFromParts{&seen}, 7);
  simulation.add_observer(Steps{&seen}, 14);  // and the deck's CSV every 20
  const RunOutcome out = simulation.run();
  fs::remove_all(dir);
  REQUIRE(out.steps > 14);
  std::vector<std::size_t> sevens, fourteens;
  for (std::size_t n = 0; n <= out.steps; n += 7) (n % 14 ? sevens : fourteens).push_back(n);
  sevens.insert(sevens.end(), fourteens.begin(), fourteens.end());
  std::ranges::sort(sevens);
  for (auto* steps : {&sevens, &fourteens})
    if (steps->back() != out.steps) steps->push_back(out.steps);  // and the last
  CHECK(seen.part_steps == sevens);
  CHECK(seen.whole_steps == fourteens);
  CHECK(seen.rows_current);
  CHECK(seen.every_point_once);
  CHECK(seen.largest > 0);  // the traction has set the plate moving
  CHECK(seen.worst < 1e-13);
  CHECK(seen.finished == 1);
}
