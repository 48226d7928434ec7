// peridot-bench: explicit-solver throughput and memory on the crack-branching decks.
// Each (deck, thread count) runs in its own child process, so the peak resident set it
// reports is that run's alone: set-up, bonds, fields and the stepping, nothing left from
// another deck. Prints seconds per step, directed bond evaluations per second (each bond
// counted from both ends, as CabanaPD counts), bytes per bond and per point, and the ratio to
// the CabanaPD figures of issue 12 measured on this machine kind.
#include <omp.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <optional>
#include <string>
#include <thread>
#include <variant>
#include <vector>
#include <fmt/core.h>
import peridot.run;

using namespace peridot;

namespace {

// CabanaPD's crack-branching example on this machine kind with 2 threads (issue 12): the
// peer each figure is compared with, keyed by point count.
struct PeerFigure {
  double seconds_per_step;
  double peak_mib;
};
const std::map<std::size_t, PeerFigure> cabana_2_threads = {{64000, {0.052, 110}}, {512000, {0.596, 1080}}};

std::string machine() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  return "unknown CPU";
}

double peak_mib(const rusage& r) { return double(r.ru_maxrss) / 1024.0; }  // ru_maxrss is in KiB on Linux

struct Timing {
  double setup_s = 0, seconds_per_step = 0;
  std::size_t points = 0, bonds = 0, broken = 0, steps = 0;
  double bond_bytes = 0;
  const char* layout = "";
  const char* precision = "";  // forces on a list: PMB, RNP, LPS
};

// --bonds: the deck's discretization.bonds, or this layout instead.
std::optional<BondLayout> layout_override;
// --list-precision: forces on a list in single precision or double (PMB, RNP, explicit LPS).
std::optional<ListPrecision> precision_override;

// One run in this (child) process, through the library's run loop with every output off; the
// parent reads the peak RSS from wait4.
Timing time_run(const std::string& deck, std::size_t steps, int threads) {
  omp_set_num_threads(threads);
  Problem p = read_deck(deck);
  if (layout_override) p.bond_layout = *layout_override;
  if (precision_override) p.list_precision = *precision_override;
  p.output = OutputSpec{};
  RunOptions options;
  options.max_steps = steps;
  const auto t_setup = std::chrono::steady_clock::now();
  Simulation simulation(std::move(p), options);
  Timing t;
  t.setup_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_setup).count();
  const Body& body = simulation.body();
  t.points = body.size();
  t.bonds = body.directed_bonds();
  t.bond_bytes = double(body.bond_bytes());
  t.layout = body.layout_name();
  const Problem& problem = simulation.problem();
  // PMB, RNP and explicit LPS run in the list precision (PMB's default single, the others' double).
  const auto model = problem.material.model;
  const bool has_precision = model == ModelKind::pmb || model == ModelKind::rnp || model == ModelKind::lps;
  t.precision = body.on_stencil() || !has_precision                           ? ""
                : problem.list_precision == ListPrecision::double_precision ? " in double"
                                                                             : " in single precision";
  const RunOutcome out = simulation.run();
  t.steps = out.steps;
  t.seconds_per_step = out.wall_seconds / double(std::max<std::size_t>(out.steps, 1));
  t.broken = out.broken;
  return t;
}

struct Measured {
  Timing t;
  double peak_mib = 0;
};

// Runs time_run in a child and passes its figures back through a pipe.
Measured measure(const std::string& deck, std::size_t steps, int threads) {
  int fd[2];
  if (pipe(fd) != 0) throw std::runtime_error("pipe failed");
  std::fflush(stdout);
  const pid_t pid = fork();
  if (pid < 0) throw std::runtime_error("fork failed");
  if (pid == 0) {
    close(fd[0]);
    int code = 0;
    try {
      const Timing t = time_run(deck, steps, threads);
      code = write(fd[1], &t, sizeof t) == ssize_t(sizeof t) ? 0 : 3;
    } catch (const std::exception& e) {
      fmt::print(stderr, "error: {}\n", e.what());
      code = 2;
    }
    close(fd[1]);
    std::fflush(stdout);
    _exit(code);
  }
  close(fd[1]);
  Measured m;
  const bool got = read(fd[0], &m.t, sizeof m.t) == ssize_t(sizeof m.t);
  close(fd[0]);
  int status = 0;
  rusage r{};
  wait4(pid, &status, 0, &r);
  if (!got || !WIFEXITED(status) || WEXITSTATUS(status) != 0) throw std::runtime_error("benchmark run of " + deck + " failed");
  m.peak_mib = peak_mib(r);
  return m;
}

void bench(const std::string& deck, std::size_t steps, const std::vector<int>& threads) {
  std::vector<Measured> runs;
  for (int n : threads) runs.push_back(measure(deck, steps, n));
  const auto& first = runs.front().t;
  const double directed = double(first.bonds);
  fmt::print("{}\n  {} points, {:.0f} directed bonds ({:.1f} per point), {}{}, {:.1f} bytes per bond ({:.0f} MiB)\n", deck, first.points,
             directed, directed / double(first.points), first.layout, first.precision, first.bond_bytes / directed,
             first.bond_bytes / (1024.0 * 1024.0));
  const auto peer = cabana_2_threads.find(first.points);
  for (std::size_t k = 0; k < runs.size(); ++k) {
    const auto& [t, peak] = runs[k];
    fmt::print("  threads {}: {:.4f} s/step, {:.3e} directed bond evaluations/s, set-up {:.2f} s, peak RSS {:.0f} MiB "
               "({:.0f} bytes per point all told; {} steps, {} bonds broken)\n",
               threads[k], t.seconds_per_step, directed / t.seconds_per_step, t.setup_s, peak, peak * 1024.0 * 1024.0 / double(t.points),
               t.steps, t.broken);
    if (threads[k] == 2 && peer != cabana_2_threads.end())
      fmt::print("    vs CabanaPD at 2 threads ({} s/step, {} MiB, issue 12): {:.2f}x faster per step, {:.2f}x its memory\n",
                 peer->second.seconds_per_step, peer->second.peak_mib, peer->second.seconds_per_step / t.seconds_per_step,
                 peak / peer->second.peak_mib);
  }
  if (runs.size() >= 2)
    fmt::print("  strong scaling {} -> {} threads: {:.2f}x\n", threads.front(), threads.back(),
               runs.front().t.seconds_per_step / runs.back().t.seconds_per_step);
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  std::size_t steps = 955;
  std::vector<std::string> decks;
  std::vector<int> threads = {1, 2};
  CLI::App app{"peridot-bench: explicit PMB speed and memory (default decks: crack_branching_3d, _3d_fine and _2d)"};
  app.add_option("decks", decks, "YAML decks")->check(CLI::ExistingFile);
  app.add_option("--steps", steps, "steps per timing (at most the deck's)")->check(CLI::Range(std::size_t(1), std::size_t(1000000)));
  app.add_option("--threads", threads, "thread counts, one child process each")->check(CLI::Range(1, 1024));
  std::string bonds = "deck";
  app.add_option("--bonds", bonds,
                 "bond layout: deck (as the deck says), auto, list (CSR, the path of perturbed clouds), compact (a list without xi and |xi|: "
                 "explicit RNP and LPS) or stencil")
      ->check(CLI::IsMember({"deck", "auto", "list", "compact", "stencil"}));
  std::string precision = "deck";
  app.add_option("--list-precision", precision, "forces on a list (PMB, RNP, explicit LPS): deck (as the deck says), single or double")
      ->check(CLI::IsMember({"deck", "single", "double"}));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  if (bonds != "deck")
    layout_override = bonds == "list"      ? BondLayout::list
                      : bonds == "compact" ? BondLayout::compact
                      : bonds == "stencil" ? BondLayout::stencil
                                           : BondLayout::automatic;
  if (precision != "deck") precision_override = precision == "double" ? ListPrecision::double_precision : ListPrecision::single;
  const std::string data = std::string(PERIDOT_SOURCE_DIR) + "/data/decks/";
  if (decks.empty()) decks = {data + "crack_branching_3d.yaml", data + "crack_branching_3d_fine.yaml", data + "crack_branching_2d.yaml"};
  // No OpenMP call before the children fork: each starts its own thread pool.
  fmt::print("peridot-bench on {} ({} hardware threads)\n", machine(), std::thread::hardware_concurrency());
  try {
    for (const auto& d : decks) {
      // The fine deck's 955 steps take minutes; 100 steps time it as issue 12 did.
      const bool fine = d.find("_fine") != std::string::npos;
      bench(d, fine ? std::min<std::size_t>(steps, 100) : steps, threads);
    }
  } catch (const std::exception& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return 2;
  }
  return 0;
}
