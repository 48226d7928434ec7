// peridot run of explicit decks on N MPI ranks (mpirun -np 2 and 4) against the one-rank run.
// Each point sums its bonds in the same order on any rank count, so the end states must be
// bitwise equal: displacements, velocities, forces, every bond's state, damage, the CSV history
// and the PNG. Every mpirun is bounded by `timeout -k`, stays on loopback (shared memory between
// ranks, the launcher's channel on lo) and is reaped by timeout if it hangs.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>
#include "../support/cli_run.hpp"
#include "../support/csv_columns.hpp"
#include "../support/mpirun.hpp"
#include "../support/deck_text.hpp"
import peridot.io;

namespace fs = std::filesystem;
using peridot::Checkpoint;

namespace {

fs::path temp(const std::string& name) { return cli_run::temp("peridot_mpi_explicit_", name); }

const fs::path decks = fs::path(PERIDOT_SOURCE_DIR) / "data/decks";

using deck_text::file_text;

// Runs `deck` with `launcher` into a fresh directory `name`; returns the directory.
fs::path run(const std::string& launcher, const fs::path& deck, const std::string& name, const std::string& extra = "") {
  const fs::path out = temp(name);
  fs::remove_all(out);
  const auto r = cli_run::run(launcher, temp(name + ".err"), "run " + deck.string() + " --out " + out.string() + " " + extra);
  INFO(name << ": " << r.err);
  REQUIRE(r.code == 0);
  return out;
}

// The CSV history, each row without its wall-time and external-work cells: wall time differs
// between any two runs, and external work is a sum of per-rank sums (checked to round-off).
std::vector<std::string> history_rows(const fs::path& file) {
  std::ifstream in(file);
  std::vector<std::string> rows;
  for (std::string line; std::getline(in, line);) {
    std::stringstream ls(line);
    std::string row, cell;
    for (std::size_t k = 0; std::getline(ls, cell, ','); ++k)
      if (k != 4 && k != 11) row += cell + ",";
    rows.push_back(row);
  }
  REQUIRE(rows.size() > 1);
  REQUIRE(rows[0] == "step,time_s,kinetic_J,strain_J,broken_bonds,damage_fraction,fragments,tip_x_m,tip_y_m,tip_speed_m_s,linear_"
                     "iterations,sub_iterations,");
  return rows;
}

// Entries that differ (a count, so that a failure does not print arrays of 10^5 values).
template <class T>
std::size_t differing(const std::vector<T>& a, const std::vector<T>& b) {
  REQUIRE(a.size() == b.size());
  std::size_t n = 0;
  for (std::size_t i = 0; i < a.size(); ++i) n += a[i] != b[i];
  return n;
}

void require_equal_checkpoints(const Checkpoint& a, const Checkpoint& b) {
  REQUIRE(a.step == b.step);
  CHECK(a.time == b.time);
  CHECK(a.points == b.points);
  for (int k = 0; k < 3; ++k) {
    INFO("component " << k);
    CHECK(differing(a.u[k], b.u[k]) == 0);
    CHECK(differing(a.v[k], b.v[k]) == 0);
    CHECK(differing(a.f[k], b.f[k]) == 0);
  }
  CHECK(differing(a.bond_state, b.bond_state) == 0);
  CHECK(a.broken == b.broken);
  CHECK(std::abs(a.external_work - b.external_work) <= 1e-12 * std::abs(b.external_work));
}

std::string bytes_of(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace

TEST_CASE("mpirun -np 2 and 4 runs of the glass branching deck equal the one-rank run bitwise") {
  // The shipped deck to t = 9 us (the crack has started to run), every observer on:
  // VTU and PNG at the last step, CSV, fragments, crack tips, and a checkpoint at the end. The
  // pre-crack and the running crack lie on y = 0.02 m, the border between the two slabs of
  // -np 2, so bonds break across ranks.
  auto text = deck_text::replaced(file_text(decks / "crack_branching_2d.yaml"), "end_time: 46.0e-6", "end_time: 9.0e-6");
  text = deck_text::replaced(text, "dds: {every: 20, snapshot_every: 100}", "checkpoint: {every: 1000, file: end.h5}");
  const fs::path deck = temp("glass.yaml");
  std::ofstream(deck) << text;
  const fs::path one = run(PERIDOT_EXE, deck, "one", "--threads 2");
  const auto serial = peridot::read_checkpoint(one / "end.h5");
  // The run ends at end_time: ceil(end_time / dt) steps (choose_time_step), dt = time / step of
  // the history's second row (every 40 steps).
  const auto history = csv_columns::read(one / "crack_branching_2d_history.csv");
  REQUIRE(history.at("step").size() >= 2);
  const double dt = history.at("time_s")[1] / history.at("step")[1];
  INFO("dt = " << dt << " s");
  const double x = 9.0e-6 / dt;  // a whole number of steps up to 1e-6 of it is taken as such
  REQUIRE(serial.step == std::size_t(std::abs(x - std::round(x)) < 1e-6 * x ? std::round(x) : std::ceil(x)));
  REQUIRE(serial.time >= 9.0e-6 * (1 - 1e-9));  // reaches end_time, within one step
  REQUIRE(serial.time - dt < 9.0e-6);
  REQUIRE(serial.broken > 200);
  const std::string digits = std::to_string(serial.step);
  const std::string last = "crack_branching_2d_" + std::string(7 - std::min<std::size_t>(7, digits.size()), '0') + digits;
  const auto serial_vtu = peridot::read_vtu(one / (last + ".vtu"));
  for (int ranks : {2, 4}) {
    INFO(ranks << " ranks");
    const fs::path out = run(mpirun(ranks), deck, "np" + std::to_string(ranks), "--threads 1");
    require_equal_checkpoints(peridot::read_checkpoint(out / "end.h5"), serial);
    CHECK(differing(history_rows(out / "crack_branching_2d_history.csv"), history_rows(one / "crack_branching_2d_history.csv")) == 0);
    CHECK((bytes_of(out / (last + ".png")) == bytes_of(one / (last + ".png"))));
    // The VTU: one piece per rank, listed by a .pvtu that the .pvd names.
    CHECK_THAT(file_text(out / "crack_branching_2d.pvd"), Catch::Contains(last + ".pvtu"));
    CHECK(fs::exists(out / (last + "_" + std::to_string(ranks - 1) + ".vtu")));
    const auto pieces = peridot::read_vtu(out / (last + ".pvtu"));
    const auto* id = pieces.find("global_id");
    REQUIRE(id);
    REQUIRE(id->values.size() == serial.points);
    for (const std::string field : {"displacement", "damage"}) {
      const auto* a = pieces.find(field);
      const auto* b = serial_vtu.find(field);
      REQUIRE(a);
      REQUIRE(b);
      const std::size_t c = std::size_t(a->components);
      std::size_t differ = 0;
      for (std::size_t i = 0; i < id->values.size(); ++i)
        for (std::size_t k = 0; k < c; ++k) differ += a->values[i * c + k] != b->values[std::size_t(id->values[i]) * c + k];
      INFO(field);
      CHECK(differ == 0);
    }
  }
}

namespace {

// Runs `deck` (output name `name`, with a checkpoint end.h5 at its last step) on one rank and on
// 2 and 4 ranks: checkpoints (u, v, f, every bond's state), CSV histories and PNGs must be equal.
// (1D decks draw no PNG: `pictures` false.)
void require_rank_independent(const fs::path& deck, const std::string& name, std::size_t least_broken, bool pictures = true) {
  const fs::path one = run(PERIDOT_EXE, deck, name + "_one", "--threads 2");
  const auto serial = peridot::read_checkpoint(one / "end.h5");
  REQUIRE(serial.broken >= least_broken);
  for (int ranks : {2, 4}) {
    INFO(ranks << " ranks");
    const fs::path out = run(mpirun(ranks), deck, name + "_np" + std::to_string(ranks), "--threads 1");
    require_equal_checkpoints(peridot::read_checkpoint(out / "end.h5"), serial);
    CHECK(differing(history_rows(out / (name + "_history.csv")), history_rows(one / (name + "_history.csv"))) == 0);
    std::size_t pngs = 0;
    for (const auto& png : fs::directory_iterator(one))
      if (png.path().extension() == ".png") {
        INFO(png.path().filename());
        CHECK((bytes_of(out / png.path().filename()) == bytes_of(png.path())));
        ++pngs;
      }
    CHECK((pngs > 0) == pictures);
  }
}

// A shipped deck with its end time, and the outputs, replaced (`edits`: pairs of old, new).
fs::path edited(const std::string& deck, const std::vector<std::pair<std::string, std::string>>& edits, const std::string& name) {
  auto text = file_text(decks / deck);
  for (const auto& [from, to] : edits) text = deck_text::replaced(text, from, to);
  const fs::path out = temp(name + ".yaml");
  std::ofstream(out) << text;
  return out;
}

}  // namespace

TEST_CASE("mpirun -np 2 and 4 runs of a meshed RNP plate, cut by coordinate bisection, equal the one-rank run bitwise") {
  // The nodal-FE pre-cracked plate with a hole (a Gmsh mesh, element-ball bonds, RNP, central
  // differences), pulled 20 times faster than the shipped deck so that the crack starts from
  // the pre-crack within 30 us (1000 steps) and runs across the cuts.
  const auto deck = edited("fe/hole_precrack_coarse.yaml",
                           {{"end_time: 600.0e-6", "end_time: 30.0e-6"},
                            {"value: [0, -0.025]", "value: [0, -0.5]"},
                            {"value: [0, 0.025]", "value: [0, 0.5]"},
                            {"png: {every: 2500, field: damage}", "png: {every: 500, field: damage}\n  vtu: {every: 1000}\n  checkpoint: {every: 100000, file: end.h5}"},
                            {"file: hole_precrack.geo", "file: " + (decks / "fe/hole_precrack.geo").string()}},
                           "fe");
  // RNP here breaks no bond (break_factor 0): the crack is where Z = max|S|/S_c >= 1, and its
  // tip, followed from the pre-crack tip at x = 10 mm, must have moved on.
  require_rank_independent(deck, "fe_hole_precrack_coarse", 0);
  const auto rows = history_rows(temp("fe_hole_precrack_coarse_one") / "fe_hole_precrack_coarse_history.csv");
  std::stringstream last(rows.back());
  std::string cell;
  for (int k = 0; k < 8; ++k) std::getline(last, cell, ',');  // tip_x_m, the 8th kept cell
  CHECK(std::stod(cell) > 0.012);
}

TEST_CASE("mpirun -np 2 and 4 runs of the OSB, LPS and 1D RNP explicit decks equal the one-rank run bitwise") {
  SECTION("OSB: the explicit plate, stress output on") {
    const auto deck = edited("osb/explicit_plate.yaml", {{"png: {every: 400, field: stress_xx}", "png: {every: 400, field: stress_xx}\n  checkpoint: {every: 100000, file: end.h5}"}}, "osb");
    require_rank_independent(deck, "osb_explicit_plate", 0);
  }
  SECTION("LPS: the explicit glass plate, cracking from its pre-crack") {
    const auto deck = edited("lps_dynamic/glass_plate_explicit.yaml",
                             {{"end_time: 42.0e-6", "end_time: 21.0e-6"},
                              {"png: {every: 672, width: 1200, field: damage}", "png: {every: 336, width: 600, field: damage}\n  checkpoint: {every: 100000, file: end.h5}"}},
                             "lps");
    require_rank_independent(deck, "glass_plate_explicit", 20);
  }
  SECTION("RNP: the 1D bar hit by a velocity pulse") {
    const auto deck = edited("rnp/bar_1d_explicit.yaml", {{"csv: {every: 100}", "csv: {every: 100}\n  checkpoint: {every: 100000, file: end.h5}"}}, "bar");
    require_rank_independent(deck, "rnp_bar_1d_explicit", 0, false);
  }
}

TEST_CASE("a checkpoint written on 2 ranks continues on 4 ranks and on one, bitwise as the uninterrupted run") {
  // 4000 points, 300 steps of a fixed dt, bonds breaking from about step 30.
  const fs::path plate = fs::path(PERIDOT_SOURCE_DIR) / "tests/apps/decks/restart_plate_2d.yaml";
  const fs::path whole = run(PERIDOT_EXE, plate, "plate_one", "--threads 1");
  const auto end = peridot::read_checkpoint(whole / "plate.h5");
  REQUIRE(end.step == 300);
  // Stopped at step 150 on 2 ranks (only solver.end_time differs, which a restart allows).
  const fs::path half = temp("plate_half.yaml");
  std::ofstream(half) << deck_text::replaced(file_text(plate), "end_time: 30.0e-6", "end_time: 15.0e-6");
  const fs::path stopped = run(mpirun(2), half, "plate_np2", "--threads 1");
  const auto mid = peridot::read_checkpoint(stopped / "plate.h5");
  REQUIRE(mid.step == 150);
  REQUIRE(mid.broken > 100);
  for (const std::string launcher : {mpirun(4), std::string(PERIDOT_EXE)}) {
    INFO(launcher);
    const fs::path out = temp("plate_continued");
    fs::remove_all(out);
    fs::create_directories(out);
    fs::copy_file(stopped / "plate.h5", out / "start.h5");
    const auto r = cli_run::run(launcher, temp("continued.err"),
                                "run " + plate.string() + " --out " + out.string() + " --threads 1 --restart " + (out / "start.h5").string());
    INFO(r.err);
    REQUIRE(r.code == 0);
    require_equal_checkpoints(peridot::read_checkpoint(out / "plate.h5"), end);
  }
}

TEST_CASE("an LPS checkpoint written on 2 ranks, mid-fracture, continues on 4 ranks bitwise as the uninterrupted one-rank run") {
  // The restarted ranks take the masks of the ghost rows they hold from their owners, and LPS
  // rebuilds its shape tensors from the restored masks. About 500 bonds are broken at step 168.
  const std::string outputs = "png: {every: 672, width: 1200, field: damage}";
  const std::string checkpoint = "png: {every: 336, width: 600, field: damage}\n  checkpoint: {every: 100000, file: end.h5}";
  const auto full = edited("lps_dynamic/glass_plate_explicit.yaml", {{"end_time: 42.0e-6", "end_time: 21.0e-6"}, {outputs, checkpoint}}, "lps_full");
  const auto half = edited("lps_dynamic/glass_plate_explicit.yaml", {{"end_time: 42.0e-6", "end_time: 10.5e-6"}, {outputs, checkpoint}}, "lps_half");
  const auto end = peridot::read_checkpoint(run(PERIDOT_EXE, full, "lps_full_one", "--threads 2") / "end.h5");
  REQUIRE(end.step == 336);
  const fs::path stopped = run(mpirun(2), half, "lps_half_np2", "--threads 1");
  const auto mid = peridot::read_checkpoint(stopped / "end.h5");
  REQUIRE(mid.step == 168);
  REQUIRE(mid.broken > 100);
  const fs::path out = temp("lps_continued");
  fs::remove_all(out);
  fs::create_directories(out);
  fs::copy_file(stopped / "end.h5", out / "start.h5");
  const auto r = cli_run::run(mpirun(4), temp("lps_continued.err"),
                              "run " + full.string() + " --out " + out.string() + " --threads 1 --restart " + (out / "start.h5").string());
  INFO(r.err);
  REQUIRE(r.code == 0);
  require_equal_checkpoints(peridot::read_checkpoint(out / "end.h5"), end);
}

TEST_CASE("decks that cannot run distributed yet are refused under mpirun, writing nothing") {
  // Implicit Newmark (LPS) and quasi-static Newton (RNP): their solves are not on PETSc.
  for (const std::string deck : {"lps_dynamic/cylinder.yaml", "rnp/precracked_soft.yaml"}) {
    INFO(deck);
    const fs::path out = temp("refused");
    fs::remove_all(out);
    const auto r = cli_run::run(mpirun(2), temp("refused.err"), "run " + (decks / deck).string() + " --out " + out.string());
    CHECK(r.code == 2);
    CHECK_THAT(r.err, Catch::Contains("cannot run on 2 MPI ranks yet"));
    CHECK_FALSE(fs::exists(out));
  }
}
