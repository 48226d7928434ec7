// Static decks through the library's one run loop: a sequentially linear OSB fracture run is
// observed once per linear solve, like the steps of a dynamic run; a static LPS solve draws a PNG.
#include <catch2/catch.hpp>

#include <unistd.h>

#include <cmath>
#include <cstddef>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <variant>
#include <vector>
#include <peridot/run_record.hpp>
#include "../support/deck_text.hpp"
import peridot.run;
import peridot.render;

using namespace peridot;
namespace fs = std::filesystem;

namespace {

fs::path temp(const std::string& name) { return fs::temp_directory_path() / ("peridot_static_runs_" + std::to_string(getpid()) + "_" + name); }

const fs::path crack_deck = fs::path(PERIDOT_SOURCE_DIR) / "data/decks/osb/crack_dirichlet.yaml";

// The Dirichlet crack deck at half size and twice the spacing (a 10 x 10 grid of 5 mm cells),
// 16 bonds removed per solve, a history row per solve to `dir` and nothing else.
std::string small_crack_deck(const fs::path& dir) {
  auto t = deck_text::file_text(crack_deck);
  t = deck_text::replaced(t, "rectangle: {min: [-0.05, -0.05], max: [0.05, 0.05]}", "rectangle: {min: [-0.025, -0.025], max: [0.025, 0.025]}");
  t = deck_text::replaced(t, "segment: {from: [0, -0.06], to: [0, -0.03]}", "segment: {from: [0, -0.035], to: [0, -0.015]}");
  t = deck_text::replaced(t, "displacement: 0.001}", "displacement: 0.0005}");
  t = deck_text::replaced(t, "spacing: 0.0025", "spacing: 0.005");
  t = deck_text::replaced(t, "bonds_per_solve: 4", "bonds_per_solve: 16");
  t = deck_text::replaced(t, "  vtu: {every: 1}\n  png: {every: 1, field: damage}", "  csv: {every: 1}");
  return deck_text::replaced(t, "directory: out", "directory: " + dir.string());
}

struct Rows {
  std::vector<RunRecord>* rows;
  void observe(const Sample& s) { rows->push_back(s.record); }
};

}  // namespace

TEST_CASE("A sequentially linear OSB run has a history row per linear solve, each with the bonds removed so far", "[osb][fracture]") {
  const fs::path dir = temp("osb_history");
  fs::remove_all(dir);
  const auto text = small_crack_deck(dir);
  std::vector<RunRecord> rows;
  Simulation simulation(parse_deck(text, crack_deck.string()));
  simulation.add_observer(Rows{&rows});
  const RunOutcome out = simulation.run();
  REQUIRE(out.exit_status() == 0);
  const std::size_t solves = out.steps;
  INFO(solves << " solves, " << out.broken << " bonds removed");
  REQUIRE(solves >= 3);
  // The start (step 0, nothing solved) and then every solve, in order.
  REQUIRE(rows.size() == solves + 1);
  for (std::size_t k = 0; k < rows.size(); ++k) CHECK(rows[k].step == k);
  CHECK(rows[0].broken_bonds == 0);
  CHECK(rows[0].strain_energy == 0);

  // The first solve is the plain linear solve of the plate with its pre-crack: the same strain
  // energy as solving the deck once without fracture, outside the loop.
  Problem once = parse_deck(text, crack_deck.string());
  auto composed = compose(once);
  auto& s = std::get<OsbStaticSetup>(composed);
  const std::size_t cut_by_precrack = s.body.broken_bonds() / 2;
  s.options.critical_stretch = 0;
  const auto r = solve_osb_static(s.body, s.model, s.problem, s.options);
  CHECK(r.solves == 1);
  CHECK(rows[1].broken_bonds == 0);
  CHECK(rows[1].strain_energy == Approx(s.model.strain_energy(s.body, r.u)).epsilon(1e-12));
  CHECK(rows[1].strain_energy > 0);
  // Before each later solve between 1 and bonds_per_solve = 16 bonds past s_c were removed.
  for (std::size_t k = 2; k <= solves; ++k) {
    INFO("solve " << k);
    CHECK(rows[k].broken_bonds > rows[k - 1].broken_bonds);
    CHECK(rows[k].broken_bonds - rows[k - 1].broken_bonds <= 16);
  }
  // The history's count is the count of bonds cleared in the body (each from both ends) past
  // those the pre-crack cut.
  CHECK(rows.back().broken_bonds + cut_by_precrack == simulation.body().broken_bonds() / 2);
  CHECK(out.broken == rows.back().broken_bonds);
  // Cracking softens the plate under a fixed end displacement: less energy at the last solve.
  CHECK(rows.back().strain_energy < rows[1].strain_energy);

  // The CSV has the same rows, whole: a header and one line per row.
  std::ifstream csv(dir / "osb_crack_dirichlet_history.csv");
  REQUIRE(csv.good());
  std::size_t lines = 0;
  for (std::string line; std::getline(csv, line);) lines += !line.empty();
  CHECK(lines == rows.size() + 1);
  fs::remove_all(dir);
}

TEST_CASE("A static LPS deck draws its solution: the PNG of the solve is the renderer's picture of the VTU's displacement") {
  const fs::path dir = temp("lps_png");
  fs::remove_all(dir);
  const fs::path deck = fs::path(PERIDOT_SOURCE_DIR) / "data/decks/lps/sine_dirichlet.yaml";
  auto text = deck_text::file_text(deck);
  text = deck_text::replaced(text, "directory: out", "directory: " + dir.string());
  text = deck_text::replaced(text, "  vtu: {every: 1}", "  vtu: {every: 1}\n  png: {every: 1, width: 200, field: displacement}");
  REQUIRE(run(parse_deck(text, deck.string())).exit_status() == 0);
  std::ifstream in(dir / "lps_sine_dirichlet_0000001.png", std::ios::binary);
  const std::vector<unsigned char> png{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  REQUIRE(!png.empty());
  // Second path: the displacement the solve wrote to its VTU, drawn by peridot.render as the
  // run labels it (linear solve 1).
  SavedField saved = read_saved_field(dir / "lps_sine_dirichlet.vtu", "displacement", 1.0);
  saved.field.time_label = "linear solve";
  saved.field.field_name = "|displacement| [m]";
  saved.field.step = 1;
  saved.field.spacing = 0.19634954084936207;
  RenderOptions o;
  o.width = 200;
  CHECK((render_png_bytes(saved.field, o) == png));  // not decomposed: a failure would print every byte
  fs::remove_all(dir);
}

// A sequentially linear run whose removed bonds cut its plate loose: the uncorrected Neumann
// crack deck at h = 5 mm (the right edge pulled by a traction, the left clamped) comes apart
// after 168 equilibria. Every solve it reports is an equilibrium, its relative residual that of
// a direct solve; the first that finds none ends the run. (Before, the run went on removing bonds
// by the noise of near-singular solves: 122 re-solves more, ending at a residual of 16.)
TEST_CASE("A static OSB fracture run stops at the first re-solve that finds no equilibrium, and the solve it reports last is one") {
  const fs::path deck = fs::path(PERIDOT_SOURCE_DIR) / "data/decks/osb/crack_neumann_uncorrected.yaml";
  const fs::path dir = temp("osb_apart");
  fs::remove_all(dir);
  auto t = deck_text::file_text(deck);
  t = deck_text::replaced(t, "spacing: 0.0025", "spacing: 0.005");
  t = deck_text::replaced(t, "  vtu: {every: 1}\n  png: {every: 1, field: damage}", "  csv: {every: 1}");
  t = deck_text::replaced(t, "directory: out", "directory: " + dir.string());
  std::vector<std::string> lines;
  RunOptions options;
  options.print = [&](const std::string& line) { lines.push_back(line); };
  std::vector<RunRecord> rows;
  Simulation simulation(parse_deck(t, deck.string()), options);
  simulation.add_observer(Rows{&rows});
  const RunOutcome out = simulation.run();
  fs::remove_all(dir);
  REQUIRE(out.exit_status() == 0);
  std::string summary, solve;
  for (const auto& line : lines) {
    if (line.find("fracture: ") != std::string::npos && line.find(" solves, ") != std::string::npos) summary = line;
    if (line.find(" residual ") != std::string::npos) solve = line;
  }
  INFO(summary << "\n" << solve);
  CHECK_THAT(summary, Catch::Contains("stopped: equilibrium is no longer possible"));
  REQUIRE(solve.rfind(" residual ") != std::string::npos);
  const double residual = std::stod(solve.substr(solve.rfind(" residual ") + 10));
  CHECK(residual < 1e-8);
  // The plate did crack before it came apart; the history has a row per solve kept.
  CHECK(out.broken > 100);
  CHECK(rows.back().broken_bonds == out.broken);
}
