module;
#include <dds/dds.h>
#include "peridot_live.h"
export module peridot.live:dds;
import peridot.std;
import :options;

// Thin RAII over the Cyclone C API, shared by the publisher and the subscriber.
// Nothing here is exported: callers of peridot.live never see DDS types.
namespace peridot::dds {

constexpr const char* summary_topic = "peridot_run_summary";
constexpr const char* snapshot_topic = "peridot_field_snapshot";
// Summary history kept by the writer for watchers that join late (transient-local).
constexpr int summary_depth = 16;
// Deeper on the reader so a watcher that polls slowly loses nothing.
constexpr int summary_reader_depth = 64;

[[noreturn]] inline void fail(const std::string& what, dds_return_t rc) {
  throw std::runtime_error(fmt::format("DDS: {} failed: {}", what, dds_strretcode(rc)));
}

inline dds_entity_t check(dds_entity_t e, const std::string& what) {
  if (e < 0) fail(what, e);
  return e;
}

// Owns one DDS entity; deleting it deletes its children too.
class Entity {
 public:
  Entity() = default;
  explicit Entity(dds_entity_t e) : e_(e) {}
  Entity(Entity&& o) noexcept : e_(std::exchange(o.e_, 0)) {}
  Entity& operator=(Entity&& o) noexcept {
    if (this != &o) {
      reset();
      e_ = std::exchange(o.e_, 0);
    }
    return *this;
  }
  ~Entity() { reset(); }
  void reset() {
    if (e_ > 0) dds_delete(e_);
    e_ = 0;
  }
  dds_entity_t get() const { return e_; }

 private:
  dds_entity_t e_ = 0;
};

using Qos = std::unique_ptr<dds_qos_t, decltype(&dds_delete_qos)>;

// Run summaries: every line matters and the final one must arrive, so reliable;
// keep-last bounds memory; transient-local hands the recent history (and the
// final status) to a watcher that starts after the run. Only the publisher's
// background thread ever blocks on it, for at most max_blocking.
inline Qos summary_qos(bool writer) {
  Qos q(dds_create_qos(), &dds_delete_qos);
  dds_qset_reliability(q.get(), DDS_RELIABILITY_RELIABLE, DDS_MSECS(50));
  dds_qset_history(q.get(), DDS_HISTORY_KEEP_LAST, writer ? summary_depth : summary_reader_depth);
  dds_qset_durability(q.get(), DDS_DURABILITY_TRANSIENT_LOCAL);
  // Cyclone sizes what a transient-local writer keeps for late joiners from the
  // durability-service history (default: last 1), not from the history QoS.
  if (writer)
    dds_qset_durability_service(q.get(), 0, DDS_HISTORY_KEEP_LAST, summary_depth, DDS_LENGTH_UNLIMITED,
                                DDS_LENGTH_UNLIMITED, DDS_LENGTH_UNLIMITED);
  return q;
}

// Field snapshots: large and superseded by the next one, so best-effort (a lost
// fragment drops one snapshot instead of stalling on retransmits), keep-last 1
// and volatile (an old field is of no use to a late watcher).
inline Qos snapshot_qos() {
  Qos q(dds_create_qos(), &dds_delete_qos);
  dds_qset_reliability(q.get(), DDS_RELIABILITY_BEST_EFFORT, 0);
  dds_qset_history(q.get(), DDS_HISTORY_KEEP_LAST, 1);
  dds_qset_durability(q.get(), DDS_DURABILITY_VOLATILE);
  return q;
}

// One domain and participant per (process, domain id), shared by every
// publisher and subscriber in the process. The first user's configuration
// creates the domain; it lives while anyone holds the participant.
class Participant {
 public:
  Participant(int domain_id, const std::string& config) {
    const dds_entity_t d = dds_create_domain(dds_domainid_t(domain_id), config.c_str());
    // PRECONDITION_NOT_MET: the domain already exists in this process (created
    // by someone else), and its configuration stays as it is.
    if (d < 0 && d != DDS_RETCODE_PRECONDITION_NOT_MET)
      fail(fmt::format("creating domain {} with config '{}'", domain_id, config), d);
    if (d > 0) domain_ = Entity(d);
    participant_ = Entity(check(dds_create_participant(dds_domainid_t(domain_id), nullptr, nullptr),
                                fmt::format("creating a participant in domain {}", domain_id)));
  }
  ~Participant() {
    participant_.reset();  // before the domain that holds it
    domain_.reset();
  }
  Participant(const Participant&) = delete;
  Participant& operator=(const Participant&) = delete;
  dds_entity_t get() const { return participant_.get(); }

 private:
  Entity domain_, participant_;
};

inline std::shared_ptr<Participant> acquire_participant(const LiveOptions& options) {
  static std::mutex mutex;
  static std::map<int, std::weak_ptr<Participant>> live;
  std::lock_guard lock(mutex);
  if (auto p = live[options.domain_id].lock()) return p;
  auto p = std::make_shared<Participant>(options.domain_id, dds_config(options));
  live[options.domain_id] = p;
  return p;
}

// The publisher or subscriber that writers or readers hang from, in options.partition
// (none set: the default partition, as a participant's implicit ones).
inline Entity make_group(dds_entity_t participant, const LiveOptions& options, bool publisher) {
  Qos q(dds_create_qos(), &dds_delete_qos);
  if (!options.partition.empty()) dds_qset_partition1(q.get(), options.partition.c_str());
  const dds_entity_t e = publisher ? dds_create_publisher(participant, q.get(), nullptr)
                                   : dds_create_subscriber(participant, q.get(), nullptr);
  return Entity(check(e, fmt::format("creating a {} in partition '{}'", publisher ? "publisher" : "subscriber",
                                     options.partition)));
}

inline Entity make_topic(dds_entity_t participant, const dds_topic_descriptor_t* desc, const char* name,
                         const dds_qos_t* qos) {
  return Entity(check(dds_create_topic(participant, desc, name, qos, nullptr), fmt::format("creating topic {}", name)));
}

inline peridot_live_RunStatus to_dds(RunStatus s) {
  switch (s) {
    case RunStatus::running: return peridot_live_RUNNING;
    case RunStatus::finished: return peridot_live_FINISHED;
    case RunStatus::failed: return peridot_live_FAILED;
  }
  return peridot_live_FAILED;
}

inline RunStatus from_dds(peridot_live_RunStatus s) {
  switch (s) {
    case peridot_live_RUNNING: return RunStatus::running;
    case peridot_live_FINISHED: return RunStatus::finished;
    case peridot_live_FAILED: return RunStatus::failed;
  }
  return RunStatus::failed;
}

// The C sample borrows the strings of `s` (dds_write serialises before returning).
inline peridot_live_RunSummary to_dds(const RunSummarySample& s) {
  peridot_live_RunSummary d{};
  d.run_id = const_cast<char*>(s.run_id.c_str());
  d.step = s.record.step;
  d.time = s.record.time;
  d.wall_time = s.record.wall_time;
  d.kinetic_energy = s.record.kinetic_energy;
  d.strain_energy = s.record.strain_energy;
  d.external_work = s.record.external_work;
  d.broken_bonds = s.record.broken_bonds;
  d.damage_fraction = s.record.damage_fraction;
  d.fragment_count = std::int32_t(s.record.fragments);
  d.tip_x = s.record.tip_x;
  d.tip_y = s.record.tip_y;
  d.tip_speed = s.record.tip_speed;
  d.status = to_dds(s.status);
  d.message = const_cast<char*>(s.message.c_str());
  d.front_length = s.record.front_length;
  d.front_mean_advance = s.record.front_mean_advance;
  d.front_max_advance = s.record.front_max_advance;
  d.front_max_speed = s.record.front_max_speed;
  d.front_branched_slices = std::int32_t(s.record.front_branched_slices);
  const auto n = std::uint32_t(s.front_points.size());
  d.front_points = {n, n, const_cast<double*>(s.front_points.data()), false};
  return d;
}

inline RunSummarySample from_dds(const peridot_live_RunSummary& d) {
  RunSummarySample s;
  s.run_id = d.run_id ? d.run_id : "";
  s.record.step = std::size_t(d.step);
  s.record.time = d.time;
  s.record.wall_time = d.wall_time;
  s.record.kinetic_energy = d.kinetic_energy;
  s.record.strain_energy = d.strain_energy;
  s.record.external_work = d.external_work;
  s.record.broken_bonds = std::size_t(d.broken_bonds);
  s.record.damage_fraction = d.damage_fraction;
  s.record.fragments = d.fragment_count;
  s.record.tip_x = d.tip_x;
  s.record.tip_y = d.tip_y;
  s.record.tip_speed = d.tip_speed;
  s.status = from_dds(d.status);
  s.message = d.message ? d.message : "";
  s.record.front_length = d.front_length;
  s.record.front_mean_advance = d.front_mean_advance;
  s.record.front_max_advance = d.front_max_advance;
  s.record.front_max_speed = d.front_max_speed;
  s.record.front_branched_slices = d.front_branched_slices;
  s.front_points.assign(d.front_points._buffer, d.front_points._buffer + d.front_points._length);
  return s;
}

}  // namespace peridot::dds
