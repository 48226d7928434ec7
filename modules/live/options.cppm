module;
#include <peridot/run_record.hpp>
export module peridot.live:options;
import peridot.std;

export namespace peridot {

struct LiveOptions {
  // Publisher: the run's name, required. Subscriber: the run to follow; empty
  // follows the first run that shows up.
  std::string run_id;
  // DDS domain; publisher and watcher must agree. Cyclone allows 0..230.
  int domain_id = 0;
  // DDS partition; publisher and watcher must agree. Empty: the default partition.
  // Runs (or tests) on one domain that must not see each other's watchers take
  // partitions of their own: a name of printable characters, no wildcards.
  std::string partition;
  // Snapshots are decimated to at most this many points (>= 1), which keeps a
  // 3D sample of four float fields under 16 bytes x 20000 = 320 KB.
  std::size_t snapshot_max_points = 20000;
  // Cyclone DDS configuration (file URI, path or XML). Unset: see dds_config().
  std::optional<std::string> config_uri;
  // How long LivePublisher::finish() waits for watchers to acknowledge the
  // final summary, so that a run that exits at once is still seen to finish.
  std::chrono::milliseconds linger{2000};
};

enum class RunStatus { running, finished, failed };

// One summary of a run: the run record (peridot/run_record.hpp, the one list of its fields)
// plus what only the live topic carries. Plain C++ so callers never see DDS types.
struct RunSummarySample {
  std::string run_id;  // filled in by the publisher
  RunRecord record;
  // The 3D crack front per slice: x, y, z [m] of slice k at 3k..3k+2, NaN where the slice is not
  // cracked; empty when the run tracks no front (IDL RunSummary.front_points).
  std::vector<double> front_points;
  RunStatus status = RunStatus::running;
  std::string message;  // why a run failed; empty while running
};

// A decimated nodal field as received; z is empty in 2D.
struct FieldSnapshotSample {
  std::string run_id;
  std::size_t step = 0;
  double time = 0;
  int dim = 2;
  std::size_t total_points = 0;  // points before decimation
  std::vector<float> x, y, z, damage;
  std::size_t size() const { return damage.size(); }
};

std::string_view to_string(RunStatus status);

// The Cyclone configuration to use, in this order: options.config_uri, then
// $CYCLONEDDS_URI (the user's choice wins over Peridot's), then
// $PERIDOT_DDS_CONFIG, then the loopback-only data/dds/loopback.xml of the
// source tree. A plain path is turned into a file:// URI and must exist.
std::string dds_config(const LiveOptions& options);

// Keep every stride-th point: the smallest stride with ceil(n / stride) <= max_points.
std::size_t snapshot_stride(std::size_t n, std::size_t max_points);

}  // namespace peridot

namespace peridot {

// Throws std::invalid_argument naming the field when options are out of range.
void validate(const LiveOptions& options, bool need_run_id);

std::string_view to_string(RunStatus status) {
  switch (status) {
    case RunStatus::running: return "running";
    case RunStatus::finished: return "finished";
    case RunStatus::failed: return "failed";
  }
  return "unknown";
}

namespace {

// XML and URIs go to Cyclone unchanged; a bare path must name a readable file.
std::string as_config(const std::string& value, std::string_view source) {
  if (value.empty()) throw std::invalid_argument(fmt::format("{} is empty: expected a Cyclone DDS config file or URI", source));
  if (value.front() == '<' || value.find("://") != std::string::npos) return value;
  if (!std::filesystem::is_regular_file(value))
    throw std::invalid_argument(fmt::format("{} = '{}': no such Cyclone DDS config file", source, value));
  return "file://" + std::filesystem::absolute(value).string();
}

}  // namespace

std::string dds_config(const LiveOptions& options) {
  if (options.config_uri) return as_config(*options.config_uri, "live config_uri");
  if (const char* uri = std::getenv("CYCLONEDDS_URI"); uri && *uri) return uri;
  if (const char* path = std::getenv("PERIDOT_DDS_CONFIG"); path && *path) return as_config(path, "PERIDOT_DDS_CONFIG");
  return as_config(PERIDOT_DDS_DEFAULT_CONFIG, "the default DDS config (set PERIDOT_DDS_CONFIG if the source tree moved)");
}

std::size_t snapshot_stride(std::size_t n, std::size_t max_points) {
  if (max_points == 0) throw std::invalid_argument("snapshot_max_points must be >= 1");
  return n <= max_points ? 1 : (n + max_points - 1) / max_points;
}

void validate(const LiveOptions& options, bool need_run_id) {
  if (need_run_id && options.run_id.empty()) throw std::invalid_argument("live run_id must not be empty");
  if (options.domain_id < 0 || options.domain_id > 230)
    throw std::invalid_argument(fmt::format("live domain_id = {}: must be in 0..230", options.domain_id));
  if (options.partition.size() > 200)
    throw std::invalid_argument(fmt::format("live partition is {} characters long: at most 200", options.partition.size()));
  for (const char c : options.partition)
    if (c < 0x21 || c > 0x7e || c == '*' || c == '?' || c == '[' || c == ']' || c == '\\')
      throw std::invalid_argument(fmt::format(
          "live partition '{}': printable characters without blanks or the wildcards * ? [ ] \\", options.partition));
  if (options.snapshot_max_points == 0) throw std::invalid_argument("live snapshot_max_points must be >= 1");
  if (options.linger.count() < 0) throw std::invalid_argument("live linger must be >= 0 ms");
}

}  // namespace peridot
