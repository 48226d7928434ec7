#include <catch2/catch.hpp>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>
#include "../support/cli_run.hpp"
#include "../support/deck_text.hpp"
#include "../support/same.hpp"
import peridot.problem;

using namespace peridot;
namespace fs = std::filesystem;

namespace {

fs::path temp(const std::string& name) { return cli_run::temp("peridot_restart_", name); }

cli_run::Result run_cli(const std::string& args) { return cli_run::run(PERIDOT_EXE, temp("stderr.txt"), args); }

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

// Runs `deck` (300 steps, a checkpoint every 50 to plate.h5) uninterrupted on 2 threads, and
// stopped at step 150 then restarted on 1 thread; the two end states must be bitwise equal.
void require_bitwise_restart(const fs::path& deck, const std::string& name, bool on_stencil = false) {
  const fs::path a = temp(name + "_full"), b = temp(name + "_restarted");
  fs::remove_all(a);
  fs::remove_all(b);
  auto r = run_cli("run " + deck.string() + " --out " + a.string() + " --threads 2");
  INFO(r.err);
  REQUIRE(r.code == 0);
  // The same deck stopped at step 150 (only solver.end_time differs), then continued on 1 thread.
  const fs::path half = temp(name + "_half.yaml");
  std::ofstream(half) << deck_text::replaced(file_text(deck), "end_time: 30.0e-6", "end_time: 15.0e-6");
  r = run_cli("run " + half.string() + " --out " + b.string() + " --threads 2");
  REQUIRE(r.code == 0);
  const auto mid = read_checkpoint(b / "plate.h5");
  REQUIRE(mid.step == 150);
  CHECK(mid.broken > 100);  // fracture is under way at the checkpoint
  r = run_cli("run " + deck.string() + " --out " + b.string() + " --threads 1 --restart " + (b / "plate.h5").string());
  REQUIRE(r.code == 0);

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
TEST_CASE("a restarted run matches an uninterrupted one bit for bit") { require_bitwise_restart(plate, "restart_plate_2d", true); }

TEST_CASE("a restarted run on a bond list matches one bit for bit", "[slow]") {
  require_bitwise_restart(plate_with("list", "horizon_factor: 3", "horizon_factor: 3\n  bonds: list"), "restart_plate_2d");
}

// LPS keeps shape tensors of the bond mask in the model; a restart rebuilds them from the mask.
TEST_CASE("a restarted LPS run matches an uninterrupted one", "[slow]") {
  require_bitwise_restart(fs::path(PERIDOT_SOURCE_DIR) / "tests/apps/decks/restart_lps_2d.yaml", "restart_lps_2d");
}

TEST_CASE("a checkpoint of another deck is refused before any output") {
  const fs::path src = temp("source"), out = temp("out");
  fs::remove_all(src);
  const auto r = run_cli("run " + plate_with("short", "end_time: 30.0e-6", "end_time: 0.5e-6").string() + " --out " + src.string());
  REQUIRE(r.code == 0);
  const auto ckpt = (src / "plate.h5").string();
  REQUIRE(read_checkpoint(ckpt).step == 5);
  const auto refused = [&](const fs::path& deck, const std::string& message) {
    fs::remove_all(out);
    const auto res = run_cli("run " + deck.string() + " --out " + out.string() + " --restart " + ckpt);
    INFO(res.err);
    CHECK(res.code == 2);
    CHECK(res.err.find(message) != std::string::npos);
    CHECK_FALSE(fs::exists(out));  // nothing written, not even the directory
  };
  refused(plate_with("renamed", "name: restart_plate_2d", "name: other_plate"),
          "checkpoint is from deck 'restart_plate_2d' with 4000 points; this deck 'other_plate' has 4000 points");
  const auto coarse = temp("coarse.yaml");
  std::ofstream(coarse) << deck_text::replaced(deck_text::replaced(file_text(plate), "spacing: 1.0e-3", "spacing: 2.0e-3"),
                                               "name: restart_plate_2d", "name: coarse_plate");
  refused(coarse, "checkpoint is from deck 'restart_plate_2d' with 4000 points; this deck 'coarse_plate' has 1000 points");
  refused(plate_with("wider", "horizon_factor: 3", "horizon_factor: 4"), "bond states; this deck has");
  refused(plate_with("dt", "dt: 1.0e-7", "dt: 0.5e-7"), "checkpoint has dt = 9.9999999999999995e-08 s; this deck has dt = 4.9999999999999998e-08 s");
  refused(plate_with("denser", "density: 2440.0", "density: 2441.0"), "deck content hash");
  refused(plate_with("scheme", "dt: 1.0e-7", "dt: 1.0e-7\n  scheme: central_difference"), "solver.scheme = 'velocity_verlet'");
  refused(plate_with("shorter", "end_time: 30.0e-6", "end_time: 0.3e-6"), "past this deck's end");
  // (A changed end_time and output section are accepted: the bitwise tests restart that way.)
  fs::remove_all(src);
  fs::remove_all(out);
}

TEST_CASE("a checkpoint that mends a bond the deck's pre-crack cuts is refused, on a list and on a stencil") {
  for (const bool list : {true, false}) {
    INFO((list ? "bond list" : "stencil"));
    const fs::path src = temp("mended_src"), out = temp("mended_out");
    fs::remove_all(src);
    const auto deck = plate_with(list ? "mended_list" : "mended_stencil", "horizon_factor: 3",
                                 list ? "horizon_factor: 3\n  bonds: list" : "horizon_factor: 3");
    // Five steps of the full deck's end_time: the content hash is the same, nothing has broken yet.
    const auto short_deck = temp(list ? "mended_list_short.yaml" : "mended_stencil_short.yaml");
    std::ofstream(short_deck) << deck_text::replaced(file_text(deck), "end_time: 30.0e-6", "end_time: 0.5e-6");
    const auto r = run_cli("run " + short_deck.string() + " --out " + src.string());
    REQUIRE(r.code == 0);
    const auto ckpt = src / "plate.h5";
    auto c = read_checkpoint(ckpt);
    // A bond the pre-crack cut: on a list state 0, on a stencil "exists" without "intact".
    const std::uint8_t cut = list ? 0 : Stencil::exists;
    const auto at = std::find(c.bond_state.begin(), c.bond_state.end(), cut);
    REQUIRE(at != c.bond_state.end());
    *at = list ? 1 : std::uint8_t(Stencil::exists | Stencil::intact);
    write_checkpoint(ckpt, c);
    fs::remove_all(out);
    const auto res = run_cli("run " + deck.string() + " --out " + out.string() + " --restart " + ckpt.string());
    INFO(res.err);
    CHECK(res.code == 2);
    CHECK(res.err.find(list ? "pre-cracks cut that bond" : "does not fit this deck's stencil") != std::string::npos);
    CHECK_FALSE(fs::exists(out));
    fs::remove_all(src);
  }
}

TEST_CASE("a missing or corrupt checkpoint is an input error") {
  const fs::path out = temp("out_corrupt");
  const auto garbage = temp("garbage.h5");
  std::ofstream(garbage) << "not a checkpoint";
  for (const auto& [file, message] : {std::pair{garbage, "not an HDF5 file"}, std::pair{temp("none.h5"), "cannot open checkpoint file"}}) {
    fs::remove_all(out);
    const auto r = run_cli("run " + plate.string() + " --out " + out.string() + " --restart " + file.string());
    INFO(r.err);
    CHECK(r.code == 2);
    CHECK(r.err.find(message) != std::string::npos);
    CHECK_FALSE(fs::exists(out));
  }
  fs::remove(garbage);
}

TEST_CASE("only explicit runs take --restart or output.checkpoint") {
  const fs::path out = temp("out_solver");
  const std::string decks = std::string(PERIDOT_SOURCE_DIR) + "/data/decks/";
  const auto garbage = temp("any.h5");
  std::ofstream(garbage) << "x";
  const auto r = run_cli("run " + decks + "lps/sine_dirichlet.yaml --out " + out.string() + " --restart " + garbage.string());
  CHECK(r.code == 2);
  CHECK(r.err.find("--restart: solver.type = 'static' cannot restart") != std::string::npos);
  CHECK_FALSE(fs::exists(out));
  const auto check_refused = [&](const std::string& deck, const std::string& from, const std::string& message) {
    const auto file = temp("solver.yaml");
    std::ofstream(file) << deck_text::replaced(file_text(decks + deck), from, from + "\n  checkpoint: {every: 10}");
    const auto res = run_cli("check " + file.string());
    INFO(res.err);
    CHECK(res.code == 2);
    CHECK(res.err.find(message) != std::string::npos);
  };
  check_refused("lps/sine_dirichlet.yaml", "directory: out", "output.checkpoint: not used by solver.type = 'static'");
  check_refused("lps_dynamic/glass_plate.yaml", "directory: out", "output.checkpoint: not used by solver.type = 'newmark'");
  fs::remove(garbage);
}
