module;
#include <dds/dds.h>
#include "peridot_live.h"
export module peridot.live:subscriber;
import peridot.std;
import :options;
import :dds;

export namespace peridot {

// Follows one run: its summaries in order and its newest field snapshot.
class LiveSubscriber {
 public:
  // options.run_id empty: follow the first run that shows up.
  explicit LiveSubscriber(const LiveOptions& options);
  ~LiveSubscriber();
  LiveSubscriber(const LiveSubscriber&) = delete;
  LiveSubscriber& operator=(const LiveSubscriber&) = delete;

  // The summaries received since the last call, in publication order; waits up
  // to `timeout` for the first one and returns empty if none came.
  std::vector<RunSummarySample> wait_summaries(std::chrono::milliseconds timeout);
  // Waits up to `timeout` for a snapshot newer than the last one returned.
  std::optional<FieldSnapshotSample> wait_snapshot(std::chrono::milliseconds timeout);
  // The newest snapshot received so far, without waiting.
  std::optional<FieldSnapshotSample> latest_snapshot();

  // The run followed; empty until the first sample when none was asked for.
  const std::string& run_id() const;
  // Publishers currently matched on the summary topic (any run).
  std::size_t publisher_count() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace peridot

namespace peridot {

struct LiveSubscriber::Impl {
  LiveOptions options;
  std::shared_ptr<dds::Participant> participant;
  // The group is deleted last: deleting it deletes its readers.
  dds::Entity group, summary_topic, snapshot_topic, summary_reader, snapshot_reader, waitset;
  std::vector<RunSummarySample> pending;
  std::optional<FieldSnapshotSample> latest;
  std::size_t snapshots_received = 0, snapshots_returned = 0;

  explicit Impl(const LiveOptions& o) : options(o) {
    validate(options, false);
    participant = dds::acquire_participant(options);
    const auto sq = dds::summary_qos(false);
    const auto fq = dds::snapshot_qos();
    const dds_entity_t p = participant->get();
    // Topics take the writers' QoS: one participant may hold both ends, and its
    // topics of one name must agree.
    summary_topic = dds::make_topic(p, &peridot_live_RunSummary_desc, dds::summary_topic, dds::summary_qos(true).get());
    snapshot_topic = dds::make_topic(p, &peridot_live_FieldSnapshot_desc, dds::snapshot_topic, fq.get());
    group = dds::make_group(p, options, false);
    summary_reader = dds::Entity(
        dds::check(dds_create_reader(group.get(), summary_topic.get(), sq.get(), nullptr), "creating the summary reader"));
    snapshot_reader = dds::Entity(
        dds::check(dds_create_reader(group.get(), snapshot_topic.get(), fq.get(), nullptr), "creating the snapshot reader"));
    waitset = dds::Entity(dds::check(dds_create_waitset(p), "creating a waitset"));
    // Read conditions belong to their reader and are deleted with it.
    for (const auto r : {summary_reader.get(), snapshot_reader.get()}) {
      const dds_entity_t cond = dds::check(dds_create_readcondition(r, DDS_ANY_STATE), "creating a read condition");
      if (const auto rc = dds_waitset_attach(waitset.get(), cond, 0); rc < 0) dds::fail("attaching a read condition", rc);
    }
  }

  // Adopts the first run seen when none was asked for.
  bool follows(const char* run_id) {
    if (!run_id) return false;
    if (options.run_id.empty()) options.run_id = run_id;
    return options.run_id == run_id;
  }

  // Takes every sample the reader holds, lending them to `use` one by one.
  template <class Sample, class Use>
  void take_all(dds_entity_t reader, Use&& use) {
    constexpr std::size_t batch = 32;
    std::array<void*, batch> samples{};
    std::array<dds_sample_info_t, batch> infos{};
    for (;;) {
      samples.fill(nullptr);  // null entries ask Cyclone to lend its own buffers
      const dds_return_t n = dds_take(reader, samples.data(), infos.data(), batch, batch);
      if (n < 0) dds::fail("taking samples", n);
      for (dds_return_t i = 0; i < n; ++i)
        if (infos[std::size_t(i)].valid_data) use(*static_cast<const Sample*>(samples[std::size_t(i)]));
      if (n > 0) dds_return_loan(reader, samples.data(), n);
      if (std::size_t(n) < batch) return;
    }
  }

  void poll() {
    take_all<peridot_live_RunSummary>(summary_reader.get(), [&](const peridot_live_RunSummary& d) {
      if (follows(d.run_id)) pending.push_back(dds::from_dds(d));
    });
    take_all<peridot_live_FieldSnapshot>(snapshot_reader.get(), [&](const peridot_live_FieldSnapshot& d) {
      if (!follows(d.run_id)) return;
      auto& s = latest ? *latest : latest.emplace();
      const auto copy = [](std::vector<float>& dst, const dds_sequence_float& src) {
        dst.assign(src._buffer, src._buffer + src._length);
      };
      s.run_id = d.run_id;
      s.step = std::size_t(d.step);
      s.time = d.time;
      s.dim = d.dim;
      s.total_points = std::size_t(d.total_points);
      copy(s.x, d.x);
      copy(s.y, d.y);
      copy(s.z, d.z);
      copy(s.damage, d.damage);
      ++snapshots_received;
    });
  }

  // Polls until `ready()` or the deadline; the waitset sleeps until data arrives.
  template <class Ready>
  void wait_until(std::chrono::milliseconds timeout, Ready&& ready) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      poll();
      const auto left = deadline - std::chrono::steady_clock::now();
      if (ready() || left <= std::chrono::steady_clock::duration::zero()) return;
      const auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(left).count();
      if (const auto rc = dds_waitset_wait(waitset.get(), nullptr, 0, ns); rc < 0) dds::fail("waiting for samples", rc);
    }
  }
};

LiveSubscriber::LiveSubscriber(const LiveOptions& options) : impl_(std::make_unique<Impl>(options)) {}
LiveSubscriber::~LiveSubscriber() = default;

std::vector<RunSummarySample> LiveSubscriber::wait_summaries(std::chrono::milliseconds timeout) {
  impl_->wait_until(timeout, [&] { return !impl_->pending.empty(); });
  return std::exchange(impl_->pending, {});
}

std::optional<FieldSnapshotSample> LiveSubscriber::wait_snapshot(std::chrono::milliseconds timeout) {
  const std::size_t seen = impl_->snapshots_returned;
  impl_->wait_until(timeout, [&] { return impl_->snapshots_received > seen; });
  if (impl_->snapshots_received == seen) return std::nullopt;
  impl_->snapshots_returned = impl_->snapshots_received;
  return impl_->latest;
}

std::optional<FieldSnapshotSample> LiveSubscriber::latest_snapshot() {
  impl_->poll();
  impl_->snapshots_returned = impl_->snapshots_received;
  return impl_->latest;
}

const std::string& LiveSubscriber::run_id() const { return impl_->options.run_id; }

std::size_t LiveSubscriber::publisher_count() const {
  dds_subscription_matched_status_t st{};
  if (dds_get_subscription_matched_status(impl_->summary_reader.get(), &st) < 0) return 0;
  return st.current_count;
}

}  // namespace peridot
