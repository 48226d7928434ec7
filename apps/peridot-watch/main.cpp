// peridot-watch: prints one line per live summary of a run published over DDS.
// Exit codes: 0 the run finished, 2 usage or setup error (as peridot), 3 the run failed, 4 timeout.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <optional>
#include <string>
#include <vector>
#include <fmt/core.h>
import peridot.live;
#ifdef PERIDOT_WATCH_PNG
import peridot.render;
#endif

namespace {

// Usage errors exit 2, as the peridot CLI does.
constexpr int exit_finished = 0, exit_usage = 2, exit_failed = 3, exit_timeout = 4;

struct Args {
  std::string run_id;
  double timeout = 30;
  std::string png;
  int domain = 0;
  std::string partition;
};

std::string optional_number(double v, const char* format) {
  return std::isnan(v) ? "-" : fmt::format(fmt::runtime(format), v);
}

// Slices of the 3D front that hold a point (the others are NaN).
std::size_t front_point_count(const std::vector<double>& xyz) {
  std::size_t n = 0;
  for (std::size_t k = 0; k + 2 < xyz.size(); k += 3) n += !std::isnan(xyz[k]);
  return n;
}

void print_summary(const peridot::RunSummarySample& s) {
  fmt::print("step {:>8}  t {:.4e} s  wall {:.2f} s  KE {:.4e} J  SE {:.4e} J  W {:.4e} J  broken {}  damage {:.4f}  "
             "fragments {}  tip ({}, {}) m  v {} m/s  {}{}{}\n",
             s.record.step, s.record.time, s.record.wall_time, s.record.kinetic_energy, s.record.strain_energy, s.record.external_work, s.record.broken_bonds,
             s.record.damage_fraction, s.record.fragments < 0 ? std::string("-") : std::to_string(s.record.fragments),
             optional_number(s.record.tip_x, "{:.5f}"), optional_number(s.record.tip_y, "{:.5f}"),
             optional_number(s.record.tip_speed, "{:.1f}"),
             // The 3D crack front, when the run tracks one.
             std::isnan(s.record.front_length) ? std::string()
                                               : fmt::format("front {:.5f} m through {} of {} slices, advance {:.5f} m (max), {:.1f} m/s, {} slices branched  ",
                                                             s.record.front_length, front_point_count(s.front_points), s.front_points.size() / 3,
                                                             s.record.front_max_advance, s.record.front_max_speed, s.record.front_branched_slices),
             peridot::to_string(s.status),
             s.message.empty() ? "" : ": " + s.message);
  std::fflush(stdout);  // watchers usually sit behind a pipe
}

std::string run_name(const std::string& run_id) { return run_id.empty() ? "any run" : fmt::format("run '{}'", run_id); }

// Draws a snapshot to `file` (written atomically, so a viewer can keep it open).
void write_png(const std::string& file, const peridot::FieldSnapshotSample& snap) {
#ifdef PERIDOT_WATCH_PNG
  const auto widen = [](const std::vector<float>& v) { return std::vector<double>(v.begin(), v.end()); };
  const auto x = widen(snap.x), y = widen(snap.y), z = widen(snap.z), damage = widen(snap.damage);
  peridot::RenderField field;
  field.dim = snap.dim;
  field.x = {x, y, z};
  field.values = damage;
  field.field_name = "damage";
  field.time = snap.time;
  field.step = snap.step;
  peridot::render_png(file, field);
#else
  (void)snap;
  throw std::runtime_error(fmt::format("cannot write {}: this build has no peridot.render", file));
#endif
}

int watch(const Args& args) {
  peridot::LiveSubscriber sub({.run_id = args.run_id, .domain_id = args.domain, .partition = args.partition});
  const auto timeout = std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::duration<double>(args.timeout));
  auto last_heard = std::chrono::steady_clock::now();
  std::optional<std::size_t> last_step;
  bool png_written = false;
  const auto update_png = [&](std::chrono::milliseconds wait) {
    if (args.png.empty()) return;
    if (auto snap = sub.wait_snapshot(wait)) {
      write_png(args.png, *snap);
      png_written = true;
    }
  };
  for (;;) {
    const auto left = timeout - std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - last_heard);
    if (left <= std::chrono::milliseconds::zero()) {
      if (last_step)
        fmt::print(stderr, "peridot-watch: {} went silent: no summary for {} s after step {}\n", run_name(sub.run_id()),
                   args.timeout, *last_step);
      else if (sub.publisher_count() > 0)
        fmt::print(stderr, "peridot-watch: a publisher is on DDS domain {} but sent no summary for {} within {} s\n",
                   args.domain, run_name(sub.run_id()), args.timeout);
      else
        fmt::print(stderr,
                   "peridot-watch: no publisher for {} on DDS domain {} within {} s (is the run publishing, on the "
                   "same domain, partition and DDS configuration?)\n",
                   run_name(sub.run_id()), args.domain, args.timeout);
      return exit_timeout;
    }
    const auto batch = sub.wait_summaries(left);
    if (batch.empty()) continue;
    last_heard = std::chrono::steady_clock::now();
    update_png(std::chrono::milliseconds::zero());
    for (const auto& s : batch) {
      print_summary(s);
      last_step = s.record.step;
      if (s.status == peridot::RunStatus::running) continue;
      // The final snapshot is sent before the final summary but may still be on its way.
      update_png(png_written ? std::chrono::milliseconds::zero() : std::chrono::milliseconds(1000));
      if (!args.png.empty() && !png_written)
        fmt::print(stderr, "peridot-watch: no field snapshot received; {} not written\n", args.png);
      return s.status == peridot::RunStatus::finished ? exit_finished : exit_failed;
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"peridot-watch: print a running simulation's live summaries, received over DDS.\n"
               "Exit codes: 0 the run finished, 2 usage or setup error (as peridot), 3 the run failed, 4 timeout."};
  Args args;
  app.add_option("--run-id", args.run_id, "Run to follow (default: the first run that publishes)");
  app.add_option("--timeout", args.timeout, "Give up after this many seconds without a summary")
      ->check(CLI::Range(0.0, 1e6))
      ->capture_default_str();
  app.add_option("--png", args.png, "Keep this PNG file showing the latest damage snapshot");
  app.add_option("--domain", args.domain, "DDS domain id")->check(CLI::Range(0, 230))->capture_default_str();
  app.add_option("--partition", args.partition, "DDS partition (default: the default partition)");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : exit_usage;
  }
  try {
    return watch(args);
  } catch (const std::exception& e) {
    fmt::print(stderr, "peridot-watch: {}\n", e.what());
    return exit_usage;
  }
}
