// In-process tests of peridot.live: publisher and subscriber share one process
// and talk over the shipped loopback-only configuration.
#include <catch2/catch.hpp>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>
#include <fmt/core.h>
import peridot.live;

using namespace peridot;
using namespace std::chrono_literals;

namespace {

const std::string loopback = fmt::format("file://{}/data/dds/loopback.xml", PERIDOT_SOURCE_DIR);

LiveOptions loopback_options(const char* what) {
  LiveOptions o;
  o.run_id = fmt::format("test-{}-{}", what, getpid());
  // Test processes run in parallel on one domain: a partition of each test's own keeps
  // other tests' readers from matching its writers (a late joiner must find none).
  o.partition = o.run_id;
  o.config_uri = loopback;
  return o;
}

// Best-effort and volatile: a snapshot sent before the reader matched is gone, so publish
// until one arrives (bounded), with the given step when one is named.
template <class Publish>
std::optional<FieldSnapshotSample> received(LiveSubscriber& sub, Publish publish, std::optional<std::size_t> step = {}) {
  std::optional<FieldSnapshotSample> snap;
  for (int attempt = 0; attempt < 50 && !(snap && (!step || snap->step == *step)); ++attempt) {
    publish();
    snap = sub.wait_snapshot(200ms);
  }
  if (snap && step && snap->step != *step) snap.reset();
  return snap;
}

// Independent of snapshot_stride: the smallest k with ceil(n / k) <= max.
std::size_t smallest_stride(std::size_t n, std::size_t max) {
  std::size_t k = 1;
  while ((n + k - 1) / k > max) ++k;
  return k;
}

}  // namespace

TEST_CASE("a 3D snapshot published in-process arrives decimated under the point limit with its values intact") {
  auto options = loopback_options("snapshot");
  options.snapshot_max_points = 5000;
  LiveSubscriber sub(options);
  LivePublisher pub(options);

  const std::size_t n = 23456;
  std::vector<double> x(n), y(n), z(n), damage(n);
  for (std::size_t i = 0; i < n; ++i) {
    x[i] = 1e-3 * double(i % 100);
    y[i] = 1e-3 * double((i / 100) % 50);
    z[i] = 1e-3 * double(i / 5000);
    damage[i] = double(i % 97) / 96.0;
  }
  const auto snap = received(sub, [&] { pub.publish_snapshot(3, x, y, z, damage, 42, 1.5e-6); });
  REQUIRE(snap);
  const std::size_t k = smallest_stride(n, options.snapshot_max_points);
  CHECK(snap->size() <= options.snapshot_max_points);
  REQUIRE(snap->size() == (n + k - 1) / k);
  REQUIRE(snap->x.size() == snap->size());
  REQUIRE(snap->y.size() == snap->size());
  REQUIRE(snap->z.size() == snap->size());
  CHECK(snap->run_id == options.run_id);
  CHECK(snap->dim == 3);
  CHECK(snap->step == 42);
  CHECK(snap->time == 1.5e-6);
  CHECK(snap->total_points == n);
  std::size_t wrong = 0;
  for (std::size_t j = 0; j < snap->size(); ++j)
    wrong += snap->x[j] != float(x[j * k]) || snap->y[j] != float(y[j * k]) || snap->z[j] != float(z[j * k]) ||
             snap->damage[j] != float(damage[j * k]);
  CHECK(wrong == 0);
}

TEST_CASE("a snapshot of every k-th point, decimated before publishing as N ranks gather it, arrives as the whole cloud's snapshot does") {
  const std::size_t n = 5003, max_points = 700;
  std::vector<double> x(n), y(n), damage(n);
  for (std::size_t i = 0; i < n; ++i) x[i] = 1e-3 * double(i % 71), y[i] = 1e-3 * double(i / 71), damage[i] = double(i % 13) / 12.0;
  const std::size_t k = smallest_stride(n, max_points);
  auto options = loopback_options("snapshot_parts");
  options.snapshot_max_points = max_points;
  LiveSubscriber sub(options);
  LivePublisher pub(options);
  std::vector<double> xs, ys, ds;
  for (std::size_t i = 0; i < n; i += k) xs.push_back(x[i]), ys.push_back(y[i]), ds.push_back(damage[i]);
  // Distinct steps: a late copy of the first cannot pass for the second.
  const auto whole = received(sub, [&] { pub.publish_snapshot(2, x, y, {}, damage, 3, 0.25); }, 3);
  const auto parts = received(sub, [&] { pub.publish_snapshot(2, xs, ys, {}, ds, 4, 0.25, n); }, 4);
  REQUIRE(whole);
  REQUIRE(parts);
  CHECK(parts->total_points == n);
  CHECK(whole->total_points == n);
  REQUIRE(parts->size() == xs.size());
  const bool same = parts->x == whole->x && parts->y == whole->y && parts->damage == whole->damage;
  CHECK(same);
}

TEST_CASE("a 2D snapshot within the point limit arrives whole, without z") {
  auto options = loopback_options("snapshot2d");
  LiveSubscriber sub(options);
  LivePublisher pub(options);
  const std::vector<double> x = {0, 1, 2, 3}, y = {0, 0, 1, 1}, damage = {0, 0.25, 0.5, 1};
  const auto snap = received(sub, [&] { pub.publish_snapshot(2, x, y, {}, damage, 7, 0.5); });
  REQUIRE(snap);
  CHECK(snap->dim == 2);
  CHECK(snap->z.empty());
  CHECK(snap->x == std::vector<float>{0, 1, 2, 3});
  CHECK(snap->damage == std::vector<float>{0, 0.25f, 0.5f, 1});
}

TEST_CASE("summaries published in-process arrive in order with every field intact, the final status last") {
  const auto options = loopback_options("summary");
  LiveSubscriber sub(options);
  std::vector<RunSummarySample> sent;
  {
    LivePublisher pub(options);
    for (int k = 1; k <= 5; ++k) {
      RunSummarySample s;
      s.record.step = std::size_t(100 * k);
      s.record.time = 1e-6 * k;
      s.record.wall_time = 0.5 * k;
      s.record.kinetic_energy = 1.25 * k;
      s.record.strain_energy = 2.5 * k;
      s.record.external_work = 3.75 * k;
      s.record.broken_bonds = std::size_t(7 * k);
      s.record.damage_fraction = 0.01 * k;
      s.record.fragments = k;
      s.record.tip_x = 0.1 * k;
      s.record.tip_y = 0.05;
      if (k > 1) s.record.tip_speed = 1000.0 * k;  // k = 1 keeps NaN: "not tracked yet"
      if (k > 1) {  // k = 1 keeps the front's NaN and -1: "not tracked"
        s.record.front_length = 0.001 * k;
        s.record.front_mean_advance = 0.002 * k;
        s.record.front_max_advance = 0.003 * k;
        s.record.front_max_speed = 500.0 * k;
        s.record.front_branched_slices = k - 1;
      }
      pub.publish_summary(s);
      sent.push_back(s);
    }
    pub.finish(false, "diverged at step 500");
  }
  std::vector<RunSummarySample> got;
  const auto deadline = std::chrono::steady_clock::now() + 20s;
  while (got.size() < sent.size() + 1 && std::chrono::steady_clock::now() < deadline)
    for (auto& s : sub.wait_summaries(1000ms)) got.push_back(std::move(s));
  REQUIRE(got.size() == sent.size() + 1);
  for (std::size_t k = 0; k < sent.size(); ++k) {
    const auto& a = sent[k];
    const auto& b = got[k];
    CHECK(b.run_id == options.run_id);
    CHECK(b.record.step == a.record.step);
    CHECK(b.record.time == a.record.time);
    CHECK(b.record.wall_time == a.record.wall_time);
    CHECK(b.record.kinetic_energy == a.record.kinetic_energy);
    CHECK(b.record.strain_energy == a.record.strain_energy);
    CHECK(b.record.external_work == a.record.external_work);
    CHECK(b.record.broken_bonds == a.record.broken_bonds);
    CHECK(b.record.damage_fraction == a.record.damage_fraction);
    CHECK(b.record.fragments == a.record.fragments);
    CHECK(b.record.tip_x == a.record.tip_x);
    CHECK(b.record.tip_y == a.record.tip_y);
    CHECK((std::isnan(a.record.tip_speed) ? std::isnan(b.record.tip_speed) : b.record.tip_speed == a.record.tip_speed));
    const auto same = [](double x, double y) { return std::isnan(x) ? std::isnan(y) : x == y; };
    CHECK(same(a.record.front_length, b.record.front_length));
    CHECK(same(a.record.front_mean_advance, b.record.front_mean_advance));
    CHECK(same(a.record.front_max_advance, b.record.front_max_advance));
    CHECK(same(a.record.front_max_speed, b.record.front_max_speed));
    CHECK(b.record.front_branched_slices == a.record.front_branched_slices);
    CHECK(b.status == RunStatus::running);
    CHECK(b.message.empty());
  }
  CHECK(got.back().record.step == sent.back().record.step);
  CHECK(got.back().record.kinetic_energy == sent.back().record.kinetic_energy);
  CHECK(got.back().status == RunStatus::failed);
  CHECK(got.back().message == "diverged at step 500");
}

TEST_CASE("a publisher destroyed without finish() reports the run as failed") {
  const auto options = loopback_options("abandoned");
  LiveSubscriber sub(options);
  {
    LivePublisher pub(options);
    RunSummarySample s;
    s.record.step = 3;
    pub.publish_summary(s);
  }  // e.g. the solver threw
  std::vector<RunSummarySample> got;
  const auto deadline = std::chrono::steady_clock::now() + 20s;
  while (got.size() < 2 && std::chrono::steady_clock::now() < deadline)
    for (auto& s : sub.wait_summaries(1000ms)) got.push_back(std::move(s));
  REQUIRE(got.size() == 2);
  CHECK(got.back().status == RunStatus::failed);
  CHECK(got.back().record.step == 3);
  CHECK_FALSE(got.back().message.empty());
}

TEST_CASE("a watcher that starts after the run finished still gets its last 16 summaries and the final status") {
  const auto options = loopback_options("latejoin");
  LivePublisher pub(options);
  for (std::size_t k = 1; k <= 20; ++k) {
    RunSummarySample s;
    s.record.step = k;
    pub.publish_summary(s);
  }
  pub.finish(true, "");  // every sample is written once this returns
  REQUIRE(pub.subscriber_count() == 0);

  LiveSubscriber sub(options);  // joins late, while the publisher still lives
  std::vector<RunSummarySample> got;
  const auto deadline = std::chrono::steady_clock::now() + 20s;
  while ((got.empty() || got.back().status == RunStatus::running) && std::chrono::steady_clock::now() < deadline)
    for (auto& s : sub.wait_summaries(1000ms)) got.push_back(std::move(s));
  // 21 samples were written (20 running, 1 final); the writer keeps the last 16.
  REQUIRE(got.size() == 16);
  for (std::size_t k = 0; k + 1 < got.size(); ++k) {
    CHECK(got[k].record.step == 6 + k);
    CHECK(got[k].status == RunStatus::running);
  }
  CHECK(got.back().record.step == 20);
  CHECK(got.back().status == RunStatus::finished);
}

TEST_CASE("a watcher in another partition of the same domain neither matches nor hears a run") {
  const auto options = loopback_options("partitioned");
  auto elsewhere = options;
  elsewhere.partition += "-other";
  LiveSubscriber other(elsewhere);
  LiveSubscriber same(options);
  LivePublisher pub(options);
  // Matching is asynchronous: wait (bounded) until the watcher in the run's partition matches.
  const auto deadline = std::chrono::steady_clock::now() + 20s;
  while (pub.subscriber_count() == 0 && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(10ms);
  REQUIRE(pub.subscriber_count() == 1);
  RunSummarySample s;
  s.record.step = 7;
  pub.publish_summary(s);
  pub.finish(true, "");
  std::vector<RunSummarySample> got;
  while ((got.empty() || got.back().status == RunStatus::running) && std::chrono::steady_clock::now() < deadline)
    for (auto& g : same.wait_summaries(200ms)) got.push_back(std::move(g));
  REQUIRE_FALSE(got.empty());
  CHECK(got.back().status == RunStatus::finished);
  // The reliable, transient-local final sample reached `same`; `other` never matched the writer.
  CHECK(other.wait_summaries(500ms).empty());
  CHECK(pub.subscriber_count() == 1);
  CHECK(other.publisher_count() == 0);
}

TEST_CASE("the snapshot stride is the smallest that keeps any cloud within the point limit") {
  for (const std::size_t max : {1, 2, 7, 100, 20000})
    for (std::size_t n = 0; n < 3000; n += 7) {
      const auto s = snapshot_stride(n, max);
      INFO("n = " << n << ", max = " << max);
      REQUIRE(s >= 1);
      CHECK((n + s - 1) / s <= max);
      if (s > 1) CHECK((n + s - 2) / (s - 1) > max);  // one less would be too many
    }
  CHECK(snapshot_stride(1'000'000, 20000) == 50);
  CHECK_THROWS_AS(snapshot_stride(10, 0), std::invalid_argument);
}

TEST_CASE("the DDS config is the option, else CYCLONEDDS_URI, else PERIDOT_DDS_CONFIG, else the shipped loopback file") {
  const auto tmp = std::filesystem::temp_directory_path() / fmt::format("peridot-dds-{}.xml", getpid());
  std::ofstream(tmp) << "<CycloneDDS/>\n";
  unsetenv("CYCLONEDDS_URI");
  unsetenv("PERIDOT_DDS_CONFIG");

  LiveOptions o;
  const auto shipped = dds_config(o);
  CHECK(shipped.rfind("file://", 0) == 0);
  CHECK(std::filesystem::equivalent(shipped.substr(7), std::filesystem::path(PERIDOT_SOURCE_DIR) / "data/dds/loopback.xml"));

  setenv("PERIDOT_DDS_CONFIG", tmp.c_str(), 1);
  CHECK(dds_config(o) == "file://" + tmp.string());
  setenv("CYCLONEDDS_URI", "file:///user/choice.xml", 1);
  CHECK(dds_config(o) == "file:///user/choice.xml");
  o.config_uri = "<CycloneDDS><Domain/></CycloneDDS>";
  CHECK(dds_config(o) == *o.config_uri);

  o.config_uri = "/no/such/dds.xml";
  CHECK_THROWS_WITH(dds_config(o), Catch::Contains("config_uri") && Catch::Contains("/no/such/dds.xml"));
  o.config_uri.reset();
  unsetenv("CYCLONEDDS_URI");
  setenv("PERIDOT_DDS_CONFIG", "/no/such/dds.xml", 1);
  CHECK_THROWS_WITH(dds_config(o), Catch::Contains("PERIDOT_DDS_CONFIG"));
  unsetenv("PERIDOT_DDS_CONFIG");
  std::filesystem::remove(tmp);
}

TEST_CASE("live options out of range are rejected naming the field") {
  auto o = loopback_options("options");
  o.run_id.clear();
  CHECK_THROWS_WITH(LivePublisher(o), Catch::Contains("run_id"));
  o = loopback_options("options");
  o.domain_id = 231;
  CHECK_THROWS_WITH(LivePublisher(o), Catch::Contains("domain_id") && Catch::Contains("0..230"));
  CHECK_THROWS_WITH(LiveSubscriber(o), Catch::Contains("domain_id"));
  o = loopback_options("options");
  o.partition = "runs-*";
  CHECK_THROWS_WITH(LivePublisher(o), Catch::Contains("partition") && Catch::Contains("runs-*"));
  o.partition = std::string(201, 'p');
  CHECK_THROWS_WITH(LiveSubscriber(o), Catch::Contains("partition") && Catch::Contains("200"));
  o = loopback_options("options");
  o.snapshot_max_points = 0;
  CHECK_THROWS_WITH(LivePublisher(o), Catch::Contains("snapshot_max_points"));

  LivePublisher pub(loopback_options("options"));
  const std::vector<double> three(3), four(4);
  CHECK_THROWS_WITH(pub.publish_snapshot(2, three, three, {}, four, 0, 0), Catch::Contains("differ in length"));
  CHECK_THROWS_WITH(pub.publish_snapshot(1, four, four, {}, four, 0, 0), Catch::Contains("dim"));
}

TEST_CASE("the shipped DDS config selects only the loopback interface, no multicast and 127.0.0.1 as the only peer") {
  // Cyclone's own trace of the configuration it applied, not the XML text.
  const auto log = std::filesystem::temp_directory_path() / fmt::format("peridot-dds-trace-{}.log", getpid());
  auto options = loopback_options("trace");
  options.config_uri = fmt::format("{},<Tracing><Verbosity>config</Verbosity><OutputFile>{}</OutputFile></Tracing>",
                                   loopback, log.string());
  { LiveSubscriber sub(options); }
  std::ifstream in(log);
  REQUIRE(in.good());
  std::string selected, peers, multicast;
  for (std::string line; std::getline(in, line);) {
    if (line.find("selected interfaces:") != std::string::npos) selected = line;
    if (line.find("add_peer_addresses:") != std::string::npos) peers = line;
    if (line.find("General/AllowMulticast/#text:") != std::string::npos) multicast = line;
  }
  in.close();
  std::filesystem::remove(log);
  INFO("selected: " << selected << "\npeers: " << peers << "\nmulticast: " << multicast);
  CHECK(selected.find("selected interfaces: lo ") != std::string::npos);
  CHECK(selected.find(',') == std::string::npos);  // one interface only
  CHECK(multicast.find("#text: false") != std::string::npos);
  // Every peer locator is on 127.0.0.1: "udp/127.0.0.1:7410, :7412, ..."
  CHECK(peers.find("udp/127.0.0.1:") != std::string::npos);
  std::size_t addresses = 0;
  for (std::size_t p = peers.find("udp/"); p != std::string::npos; p = peers.find("udp/", p + 1)) ++addresses;
  CHECK(addresses == 1);  // the rest are ports on that same address
}
