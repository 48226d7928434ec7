#include <catch2/catch.hpp>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <csignal>

#include "../live/child_process.hpp"
import peridot.io;

namespace fs = std::filesystem;
using namespace std::chrono_literals;

namespace {

struct Row {
  double time = 0, kinetic = 0, strain = 0, work = 0, damage = 0;
  long broken = 0, fragments = 0;
};

// A short glass run publishing every 10 steps; the deck is the shipped one, coarsened.
// end_time: the run's length; checkpoint: an output.checkpoint cadence (0: none).
fs::path small_deck(const std::string& end_time = "30.0e-6", int checkpoint = 0) {
  std::ifstream in(std::string(PERIDOT_SOURCE_DIR) + "/data/decks/crack_branching_2d.yaml");
  std::stringstream ss;
  ss << in.rdbuf();
  std::string s = ss.str();
  const auto cut = s.find("output:");
  s = s.substr(0, cut);
  for (auto [from, to] : {std::pair<std::string, std::string>{"spacing: 1.25e-4", "spacing: 1.0e-3"},
                          {"end_time: 46.0e-6", "end_time: " + end_time}}) {
    const auto p = s.find(from);
    REQUIRE(p != std::string::npos);
    s.replace(p, from.size(), to);
  }
  s += "output:\n  csv: {every: 10}\n  dds: {every: 10, snapshot_every: 50}\n  fragments: {every: 10}\n";
  if (checkpoint) s += "  checkpoint: {every: " + std::to_string(checkpoint) + "}\n";
  const fs::path file = fs::temp_directory_path() / ("peridot_live_run_" + std::to_string(getpid()) + ".yaml");
  std::ofstream(file) << s;
  return file;
}

std::vector<std::string> env() { return {"CYCLONEDDS_URI=file://" + std::string(PERIDOT_SOURCE_DIR) + "/data/dds/loopback.xml"}; }
// A DDS partition of this test process's own: no other test's run or watcher is seen.
std::string partition() { return "peridot-live-run-" + std::to_string(getpid()); }

// The watcher's summary lines by step.
std::map<long, Row> parse_watch(const std::string& out) {
  std::map<long, Row> rows;
  std::istringstream in(out);
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("step", 0) != 0) continue;
    std::istringstream l(line);
    std::string w, unit;
    long step;
    Row r;
    std::string frag;
    l >> w >> step >> w >> r.time >> unit >> w >> w >> unit >> w >> r.kinetic >> unit >> w >> r.strain >> unit >> w >> r.work >> unit >>
        w >> r.broken >> w >> r.damage >> w >> frag;
    r.fragments = frag == "-" ? -1 : std::stol(frag);
    rows[step] = r;  // the final sample repeats the last step
  }
  return rows;
}

std::map<long, Row> parse_csv(const fs::path& file) {
  std::map<long, Row> rows;
  std::ifstream in(file);
  std::string line;
  std::getline(in, line);
  while (std::getline(in, line)) {
    std::replace(line.begin(), line.end(), ',', ' ');
    std::istringstream l(line);
    long step;
    Row r;
    l >> step >> r.time >> r.kinetic >> r.strain >> r.work >> r.broken >> r.damage >> r.fragments;
    rows[step] = r;
  }
  return rows;
}

}  // namespace

TEST_CASE("a running simulation publishes live state that peridot-watch receives in another process, ending with the final sample") {
  const auto deck = small_deck();
  const fs::path out = fs::temp_directory_path() / ("peridot_live_run_out_" + std::to_string(getpid()));
  fs::remove_all(out);
  const std::string run_id = "live-run-" + std::to_string(getpid());
  ChildProcess watch({PERIDOT_WATCH_EXE, "--run-id", run_id, "--timeout", "60", "--partition", partition()}, env());
  std::this_thread::sleep_for(300ms);
  ChildProcess run({PERIDOT_EXE, "run", deck.string(), "--out", out.string(), "--threads", "1", "--quiet", "--run-id", run_id,
                    "--dds-partition", partition()},
                   env());
  const auto r = run.wait(120s);
  const auto w = watch.wait(90s);
  INFO("run stderr: " << r.err << "\nwatch stdout: " << w.out << "\nwatch stderr: " << w.err);
  REQUIRE(r.exit_code == 0);
  REQUIRE(w.exit_code == 0);
  CHECK(w.out.find("finished") != std::string::npos);

  // Steps arrive in increasing order.
  std::istringstream in(w.out);
  std::string line;
  long last = -1, count = 0;
  while (std::getline(in, line))
    if (line.rfind("step", 0) == 0) {
      const long step = std::stol(line.substr(4));
      CHECK(step >= last);
      last = step, ++count;
    }
  CHECK(count >= 5);

  SECTION("the live summaries match the CSV history for the same steps") {
    const auto live = parse_watch(w.out);
    const auto csv = parse_csv(out / "crack_branching_2d_history.csv");
    std::size_t matched = 0;
    for (const auto& [step, a] : live) {
      const auto it = csv.find(step);
      if (it == csv.end()) continue;
      const auto& b = it->second;
      ++matched;
      INFO("step " << step);
      CHECK(a.time == Approx(b.time).epsilon(1e-4));
      CHECK(a.kinetic == Approx(b.kinetic).epsilon(1e-4).margin(1e-12));
      CHECK(a.strain == Approx(b.strain).epsilon(1e-4).margin(1e-12));
      CHECK(a.work == Approx(b.work).epsilon(1e-4).margin(1e-12));
      CHECK(a.broken == b.broken);
      CHECK(a.damage == Approx(b.damage).margin(1e-4));
      CHECK(a.fragments == b.fragments);
    }
    CHECK(matched >= 5);
  }
  fs::remove_all(out);
  fs::remove(deck);
}

TEST_CASE("SIGTERM ends a run after its current step: exit 143, whole CSV rows, a checkpoint of that step, and a FAILED 'interrupted' summary a watcher sees") {
  // Long enough that the signal always comes first (1 s of simulated time is millions of steps);
  // the checkpoint cadence is never reached, so the one written is the stop's.
  const auto deck = small_deck("1.0", 100000000);
  const fs::path out = fs::temp_directory_path() / ("peridot_live_stop_out_" + std::to_string(getpid()));
  fs::remove_all(out);
  const std::string run_id = "live-stop-" + std::to_string(getpid());
  ChildProcess watch({PERIDOT_WATCH_EXE, "--run-id", run_id, "--timeout", "60", "--partition", partition()}, env());
  ChildProcess run({PERIDOT_EXE, "run", deck.string(), "--out", out.string(), "--threads", "1", "--quiet", "--run-id", run_id,
                    "--dds-partition", partition()},
                   env());
  // Signal once the history has a few rows: the run is in its steps, observers and all.
  const auto csv = out / "crack_branching_2d_history.csv";
  const auto rows = [&] {
    std::ifstream in(csv);
    return std::count(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>(), '\n');
  };
  for (int i = 0; i < 600 && rows() < 4; ++i) std::this_thread::sleep_for(100ms);
  REQUIRE(rows() >= 4);
  run.signal(SIGTERM);
  const auto r = run.wait(60s);
  const auto w = watch.wait(60s);
  INFO("run stderr: " << r.err << "\nwatch stdout: " << w.out << "\nwatch stderr: " << w.err);
  CHECK(r.exit_code == 128 + SIGTERM);
  // peridot-watch: 3 is a failed run it was told about; 4 would be a watcher left waiting.
  CHECK(w.exit_code == 3);
  CHECK(w.out.find("interrupted") != std::string::npos);

  // Every row whole (as many fields as the header), and the last one is the step the run stopped at.
  std::ifstream in(csv);
  std::string header, line, last;
  std::getline(in, header);
  const auto fields = std::count(header.begin(), header.end(), ',');
  long rows_read = 0;
  while (std::getline(in, line)) {
    CHECK(std::count(line.begin(), line.end(), ',') == fields);
    last = line, ++rows_read;
  }
  REQUIRE(rows_read >= 4);
  const long stop_step = std::stol(last.substr(0, last.find(',')));
  const auto live = parse_watch(w.out);
  REQUIRE(!live.empty());
  CHECK(live.rbegin()->first == stop_step);
  const auto c = peridot::read_checkpoint(out / "crack_branching_2d.h5");
  CHECK(long(c.step) == stop_step);
  fs::remove_all(out);
  fs::remove(deck);
}
