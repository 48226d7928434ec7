#include <catch2/catch.hpp>
#include <unistd.h>

#include <array>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "../live/child_process.hpp"
#include "../support/mpirun.hpp"

namespace fs = std::filesystem;
using namespace std::chrono_literals;

// The README's example: a user observer added to a library run prints its own lines, on its own
// cadence, and hears how the run ended.
TEST_CASE("the example program runs a deck through the library and its own observer reports every 20 steps and the end") {
  // The shipped explicit 1D RNP bar (a few hundred steps), its output in a directory of this process's own.
  std::ifstream in(std::string(PERIDOT_SOURCE_DIR) + "/data/decks/rnp/bar_1d_explicit.yaml");
  REQUIRE(in.good());
  std::stringstream text;
  text << in.rdbuf();
  const fs::path dir = fs::temp_directory_path() / ("peridot_example_" + std::to_string(getpid()));
  fs::create_directories(dir);
  std::string deck = text.str();
  deck += "\n";
  std::ofstream(dir / "bar.yaml") << deck;
  const fs::path cwd = fs::current_path();
  fs::current_path(dir);  // the deck's output directory is relative
  ChildProcess example({PERIDOT_EXAMPLE_EXE, (dir / "bar.yaml").string(), "20"}, {});
  const auto r = example.wait(60s);
  fs::current_path(cwd);
  INFO("stdout: " << r.out.substr(0, 2000) << "\nstderr: " << r.err);
  REQUIRE(r.exit_code == 0);
  // One line per 20 steps from step 0, and one at the last step; then the finish line.
  std::istringstream lines(r.out);
  std::string line, finish;
  std::vector<long> steps;
  while (std::getline(lines, line)) {
    if (line.rfind("step", 0) == 0) steps.push_back(std::stol(line.substr(4)));
    else if (line.rfind("finished after", 0) == 0) finish = line;
  }
  REQUIRE(steps.size() >= 3);
  for (std::size_t k = 0; k + 1 < steps.size(); ++k) CHECK(steps[k] == long(20 * k));
  const long last_step = steps.back();
  CHECK(last_step > steps[steps.size() - 2]);
  CHECK(finish == "finished after " + std::to_string(last_step) + " steps");
  fs::remove_all(dir);
}

namespace {

// The example program's stdout on `deck`, one line per `every` steps, run in a directory of
// this process's own; under mpirun on `ranks` ranks when ranks > 1 (bounded by timeout -k,
// shared memory between ranks, the launcher's channel on lo). whole: its observer reads the
// whole body on rank 0 (Sample) instead of its part on every rank (PartSample).
std::string example_lines(const std::string& deck, int ranks, const std::string& every, bool whole = false, const std::string& steps = "") {
  const fs::path dir = fs::temp_directory_path() / ("peridot_example_np" + std::to_string(ranks) + (whole ? "w_" : "_") + std::to_string(getpid()));
  fs::create_directories(dir);
  const fs::path cwd = fs::current_path();
  fs::current_path(dir);  // the decks' output directories are relative
  const std::string file = std::string(PERIDOT_SOURCE_DIR) + "/data/decks/" + deck;
  std::vector<std::string> argv{PERIDOT_EXAMPLE_EXE, file, every};
  if (whole) argv.push_back("--whole");
  if (!steps.empty()) argv.insert(argv.end(), {"--steps", steps});
  if (ranks > 1) {
    const auto launcher = mpirun_argv(ranks);
    argv.insert(argv.begin(), launcher.begin(), launcher.end());
  }
  ChildProcess example(argv, {"OMPI_ALLOW_RUN_AS_ROOT=1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1"});
  const auto r = example.wait(150s);
  fs::current_path(cwd);
  fs::remove_all(dir);
  INFO(deck << " on " << ranks << (whole ? " ranks, whole body" : " ranks, parts") << "; stderr: " << r.err.substr(0, 2000));
  REQUIRE(r.exit_code == 0);
  return r.out;
}

}  // namespace

// A library program started by mpirun runs its deck once, on the ranks (Simulation starts MPI),
// not once per rank. Its observer reads its part on every rank and reduces the largest |u|
// over the ranks (PartSample: no rank gathers the body), or with --whole reads the whole body
// on rank 0, gathered from the ranks' parts (explicit and quasi-static runs) or from their owned
// points (static LPS and static OSB, whose own observers hold no point). Both print one
// process's lines, on every flavour that cuts its body.
// A mesh deck (a structured mesh, made by rank 0 and sent in shares) gives rank 0's whole-body
// observer positions gathered from the ranks: no rank keeps the mesh past the set-up.
TEST_CASE("the example program's part and whole-body observers print one process's lines once under mpirun -np 2, for explicit, "
          "quasi-static, static LPS, static OSB and mesh decks") {
  for (const auto& [deck, every, steps] : std::vector<std::array<std::string, 3>>{{"osb/explicit_plate.yaml", "50", ""},
                                                                                   {"rnp/plate_2d.yaml", "1", ""},
                                                                                   {"lps/sine_top_traction.yaml", "1", ""},
                                                                                   {"osb/traction.yaml", "1", ""},
                                                                                   {"fe/mode_i.yaml", "10", "40"}}) {
    INFO(deck);
    const auto one = example_lines(deck, 1, every, false, steps);
    REQUIRE(one.find("max |u| = 0.000000e+00") != std::string::npos);  // step 0
    const auto last = one.rfind("step");
    REQUIRE(last != std::string::npos);
    REQUIRE(one.substr(last).find("max |u| = 0.000000e+00") == std::string::npos);
    CHECK(example_lines(deck, 1, every, true, steps) == one);
    CHECK(example_lines(deck, 2, every, false, steps) == one);
    CHECK(example_lines(deck, 2, every, true, steps) == one);
  }
}
