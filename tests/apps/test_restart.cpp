// Restarts through the library: a deck run in-process by peridot::Simulation, stopped at a
// checkpoint and continued from it (RunOptions::restart) on another thread count; foreign or
// damaged checkpoints refused with a DeckError before any file. (test_cli.cpp keeps one case
// that `peridot run --restart FILE` reaches the library.)
#include <catch2/catch.hpp>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <utility>
#include <variant>
#include <vector>
#include "../support/deck_text.hpp"
#include "../support/in_process.hpp"
#include "../support/same.hpp"
import peridot.run;

using namespace peridot;
namespace fs = std::filesystem;

namespace {

// Every test case uses names of its own.
fs::path temp(const std::string& name) { return in_process::temp("peridot_restart_", name); }

using in_process::refusal;
using in_process::run_deck;

// A coarse pre-cracked PMB plate: 4000 points, dt = 1e-7 s, 300 steps, bonds break from about
// step 30; a checkpoint every 50 steps (and at the last) to <out>/plate.h5.
const fs::path plate = fs::path(PERIDOT_SOURCE_DIR) / "tests/apps/decks/restart_plate_2d.yaml";

using deck_text::file_text;

// The plate deck with one piece of text replaced, as a temporary file.
fs::path plate_with(const std::string& name, const std::string& from, const std::string& to) {
  const fs::path file = temp(name + ".yaml");
  std::ofstream(file) << deck_text::replaced(file_text(plate), from, to);
  return file;
}

// The CSV history without its wall_time column, which differs between runs.
std::vector<std::string> history_rows(const fs::path& file) {
  std::ifstream in(file);
  std::vector<std::string> rows;
  std::string header;
  std::getline(in, header);
  std::size_t wall = 0;
  std::stringstream hs(header);
  for (std::string col; std::getline(hs, col, ',') && col.rfind("wall_time", 0) != 0;) ++wall;
  for (std::string line; std::getline(in, line);) {
    std::stringstream ls(line);
    std::string row, cell;
    for (std::size_t k = 0; std::getline(ls, cell, ','); ++k)
      if (k != wall) row += cell + ",";
    rows.push_back(row);
  }
  return rows;
}

// Runs `deck` (300 steps, a checkpoint every 50 to plate.h5; `name` its deck name)
// uninterrupted on 2 threads, and stopped at step 150 then restarted on 1 thread; the two end
// states must be bitwise equal. `tag` names the case's temporary files.
void require_bitwise_restart(const fs::path& deck, const std::string& name, const std::string& tag, bool on_stencil = false) {
  const fs::path a = temp(tag + "_full"), b = temp(tag + "_restarted");
  fs::remove_all(a);
  fs::remove_all(b);
  run_deck(deck, a, 2);
  // The same deck stopped at step 150 (only solver.end_time differs), then continued on 1 thread.
  const fs::path half = temp(tag + "_half.yaml");
  std::ofstream(half) << deck_text::replaced(file_text(deck), "end_time: 30.0e-6", "end_time: 15.0e-6");
  run_deck(half, b, 2);
  const auto mid = read_checkpoint(b / "plate.h5");
  REQUIRE(mid.step == 150);
  CHECK(mid.broken > 100);  // fracture is under way at the checkpoint
  run_deck(deck, b, 1, b / "plate.h5");

  const auto x = read_checkpoint(a / "plate.h5"), y = read_checkpoint(b / "plate.h5");
  REQUIRE(x.step == 300);
  REQUIRE(y.step == 300);
  CHECK(x.time == y.time);
  CHECK(same::difference(x.u, y.u, "x.u") == "");
  CHECK(same::difference(x.v, y.v, "x.v") == "");
  CHECK(same::difference(x.f, y.f, "x.f") == "");
  CHECK(same::difference(x.bond_state, y.bond_state, "x.bond_state") == "");
  // A stencil's states carry an `exists` bit (2 broken, 3 intact); a list's are 0 or 1.
  const bool stencil_states = std::count(x.bond_state.begin(), x.bond_state.end(), std::uint8_t(3)) > 0;
  CHECK(stencil_states == on_stencil);
  CHECK(x.broken == y.broken);
  CHECK(x.broken > mid.broken);
  CHECK(x.external_work == y.external_work);
  // The restarted run's history is the uninterrupted one: rows before step 150 kept, the rest
  // appended once; the .pvd lists the first run's VTUs and the new ones.
  const auto rows = history_rows(a / (name + "_history.csv"));
  CHECK(rows.size() == 31);
  CHECK(same::difference(history_rows(b / (name + "_history.csv")), rows, "history rows") == "");
  CHECK(read_pvd(b / (name + ".pvd")).size() == 4);
  const auto vtu = name + "_0000300.vtu";
  CHECK(read_vtu(b / vtu).find("displacement")->values == read_vtu(a / vtu).find("displacement")->values);
  for (const auto& e : fs::directory_iterator(b)) CHECK(e.path().extension() != ".tmp");
  fs::remove_all(a);
  fs::remove_all(b);
}

}  // namespace

// The plate is a PMB lattice body: it runs on the lattice stencil unless the deck asks for a list.
TEST_CASE("a restarted run matches an uninterrupted one bit for bit") {
  require_bitwise_restart(plate, "restart_plate_2d", "stencil", true);
}

// Stencil checkpoints written before bond_layout held the stencil's padded state grid, and
// still restart. Such a file is made here from a new one: its states put into a stencil body
// (restore_run) and written out as that body holds them, without the attribute.
TEST_CASE("a stencil checkpoint in the padded grid of earlier versions still restarts bit for bit") {
  const fs::path a = temp("padded_full"), b = temp("padded_restarted");
  fs::remove_all(a);
  fs::remove_all(b);
  run_deck(plate, a, 2);
  const fs::path half = temp("padded_half.yaml");
  std::ofstream(half) << deck_text::replaced(file_text(plate), "end_time: 30.0e-6", "end_time: 15.0e-6");
  run_deck(half, b, 2);
  const auto mid = read_checkpoint(b / "plate.h5");
  REQUIRE(mid.step == 150);
  REQUIRE(mid.bond_layout == "point_offsets");
  auto setup = std::get<Setup>(compose(read_deck(plate)));
  REQUIRE(setup.body.on_stencil());
  REQUIRE(mid.bonds == setup.body.size() * setup.body.stencil.offsets());
  auto moved = mid;
  State state(setup.body.size());
  restore_run(moved, setup.body, state);
  auto padded = mid;
  const auto grid = setup.body.bond_states();
  padded.bond_state.assign(grid.begin(), grid.end());
  padded.bonds = padded.bond_state.size();
  padded.bond_layout.clear();
  REQUIRE(padded.bonds != mid.bonds);  // the grid pads its rows: another layout, another size
  write_checkpoint(b / "plate.h5", padded);
  run_deck(plate, b, 1, b / "plate.h5");
  const auto x = read_checkpoint(a / "plate.h5"), y = read_checkpoint(b / "plate.h5");
  REQUIRE(y.step == 300);
  CHECK(same::difference(x.u, y.u, "x.u") == "");
  CHECK(same::difference(x.bond_state, y.bond_state, "x.bond_state") == "");
  CHECK(x.broken == y.broken);
  fs::remove_all(a);
  fs::remove_all(b);
}

TEST_CASE("a restarted run on a bond list matches one bit for bit", "[slow]") {
  require_bitwise_restart(plate_with("list", "horizon_factor: 3", "horizon_factor: 3\n  bonds: list"), "restart_plate_2d", "list");
}

// LPS keeps shape tensors of the bond mask in the model; a restart rebuilds them from the mask.
TEST_CASE("a restarted LPS run matches an uninterrupted one", "[slow]") {
  require_bitwise_restart(fs::path(PERIDOT_SOURCE_DIR) / "tests/apps/decks/restart_lps_2d.yaml", "restart_lps_2d", "lps");
}

TEST_CASE("a checkpoint of another deck is refused before any output") {
  const fs::path src = temp("foreign_source"), out = temp("foreign_out");
  fs::remove_all(src);
  run_deck(plate_with("foreign_short", "end_time: 30.0e-6", "end_time: 0.5e-6"), src);
  const auto ckpt = src / "plate.h5";
  REQUIRE(read_checkpoint(ckpt).step == 5);
  const auto refused = [&](const fs::path& deck, const std::string& message) {
    fs::remove_all(out);
    const auto error = refusal(deck, out, ckpt);
    INFO(error);
    CHECK(error.find(message) != std::string::npos);
    CHECK_FALSE(fs::exists(out));  // nothing written, not even the directory
  };
  refused(plate_with("foreign_renamed", "name: restart_plate_2d", "name: other_plate"),
          "checkpoint is from deck 'restart_plate_2d' with 4000 points; this deck 'other_plate' has 4000 points");
  const auto coarse = temp("foreign_coarse.yaml");
  std::ofstream(coarse) << deck_text::replaced(deck_text::replaced(file_text(plate), "spacing: 1.0e-3", "spacing: 2.0e-3"),
                                               "name: restart_plate_2d", "name: coarse_plate");
  refused(coarse, "checkpoint is from deck 'restart_plate_2d' with 4000 points; this deck 'coarse_plate' has 1000 points");
  refused(plate_with("foreign_wider", "horizon_factor: 3", "horizon_factor: 4"), "bond states; this deck has");
  refused(plate_with("foreign_dt", "dt: 1.0e-7", "dt: 0.5e-7"), "checkpoint has dt = 9.9999999999999995e-08 s; this deck has dt = 4.9999999999999998e-08 s");
  refused(plate_with("foreign_denser", "density: 2440.0", "density: 2441.0"), "deck content hash");
  refused(plate_with("foreign_scheme", "dt: 1.0e-7", "dt: 1.0e-7\n  scheme: central_difference"), "solver.scheme = 'velocity_verlet'");
  refused(plate_with("foreign_shorter", "end_time: 30.0e-6", "end_time: 0.3e-6"), "past this deck's end");
  // (A changed end_time and output section are accepted: the bitwise tests restart that way.)
  fs::remove_all(src);
  fs::remove_all(out);
}

TEST_CASE("a checkpoint that mends a bond the deck's pre-crack cuts is refused, on a list and on a stencil") {
  for (const bool list : {true, false}) {
    INFO((list ? "bond list" : "stencil"));
    const fs::path src = temp(list ? "mended_list_src" : "mended_stencil_src"), out = temp(list ? "mended_list_out" : "mended_stencil_out");
    fs::remove_all(src);
    const auto deck = plate_with(list ? "mended_list" : "mended_stencil", "horizon_factor: 3",
                                 list ? "horizon_factor: 3\n  bonds: list" : "horizon_factor: 3");
    // Five steps of the full deck's end_time: the content hash is the same, nothing has broken yet.
    const auto short_deck = temp(list ? "mended_list_short.yaml" : "mended_stencil_short.yaml");
    std::ofstream(short_deck) << deck_text::replaced(file_text(deck), "end_time: 30.0e-6", "end_time: 0.5e-6");
    run_deck(short_deck, src);
    const auto ckpt = src / "plate.h5";
    auto c = read_checkpoint(ckpt);
    // A bond the pre-crack cut: on a list state 0, on a stencil "exists" without "intact".
    const std::uint8_t cut = list ? 0 : Stencil::exists;
    const auto at = std::find(c.bond_state.begin(), c.bond_state.end(), cut);
    REQUIRE(at != c.bond_state.end());
    *at = list ? 1 : std::uint8_t(Stencil::exists | Stencil::intact);
    write_checkpoint(ckpt, c);
    fs::remove_all(out);
    const auto error = refusal(deck, out, ckpt);
    INFO(error);
    CHECK(error.find(list ? "pre-cracks cut that bond" : "does not fit this deck's stencil") != std::string::npos);
    CHECK_FALSE(fs::exists(out));
    fs::remove_all(src);
  }
}

TEST_CASE("a missing or corrupt checkpoint is an input error") {
  const fs::path out = temp("corrupt_out");
  const auto garbage = temp("corrupt_garbage.h5");
  std::ofstream(garbage) << "not a checkpoint";
  for (const auto& [file, message] : {std::pair{garbage, "not an HDF5 file"}, std::pair{temp("corrupt_none.h5"), "cannot open checkpoint file"}}) {
    fs::remove_all(out);
    const auto error = refusal(plate, out, file);
    INFO(error);
    CHECK(error.find(message) != std::string::npos);
    CHECK_FALSE(fs::exists(out));
  }
  fs::remove(garbage);
}

TEST_CASE("only explicit runs take a restart or output.checkpoint") {
  const fs::path out = temp("solver_out");
  const std::string decks = std::string(PERIDOT_SOURCE_DIR) + "/data/decks/";
  const auto garbage = temp("solver_any.h5");
  std::ofstream(garbage) << "x";
  const auto error = refusal(decks + "lps/sine_dirichlet.yaml", out, garbage);
  CHECK(error.find("--restart: solver.type = 'static' cannot restart") != std::string::npos);
  CHECK_FALSE(fs::exists(out));
  // As `peridot check` does: the deck read and composed, nothing run.
  const auto check_refused = [&](const std::string& deck, const std::string& from, const std::string& message) {
    const auto file = temp("solver_checkpoint.yaml");
    std::ofstream(file) << deck_text::replaced(file_text(decks + deck), from, from + "\n  checkpoint: {every: 10}");
    const auto why = refusal(file, out, std::nullopt);
    INFO(why);
    CHECK(why.find(message) != std::string::npos);
    CHECK_FALSE(fs::exists(out));
  };
  check_refused("lps/sine_dirichlet.yaml", "directory: out", "output.checkpoint: not used by solver.type = 'static'");
  check_refused("lps_dynamic/glass_plate.yaml", "directory: out", "output.checkpoint: not used by solver.type = 'newmark'");
  fs::remove(garbage);
}
