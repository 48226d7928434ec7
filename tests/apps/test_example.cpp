#include <catch2/catch.hpp>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "../live/child_process.hpp"

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
