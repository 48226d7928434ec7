// Two-process DDS tests: fake_run publishes, peridot-watch listens in another
// process. Every process is bounded in time and reaped (ChildProcess).
#include <catch2/catch.hpp>
#include <unistd.h>

#include <chrono>
#include <cstddef>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>
#include <fmt/core.h>

#include "child_process.hpp"

namespace {

using namespace std::chrono_literals;

// Every process sees only the loopback config, whatever the environment says.
const std::vector<std::string> loopback_env = {
    fmt::format("CYCLONEDDS_URI=file://{}/data/dds/loopback.xml", PERIDOT_SOURCE_DIR)};

// Unique per process, so concurrent test runs do not follow each other's runs.
std::string unique_run_id(const char* what) { return fmt::format("test-{}-{}", what, getpid()); }

// A DDS partition per test process as well: fake_run starts publishing once *a*
// watcher is matched, and that must be its own; and the test that must find no
// publisher at all sees none of another test's. Pids are unique among live processes.
std::string own_partition() { return fmt::format("peridot-test-{}", getpid()); }

// The step and status of every summary line the watcher printed.
struct WatchLines {
  std::vector<std::size_t> steps;
  std::vector<std::string> statuses;
};

WatchLines parse_watch_output(const std::string& out) {
  WatchLines w;
  std::istringstream in(out);
  for (std::string line; std::getline(in, line);) {
    std::istringstream words(line);
    std::string first, word, status;
    std::size_t step = 0;
    if (!(words >> first >> step) || first != "step") continue;
    while (words >> word && word != "m/s") {
    }
    words >> status;  // the word after the tip speed's unit, then ": message" if any
    w.steps.push_back(step);
    w.statuses.push_back(status.substr(0, status.find(':')));
  }
  return w;
}

struct RunAndWatch {
  ChildResult watch, run;
};

// Starts the watcher, then the fake run, and waits for both (60 s in all).
RunAndWatch run_and_watch(const std::string& run_id, int summaries, std::vector<std::string> run_extra,
                          std::vector<std::string> watch_extra) {
  std::vector<std::string> watch_argv = {PERIDOT_WATCH_EXE, "--run-id", run_id, "--timeout", "30",
                                         "--partition", own_partition()};
  watch_argv.insert(watch_argv.end(), watch_extra.begin(), watch_extra.end());
  std::vector<std::string> run_argv = {FAKE_RUN_EXE, "--run-id", run_id, "--summaries", std::to_string(summaries),
                                       "--partition", own_partition()};
  run_argv.insert(run_argv.end(), run_extra.begin(), run_extra.end());
  ChildProcess watch(watch_argv, loopback_env);
  ChildProcess run(run_argv, loopback_env);
  const auto start = std::chrono::steady_clock::now();
  RunAndWatch r;
  r.watch = watch.wait(60s);
  r.run = run.wait(std::max(1000ms, 60000ms - std::chrono::duration_cast<std::chrono::milliseconds>(
                                                  std::chrono::steady_clock::now() - start)));
  INFO("watch stdout:\n" << r.watch.out << "\nwatch stderr:\n" << r.watch.err << "\nrun stdout:\n" << r.run.out
                         << "\nrun stderr:\n" << r.run.err);
  REQUIRE_FALSE(r.watch.timed_out);
  REQUIRE_FALSE(r.run.timed_out);
  REQUIRE(r.run.exit_code == 0);
  return r;
}

}  // namespace

TEST_CASE("peridot-watch in another process receives every summary of a run in step order and exits 0 when it finishes") {
  const int summaries = 12;
  const auto png = std::filesystem::temp_directory_path() / fmt::format("peridot-watch-{}.png", getpid());
  std::filesystem::remove(png);
  std::vector<std::string> watch_extra;
  if (PERIDOT_WATCH_HAS_PNG) watch_extra = {"--png", png.string()};
  const auto r = run_and_watch(unique_run_id("finish"), summaries, {}, watch_extra);
  INFO("watch stdout:\n" << r.watch.out << "\nwatch stderr:\n" << r.watch.err);
  CHECK(r.watch.exit_code == 0);
  const auto lines = parse_watch_output(r.watch.out);
  // Every running summary, in order, then the final one repeating the last step.
  REQUIRE(lines.steps.size() == std::size_t(summaries) + 1);
  for (int k = 0; k < summaries; ++k) {
    CHECK(lines.steps[std::size_t(k)] == std::size_t(10 * (k + 1)));
    CHECK(lines.statuses[std::size_t(k)] == "running");
  }
  CHECK(lines.steps.back() == std::size_t(10 * summaries));
  CHECK(lines.statuses.back() == "finished");

  if (PERIDOT_WATCH_HAS_PNG) {
    std::ifstream in(png, std::ios::binary);
    REQUIRE(in.good());
    std::string magic(8, '\0');
    in.read(magic.data(), 8);
    CHECK(magic == "\x89PNG\r\n\x1a\n");
    in.close();
    std::filesystem::remove(png);
  }
}

TEST_CASE("peridot-watch exits 3 and prints the message when the run reports failure") {
  const auto r = run_and_watch(unique_run_id("fail"), 3, {"--fail"}, {});
  INFO("watch stdout:\n" << r.watch.out << "\nwatch stderr:\n" << r.watch.err);
  CHECK(r.watch.exit_code == 3);
  const auto lines = parse_watch_output(r.watch.out);
  REQUIRE_FALSE(lines.statuses.empty());
  CHECK(lines.statuses.back() == "failed");
  CHECK(r.watch.out.find("fake failure") != std::string::npos);
}

TEST_CASE("peridot-watch with no publisher gives up after --timeout with a clear message and exit code 4") {
  ChildProcess watch(
      {PERIDOT_WATCH_EXE, "--run-id", unique_run_id("none"), "--timeout", "2", "--partition", own_partition()},
      loopback_env);
  const auto r = watch.wait(30s);
  INFO("stdout:\n" << r.out << "\nstderr:\n" << r.err);
  REQUIRE_FALSE(r.timed_out);
  CHECK(r.exit_code == 4);
  CHECK(r.err.find("no publisher for run '" + unique_run_id("none") + "'") != std::string::npos);
  CHECK(r.err.find("within 2 s") != std::string::npos);
  CHECK(r.out.empty());
}

TEST_CASE("peridot-watch rejects an out-of-range option with exit code 2, as peridot does, before touching DDS") {
  ChildProcess watch({PERIDOT_WATCH_EXE, "--timeout", "-5"}, loopback_env);
  const auto r = watch.wait(30s);
  REQUIRE_FALSE(r.timed_out);
  CHECK(r.exit_code == 2);
  CHECK(r.err.find("--timeout") != std::string::npos);
}
