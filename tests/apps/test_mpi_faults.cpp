// A failure on one rank ends every rank, at any phase of a distributed run: mpirun -np 2 with a
// failure injected on rank 1 (PERIDOT_INJECT_FAILURE=<phase>@1, a test-only switch) must exit 1
// within 10 s, naming the rank and the phase, instead of leaving rank 0 waiting in a collective.
// Every mpirun is bounded by `timeout -k` (a hang is killed at 60 s and fails the test), stays
// on loopback (shared memory between ranks, the launcher's channel on lo) and is reaped.
#include <catch2/catch.hpp>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>
#include "../support/cli_run.hpp"
#include "../support/mpirun.hpp"

namespace fs = std::filesystem;

namespace {

fs::path temp(const std::string& name) { return cli_run::temp("peridot_mpi_faults_", name); }

// A small PMB plate: on the lattice stencil (slabs), or on a bond list (coordinate bisection).
// 50 x 20 points, a checkpoint every 5 steps for the restart phases.
fs::path plate_deck(bool list) {
  const fs::path file = temp(list ? "list.yaml" : "stencil.yaml");
  std::ofstream(file) << "name: faults\n"
                         "dimension: 2\n"
                         "geometry: {body: {rectangle: {min: [0, 0], max: [0.01, 0.004]}}}\n"
                         "discretization: {spacing: 2.0e-4, horizon_factor: 3"
                      << (list ? ", bonds: list" : "")
                      << "}\n"
                         "material: {model: pmb, kinematics: plane_stress, youngs_modulus: 72.0e9, density: 2440.0, "
                         "fracture_energy: 3.8}\n"
                         "boundaries:\n"
                         "  - {name: top, type: traction, region: {layer: {side: +y, count: 1}}, value: [0.0, 1.0e6]}\n"
                         "solver: {type: explicit, end_time: 2.0e-7}\n"
                         "output: {csv: {every: 5}, checkpoint: {every: 5}}\n";
  return file;
}

struct Outcome {
  int code;
  std::string err;
  double seconds;
};

Outcome run_failing(const std::string& phase, const fs::path& deck, const std::string& extra = "") {
  const fs::path out = temp("out");
  const auto t0 = std::chrono::steady_clock::now();
  // mpirun hands the variable to every rank (-x); only rank 1 matches it.
  std::string launcher = mpirun(2);
  launcher.replace(launcher.find(" -np "), 5, " -x PERIDOT_INJECT_FAILURE -np ");
  const auto r = cli_run::run("env PERIDOT_INJECT_FAILURE='" + phase + "@1' " + launcher, temp("err"),
                              "run " + deck.string() + " --quiet --threads 1 --out " + out.string() + " " + extra);
  return {r.code, r.err, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()};
}

void require_ended(const Outcome& o, const std::string& phase) {
  INFO("phase " << phase << ", " << o.seconds << " s, stderr:\n" << o.err);
  CHECK(o.code == 1);  // not 124: timeout's code for a hang
  CHECK(o.err.find("injected failure") != std::string::npos);
  CHECK(o.err.find("rank 1, " + phase) != std::string::npos);
  CHECK(o.seconds < 10);
}

}  // namespace

TEST_CASE("a rank that fails in any phase before or during the steps ends both ranks with exit 1, naming rank and phase") {
  for (const bool list : {false, true}) {
    const auto deck = plate_deck(list);
    for (const std::string phase :
         {"set-up", "allocation", "halo set-up", "initial forces", "observers and output directory", "stepping"}) {
      INFO((list ? "bond list" : "stencil") << ", phase " << phase);
      require_ended(run_failing(phase, deck), phase);
    }
  }
}

// Since wave 3 a one-file checkpoint restarts as one in parts does: each rank reads its own
// points ("restart") and then its ghosts' ("restart halo"); nothing is scattered from rank 0.
TEST_CASE("a rank that fails while a restart is read or its ghosts are refreshed ends both ranks with exit 1") {
  const auto deck = plate_deck(false);
  const fs::path out = temp("first");
  fs::remove_all(out);
  const auto first = cli_run::run(PERIDOT_EXE, temp("first.err"), "run " + deck.string() + " --quiet --out " + out.string());
  INFO(first.err);
  REQUIRE(first.code == 0);
  const std::string restart = "--restart " + (out / "faults.h5").string();
  for (const std::string phase : {"restart", "restart halo"}) require_ended(run_failing(phase, deck, restart), phase);
  // Without an injected failure the same restart runs to the end on 2 ranks.
  const auto ok = cli_run::run(mpirun(2), temp("ok.err"), "run " + deck.string() + " --quiet --threads 1 --out " + temp("ok").string() + " " + restart);
  INFO(ok.err);
  CHECK(ok.code == 0);
}

TEST_CASE("a rank that fails in a static solve on PETSc ends both ranks with exit 1") {
  const auto deck = fs::path(PERIDOT_SOURCE_DIR) / "data/decks/lps/sine_top_traction.yaml";
  require_ended(run_failing("static solve", deck), "static solve");
}

TEST_CASE("a stop that rank 1 alone asks for after step 3 ends both ranks after that step: exit 143, the CSV's last row and the checkpoint at step 3") {
  const fs::path deck = plate_deck(true), out = temp("stop_out");
  fs::remove_all(out);
  std::string launcher = mpirun(2);
  launcher.replace(launcher.find(" -np "), 5, " -x PERIDOT_INJECT_STOP -np ");
  // PERIDOT_INJECT_STOP (test-only) makes rank 1 request a stop as its own SIGTERM would.
  const auto r = cli_run::run("env PERIDOT_INJECT_STOP='3@1' " + launcher, temp("err"),
                              "run " + deck.string() + " --quiet --threads 1 --out " + out.string());
  INFO("stderr:\n" << r.err);
  CHECK(r.code == 128 + 15);  // both ranks: 128 + SIGTERM, agreed over the ranks
  std::ifstream csv(out / "faults_history.csv");
  std::string header, line, last;
  std::getline(csv, header);
  const auto fields = std::count(header.begin(), header.end(), ',');
  while (std::getline(csv, line)) {
    CHECK(std::count(line.begin(), line.end(), ',') == fields);
    last = line;
  }
  REQUIRE(!last.empty());
  CHECK(last.substr(0, last.find(',')) == "3");  // rows every 5 steps, and the stop's own: step 3
  CHECK(fs::exists(out / "faults.h5"));
  fs::remove_all(out);
}
