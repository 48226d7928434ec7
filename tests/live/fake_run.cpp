// Test fixture: a stand-in for `peridot run` that publishes a short, made-up run
// over DDS, so the watcher can be tested in another process without a solver.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstddef>
#include <thread>
#include <vector>
#include <fmt/core.h>
import peridot.live;

int main(int argc, char** argv) {
  CLI::App app{"fake_run: publish a made-up run's summaries and snapshots over DDS"};
  peridot::LiveOptions options;
  int summaries = 10;
  double wait_s = 10;
  bool fail = false;
  app.add_option("--run-id", options.run_id)->required();
  app.add_option("--domain", options.domain_id);
  app.add_option("--partition", options.partition);
  app.add_option("--summaries", summaries)->check(CLI::Range(1, 1000));
  app.add_option("--wait-subscriber", wait_s, "Seconds to wait for a watcher to come, and at the end to leave");
  app.add_flag("--fail", fail, "End with status failed instead of finished");
  CLI11_PARSE(app, argc, argv);

  peridot::LivePublisher pub(options);
  // A watcher that joins late still gets the last 16 summaries (transient-local);
  // waiting for it keeps a longer run deterministic too.
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(wait_s);
  while (pub.subscriber_count() == 0 && std::chrono::steady_clock::now() < until)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));

  // A 60 x 40 plate whose damage grows from the left edge.
  const std::size_t nx = 60, ny = 40;
  std::vector<double> x, y, damage(nx * ny);
  for (std::size_t j = 0; j < ny; ++j)
    for (std::size_t i = 0; i < nx; ++i) {
      x.push_back(1e-3 * double(i));
      y.push_back(1e-3 * double(j));
    }
  for (int k = 1; k <= summaries; ++k) {
    peridot::RunSummarySample s;
    s.record.step = std::size_t(10 * k);
    s.record.time = 1e-7 * k;
    s.record.wall_time = 0.01 * k;
    s.record.kinetic_energy = 1e-3 * k;
    s.record.strain_energy = 2e-3 * k;
    s.record.external_work = 3e-3 * k;
    s.record.broken_bonds = std::size_t(5 * k);
    s.record.damage_fraction = 1e-3 * k;
    s.record.fragments = 1;
    s.record.tip_x = 1e-3 * k;
    s.record.tip_y = 0.02;
    s.record.tip_speed = 1e4;
    pub.publish_summary(s);
    for (std::size_t p = 0; p < x.size(); ++p) damage[p] = x[p] < 1e-3 * k ? 1.0 : 0.0;
    pub.publish_snapshot(2, x, y, {}, damage, s.record.step, s.record.time);
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  pub.finish(!fail, fail ? "fake failure" : "");
  // Stay until the watchers have left (bounded): one that is still discovering
  // this run then gets the whole history instead of nothing.
  const auto linger_until = std::chrono::steady_clock::now() + std::chrono::duration<double>(wait_s);
  while (pub.subscriber_count() > 0 && std::chrono::steady_clock::now() < linger_until)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  fmt::print("published {} summaries, dropped {} summaries and {} snapshots, {} watcher(s)\n", summaries,
             pub.dropped_summaries(), pub.dropped_snapshots(), pub.subscriber_count());
}
