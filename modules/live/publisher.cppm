module;
#include <dds/dds.h>
#include "peridot_live.h"
export module peridot.live:publisher;
import peridot.std;
import :options;
import :dds;

export namespace peridot {

// Publishes a run's summaries and field snapshots.
//
// Never stalls the solver: publish_* only copy the sample into a mailbox and
// wake a background thread that does the DDS writes. Summaries queue in a
// fixed ring (the oldest is dropped if 64 pile up behind a blocked writer);
// snapshots sit in a one-slot mailbox where a newer one replaces a stale one.
// Call publish_* from one thread (the solver's).
class LivePublisher {
 public:
  explicit LivePublisher(const LiveOptions& options);
  // Reports the run as failed if finish() was never called (e.g. an exception).
  ~LivePublisher();
  LivePublisher(const LivePublisher&) = delete;
  LivePublisher& operator=(const LivePublisher&) = delete;

  void publish_summary(const RunSummarySample& sample);
  // Positions and damage of all n points (z may be empty in 2D); every k-th
  // point is kept so that at most snapshot_max_points go out. decimated_from > 0: the points
  // are already every snapshot_stride(decimated_from, snapshot_max_points)-th point of a cloud
  // of that many (N ranks gather only those) and all go out.
  void publish_snapshot(int dim, std::span<const double> x, std::span<const double> y, std::span<const double> z,
                        std::span<const double> damage, std::size_t step, double time, std::size_t decimated_from = 0);
  // Sends the last summary again with status finished (ok) or failed and the
  // message, flushes, and waits up to options.linger for watchers to acknowledge.
  void finish(bool ok, std::string message);

  const std::string& run_id() const;
  // Watchers currently matched on the summary topic.
  std::size_t subscriber_count() const;
  // Samples lost to a full queue or a write error (summaries), or replaced
  // before they were sent (snapshots).
  std::size_t dropped_summaries() const;
  std::size_t dropped_snapshots() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace peridot

namespace peridot {

namespace {

struct SnapshotBuffer {
  int dim = 2;
  std::size_t step = 0, total_points = 0;
  double time = 0;
  std::vector<float> x, y, z, damage;
};

constexpr std::size_t summary_queue_capacity = 64;

}  // namespace

struct LivePublisher::Impl {
  LiveOptions options;
  std::shared_ptr<dds::Participant> participant;
  // The group is deleted last: deleting it deletes its writers.
  dds::Entity group, summary_topic, snapshot_topic, summary_writer, snapshot_writer;

  std::mutex mutex;
  std::condition_variable wake;
  std::array<RunSummarySample, summary_queue_capacity> queue;  // ring buffer
  std::size_t head = 0, count = 0;
  SnapshotBuffer staging, slot, sending;  // solver-owned, mailbox, writer-owned
  bool slot_full = false, stop = false;
  std::atomic<std::size_t> dropped_summaries{0}, dropped_snapshots{0};
  RunSummarySample last;  // solver-owned: the base of the final sample (run_id unused)
  bool finished = false;
  std::thread worker;

  explicit Impl(const LiveOptions& o) : options(o) {
    validate(options, true);
    participant = dds::acquire_participant(options);
    const auto sq = dds::summary_qos(true);
    const auto fq = dds::snapshot_qos();
    summary_topic = dds::make_topic(participant->get(), &peridot_live_RunSummary_desc, dds::summary_topic, sq.get());
    snapshot_topic = dds::make_topic(participant->get(), &peridot_live_FieldSnapshot_desc, dds::snapshot_topic, fq.get());
    group = dds::make_group(participant->get(), options, true);
    summary_writer = dds::Entity(
        dds::check(dds_create_writer(group.get(), summary_topic.get(), sq.get(), nullptr), "creating the summary writer"));
    snapshot_writer = dds::Entity(
        dds::check(dds_create_writer(group.get(), snapshot_topic.get(), fq.get(), nullptr), "creating the snapshot writer"));
    worker = std::thread([this] { run(); });
  }

  ~Impl() {
    {
      std::lock_guard lock(mutex);
      stop = true;
    }
    wake.notify_one();
    if (worker.joinable()) worker.join();
  }

  // Background thread: queued summaries first (small, and none may be lost),
  // the snapshot when they are out. When stopping, the last snapshot goes
  // before the final summary, so a watcher has it when it sees the end.
  void run() {
    RunSummarySample current;
    std::unique_lock lock(mutex);
    for (;;) {
      wake.wait(lock, [&] { return stop || count > 0 || slot_full; });
      if (slot_full && (stop || count == 0)) {
        std::swap(slot, sending);
        slot_full = false;
        lock.unlock();
        write_snapshot(sending);
        lock.lock();
      } else if (count > 0) {
        std::swap(current, queue[head]);
        head = (head + 1) % summary_queue_capacity;
        --count;
        lock.unlock();
        const auto d = dds::to_dds(current);
        if (dds_write(summary_writer.get(), &d) < 0) ++dropped_summaries;
        lock.lock();
      } else if (stop) {
        return;
      }
    }
  }

  void write_snapshot(SnapshotBuffer& b) {
    const auto seq = [](std::vector<float>& v) {
      return dds_sequence_float{std::uint32_t(v.size()), std::uint32_t(v.size()), v.data(), false};
    };
    peridot_live_FieldSnapshot d{};
    d.run_id = const_cast<char*>(options.run_id.c_str());
    d.step = b.step;
    d.time = b.time;
    d.dim = b.dim;
    d.total_points = b.total_points;
    d.x = seq(b.x);
    d.y = seq(b.y);
    d.z = seq(b.z);
    d.damage = seq(b.damage);
    if (dds_write(snapshot_writer.get(), &d) < 0) ++dropped_snapshots;
  }

  // Call with `mutex` held.
  void push(const RunSummarySample& s) {
    if (count == summary_queue_capacity) {  // the writer is stuck: drop the oldest
      head = (head + 1) % summary_queue_capacity;
      --count;
      ++dropped_summaries;
    }
    auto& dst = queue[(head + count) % summary_queue_capacity];
    dst = s;  // string capacity is reused, so no allocation once warm
    dst.run_id = options.run_id;
    ++count;
  }
};

LivePublisher::LivePublisher(const LiveOptions& options) : impl_(std::make_unique<Impl>(options)) {}

LivePublisher::~LivePublisher() {
  if (!impl_->finished) {
    try {
      finish(false, "the run ended without reporting a final status");
    } catch (...) {  // a destructor must not throw; the watcher then times out
    }
  }
}

const std::string& LivePublisher::run_id() const { return impl_->options.run_id; }

void LivePublisher::publish_summary(const RunSummarySample& sample) {
  if (impl_->finished) throw std::logic_error("LivePublisher::publish_summary after finish()");
  impl_->last = sample;
  {
    std::lock_guard lock(impl_->mutex);
    impl_->push(sample);
  }
  impl_->wake.notify_one();
}

void LivePublisher::publish_snapshot(int dim, std::span<const double> x, std::span<const double> y,
                                     std::span<const double> z, std::span<const double> damage, std::size_t step,
                                     double time, std::size_t decimated_from) {
  if (impl_->finished) throw std::logic_error("LivePublisher::publish_snapshot after finish()");
  if (dim != 2 && dim != 3) throw std::invalid_argument(fmt::format("snapshot dim = {}: must be 2 or 3", dim));
  const std::size_t n = damage.size();
  if (x.size() != n || y.size() != n || (dim == 3 && z.size() != n))
    throw std::invalid_argument(fmt::format("snapshot fields differ in length: x {}, y {}, z {}, damage {}", x.size(),
                                            y.size(), z.size(), n));
  const std::size_t stride = decimated_from ? 1 : snapshot_stride(n, impl_->options.snapshot_max_points);
  const std::size_t m = (n + stride - 1) / stride;
  auto& b = impl_->staging;
  const auto take = [&](std::vector<float>& dst, std::span<const double> src) {
    dst.resize(src.empty() ? 0 : m);  // capacity is kept between calls
    for (std::size_t k = 0; k < dst.size(); ++k) dst[k] = float(src[k * stride]);
  };
  take(b.x, x);
  take(b.y, y);
  take(b.z, dim == 3 ? z : std::span<const double>{});
  take(b.damage, damage);
  b.dim = dim;
  b.step = step;
  b.time = time;
  b.total_points = decimated_from ? decimated_from : n;
  {
    std::lock_guard lock(impl_->mutex);
    if (impl_->slot_full) ++impl_->dropped_snapshots;  // superseded before it was sent
    std::swap(impl_->staging, impl_->slot);
    impl_->slot_full = true;
  }
  impl_->wake.notify_one();
}

void LivePublisher::finish(bool ok, std::string message) {
  auto& im = *impl_;
  if (im.finished) return;
  im.finished = true;
  im.last.status = ok ? RunStatus::finished : RunStatus::failed;
  im.last.message = std::move(message);
  {
    std::lock_guard lock(im.mutex);  // one step, so the worker sees both at once
    im.push(im.last);
    im.stop = true;  // the worker drains the snapshot and the queue, then exits
  }
  im.wake.notify_one();
  im.worker.join();
  // Returns at once when no watcher is matched; the run has ended, so waiting here stalls nothing.
  dds_wait_for_acks(im.summary_writer.get(), DDS_MSECS(im.options.linger.count()));
}

std::size_t LivePublisher::subscriber_count() const {
  dds_publication_matched_status_t st{};
  if (dds_get_publication_matched_status(impl_->summary_writer.get(), &st) < 0) return 0;
  return st.current_count;
}

std::size_t LivePublisher::dropped_summaries() const { return impl_->dropped_summaries; }
std::size_t LivePublisher::dropped_snapshots() const { return impl_->dropped_snapshots; }

}  // namespace peridot
