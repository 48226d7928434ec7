#include <catch2/catch.hpp>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace fs = std::filesystem;

namespace {

struct Result {
  int code;
  std::string err;
};

// Runs the peridot CLI with a time bound; stderr is captured.
Result peridot(const std::string& args) {
  const fs::path err = fs::temp_directory_path() / "peridot_cli_stderr.txt";
  const std::string cmd = "timeout 120 " + std::string(PERIDOT_EXE) + " " + args + " > /dev/null 2> " + err.string();
  const int status = std::system(cmd.c_str());
  std::ifstream in(err);
  std::stringstream ss;
  ss << in.rdbuf();
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, ss.str()};
}

fs::path deck_with(const std::string& name, const std::string& from, const std::string& to) {
  std::ifstream in(std::string(PERIDOT_SOURCE_DIR) + "/data/decks/crack_branching_2d.yaml");
  std::stringstream ss;
  ss << in.rdbuf();
  std::string s = ss.str();
  const auto p = s.find(from);
  REQUIRE(p != std::string::npos);
  s.replace(p, from.size(), to);
  const fs::path file = fs::temp_directory_path() / ("peridot_cli_" + name + ".yaml");
  std::ofstream(file) << s;
  return file;
}

void require_rejected(const fs::path& deck, const std::string& message) {
  const fs::path out = fs::temp_directory_path() / "peridot_cli_out";
  fs::remove_all(out);
  const auto r = peridot("run " + deck.string() + " --out " + out.string());
  INFO(r.err);
  CHECK(r.code == 2);
  CHECK(r.err.find(message) != std::string::npos);
  CHECK_FALSE(fs::exists(out));  // nothing written, not even the directory
  CHECK(peridot("check " + deck.string()).code == 2);
}

}  // namespace

TEST_CASE("the CLI rejects bad decks with a clear message, exit code 2 and no output files") {
  require_rejected(deck_with("malformed", "dimension: 2", "dimension: [2"), "malformed YAML");
  require_rejected(deck_with("unknown", "density: 2440.0", "density: 2440.0\n  poisson: 0.2"), "unknown key 'poisson'");
  require_rejected(deck_with("negative_horizon", "horizon_factor: 4", "horizon: -1.0e-3"), "discretization.horizon = -1.0e-3");
  require_rejected(deck_with("zero_horizon", "horizon_factor: 4", "horizon: 0"), "discretization.horizon = 0");
  require_rejected(deck_with("coarse", "horizon_factor: 4", "horizon: 1.0e-4"), "must be >= spacing");
  require_rejected(deck_with("empty", "rectangle: {min: [0.0, 0.0], max: [0.1, 0.04]}",
                             "difference: [{rectangle: {min: [0.0, 0.0], max: [0.1, 0.04]}}, {rectangle: {min: [-1, -1], max: [1, 1]}}]"),
                   "no lattice points");
  require_rejected(deck_with("nan", "youngs_modulus: 72.0e9", "youngs_modulus: .nan"), "material.youngs_modulus");
  require_rejected(fs::temp_directory_path() / "peridot_no_such_deck.yaml", "cannot open deck file");
}

TEST_CASE("the CLI reports usage errors with exit code 2") {
  CHECK(peridot("").code == 2);
  CHECK(peridot("run --threads -3").code == 2);
  CHECK(peridot("frobnicate").code == 2);
}

TEST_CASE("the CLI runs a small deck to completion with VTU, PVD and CSV output") {
  const auto deck = deck_with("small", "spacing: 1.25e-4", "spacing: 1.0e-3");
  const fs::path out = fs::temp_directory_path() / "peridot_cli_small";
  fs::remove_all(out);
  const auto r = peridot("run " + deck.string() + " --out " + out.string() + " --threads 1");
  INFO(r.err);
  REQUIRE(r.code == 0);
  CHECK(fs::exists(out / "crack_branching_2d.pvd"));
  CHECK(fs::exists(out / "crack_branching_2d_history.csv"));
  std::size_t vtu = 0;
  for (const auto& e : fs::directory_iterator(out)) {
    vtu += e.path().extension() == ".vtu";
    CHECK(e.path().extension() != ".tmp");
  }
  CHECK(vtu >= 2);
  fs::remove_all(out);
}
