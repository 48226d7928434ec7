// The front of a 3D crack: a curve, reported slice by slice through the thickness.
export module peridot.analysis:crack_front;
import peridot.std;
import peridot.models;
import :crack_tip;

export namespace peridot {

// Lengths in metres, times in seconds, speeds in m/s.
struct CrackFrontOptions {
  int axis = 2;                     // the slices are layers across this axis (the thickness)
  Vec3 direction{1, 0, 0};          // the crack advances along this (any length, not zero, not along axis)
  Vec3 origin{0, 0, 0};             // [m] advance is measured from here (a notch tip)
  double damage_threshold = 0.35;   // [-] a point is cracked when its damage reaches this
  double slice_thickness = 0;       // [m] 0: the cloud's point spacing, one lattice layer per slice
};

// Where the crack of one slice branched (its 2D tip tracker's BranchEvent, back in 3D).
struct FrontBranch {
  std::size_t slice = 0;
  double time = 0;       // [s] when that slice's tip passed the branch point
  Vec3 position{};       // [m]
};

// One sample of the front.
struct FrontSample {
  double time = 0;                       // [s]
  std::size_t slices = 0;                // layers across the axis
  std::vector<std::optional<Vec3>> front;  // per slice: its cracked point farthest along direction, or none
  std::size_t cracked_slices = 0;        // slices with a front point
  double length = 0;                     // [m] the polyline through the front points, slice after slice
  double mean_advance = 0, max_advance = 0;  // [m] (p - origin) . direction over the cracked slices
  // [m/s] the advance since the previous sample over the time between them, per slice cracked
  // in both (0 on the first sample): their mean and the largest.
  double mean_speed = 0, max_speed = 0;
  // Slices whose crack has branched so far, and the earliest of their branches. Each slice is
  // a 2D crack followed from the origin by its own CrackTipTracker (its default lengths from
  // the point spacing), so a front that splits shows in every layer it split in.
  std::size_t branched_slices = 0;
  std::optional<FrontBranch> first_branch;
};

// Follows the front from sample to sample: update() takes the damage of a step.
class CrackFrontTracker {
 public:
  explicit CrackFrontTracker(CrackFrontOptions options = {});
  // extent: the body's [min, max] along the axis, when `points` are only some of its points
  // (the cracked ones, gathered from N ranks); otherwise the points' own.
  const FrontSample& update(const PointCloud& points, std::span<const double> damage, double time,
                            const std::array<double, 2>* extent = nullptr);
  const std::optional<FrontSample>& last() const { return last_; }
  double max_speed() const { return max_speed_; }  // the largest per-sample max_speed so far

 private:
  CrackFrontOptions o_;
  Vec3 e_{};  // unit direction
  std::optional<FrontSample> last_;
  double max_speed_ = 0;
  std::vector<CrackTipTracker> tips_;  // one per slice, made at the first update

  void branches(const PointCloud& points, std::span<const double> damage, double time, double lo, double thickness, FrontSample& s);
};

}  // namespace peridot

namespace peridot {

CrackFrontTracker::CrackFrontTracker(CrackFrontOptions o) : o_(o) {
  if (o_.axis < 0 || o_.axis > 2) throw std::invalid_argument("crack front: axis must be 0, 1 or 2 (x, y, z)");
  Vec3 d = o_.direction;
  d[std::size_t(o_.axis)] = 0;  // the advance is measured within a slice
  const double n = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  if (!(n > 0)) throw std::invalid_argument("crack front: the direction must have a component across the slicing axis");
  e_ = {d[0] / n, d[1] / n, d[2] / n};
}

const FrontSample& CrackFrontTracker::update(const PointCloud& pc, std::span<const double> damage, double time,
                                             const std::array<double, 2>* extent) {
  if (damage.size() != pc.size()) throw std::invalid_argument("crack front: one damage value per point");
  const auto a = std::size_t(o_.axis);
  const double t = o_.slice_thickness > 0 ? o_.slice_thickness : pc.spacing;
  if (!(t > 0)) throw std::invalid_argument("crack front: slice thickness unknown (the cloud has no spacing)");
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (std::size_t i = 0; i < pc.size(); ++i) lo = std::min(lo, pc.x[a][i]), hi = std::max(hi, pc.x[a][i]);
  if (extent) lo = (*extent)[0], hi = (*extent)[1];
  FrontSample s;
  s.time = time;
  s.slices = pc.size() || extent ? std::size_t(std::floor((hi - lo) / t + 0.5)) + 1 : 0;
  s.front.assign(s.slices, std::nullopt);
  std::vector<double> advance(s.slices, -std::numeric_limits<double>::infinity());
  for (std::size_t i = 0; i < pc.size(); ++i) {
    if (!(damage[i] >= o_.damage_threshold)) continue;
    const auto k = std::min(s.slices - 1, std::size_t(std::floor((pc.x[a][i] - lo) / t + 0.5)));
    const Vec3 p = pc.position(i);
    const double along = (p[0] - o_.origin[0]) * e_[0] + (p[1] - o_.origin[1]) * e_[1] + (p[2] - o_.origin[2]) * e_[2];
    if (along > advance[k]) advance[k] = along, s.front[k] = p;
  }
  const std::optional<Vec3>* previous = nullptr;
  double speed_sum = 0;
  std::size_t timed = 0;
  for (std::size_t k = 0; k < s.slices; ++k) {
    if (!s.front[k]) continue;
    ++s.cracked_slices;
    s.mean_advance += advance[k];
    s.max_advance = s.cracked_slices == 1 ? advance[k] : std::max(s.max_advance, advance[k]);
    if (previous) {
      const Vec3& p = **previous;
      const Vec3& q = *s.front[k];
      s.length += std::sqrt((q[0] - p[0]) * (q[0] - p[0]) + (q[1] - p[1]) * (q[1] - p[1]) + (q[2] - p[2]) * (q[2] - p[2]));
    }
    previous = &s.front[k];
    if (last_ && last_->slices == s.slices && last_->front[k] && time > last_->time) {
      const Vec3& p = *last_->front[k];
      const double before = (p[0] - o_.origin[0]) * e_[0] + (p[1] - o_.origin[1]) * e_[1] + (p[2] - o_.origin[2]) * e_[2];
      const double v = (advance[k] - before) / (time - last_->time);
      speed_sum += v;
      s.max_speed = timed == 0 ? v : std::max(s.max_speed, v);
      ++timed;
    }
  }
  branches(pc, damage, time, lo, t, s);
  if (s.cracked_slices) s.mean_advance /= double(s.cracked_slices);
  if (timed) s.mean_speed = speed_sum / double(timed);
  max_speed_ = std::max(max_speed_, s.max_speed);
  last_ = std::move(s);
  return *last_;
}

namespace {

// The two axes of a slice across `axis`, in cyclic order, so (u, v, axis) is right-handed.
std::array<std::size_t, 2> in_plane(std::size_t axis) { return {(axis + 1) % 3, (axis + 2) % 3}; }

Vec3 to_plane(const Vec3& p, std::size_t axis) {
  const auto [u, v] = in_plane(axis);
  return {p[u], p[v], 0};
}

}  // namespace

void CrackFrontTracker::branches(const PointCloud& pc, std::span<const double> damage, double time, double lo, double thickness, FrontSample& s) {
  const auto a = std::size_t(o_.axis);
  if (tips_.size() != s.slices) {
    tips_.clear();
    const CrackTipOptions options{.damage_threshold = o_.damage_threshold, .origin = to_plane(o_.origin, a), .direction = to_plane(e_, a)};
    tips_.assign(s.slices, CrackTipTracker(options));
  }
  // Each slice as a 2D cloud in its own plane.
  std::vector<PointCloud> slice(s.slices);
  std::vector<std::vector<double>> phi(s.slices);
  for (auto& c : slice) c.spacing = pc.spacing;
  for (std::size_t i = 0; i < pc.size(); ++i) {
    const auto k = std::min(s.slices - 1, std::size_t(std::floor((pc.x[a][i] - lo) / thickness + 0.5)));
    slice[k].push_back(to_plane(pc.position(i), a), pc.volume[i]);
    phi[k].push_back(damage[i]);
  }
  const auto [u, v] = in_plane(a);
  for (std::size_t k = 0; k < s.slices; ++k) {
    if (slice[k].size() == 0) continue;
    tips_[k].update(slice[k], phi[k], time);
    const auto b = tips_[k].branch();
    if (!b) continue;
    ++s.branched_slices;
    if (s.first_branch && s.first_branch->time <= b->time) continue;
    Vec3 p{};
    p[u] = b->position[0];
    p[v] = b->position[1];
    p[a] = lo + double(k) * thickness;
    s.first_branch = FrontBranch{k, b->time, p};
  }
}

}  // namespace peridot
