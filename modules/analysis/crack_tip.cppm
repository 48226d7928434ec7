export module peridot.analysis:crack_tip;
import peridot.std;
import peridot.models;

export namespace peridot {

// Crack-tip tracking for 2D runs. Lengths in metres, times in seconds, speeds in m/s.
// Options left at 0 are derived from the point spacing h of the cloud passed to update().
struct CrackTipOptions {
  double damage_threshold = 0.35;  // [-] points with damage above this are cracked (seed 000: 0.35); >= 0: broken-bond
                                   // damage lies in [0, 1], RNP's bond-strain ratio Z is unbounded and cracks at Z >= 1
  Vec3 origin{0, 0, 0};            // [m] notch tip or any point on the crack path
  // Set: the tip is the cracked point farthest along this direction (any length, not zero).
  // Unset: the tip is the cracked point farthest from origin.
  std::optional<Vec3> direction;
  // [m] the crack is the set of cracked points chained to origin by steps no longer than
  // link_distance, starting from cracked points within seed_radius of origin; damage
  // elsewhere (loaded edges, other cracks) is ignored. 0: link 2 h, seed 5 h.
  double link_distance = 0;
  double seed_radius = 0;
  // [m] two arms count as separate once the gap between their cracked bands exceeds this, or,
  // for an arm that stopped, once a point of it lies this far from the other band (about 3
  // horizons). 0: 9 h, three horizons at the usual delta = 3 h.
  double branch_min_separation = 0;
  // [m] how far behind the tip arms are looked for. 0: 3 * branch_min_separation.
  double branch_window = 0;
  // Tip samples the speed is fitted over: the least-squares velocity of the last
  // speed_window + 1 tip positions; 1: the plain difference of consecutive tips. Averaging
  // over a few samples keeps the jitter of the extreme point out of max_speed().
  std::size_t speed_window = 3;
  // With a direction: the speed is the fitted velocity's component along it (floored at 0),
  // not its magnitude. For a straight crack whose Z >= 1 band is wide (RNP, seed 003), the
  // farthest point jumps sideways across the band and would count as speed.
  bool speed_along_direction = false;
};

struct TipSample {
  double time = 0;      // [s]
  Vec3 position{};      // [m]
  double speed = 0;     // [m/s], 0 on the first sample; fitted over fewer samples until the window fills
  double length = 0;    // [m] path length of the tip since the first sample
};

struct BranchEvent {
  double time = 0;           // [s] when the tip passed the branch point (interpolated in the history)
  Vec3 position{};           // [m] where the arms' centre lines meet
  double detected_time = 0;  // [s] the update at which the arms were first seen apart
};

// What the papers' tables compare: branch location and time, maximum and average speed.
struct TipSummary {
  bool initiated = false;
  double initiation_time = 0;        // [s] first sample with a crack
  Vec3 tip{};                        // [m] last tip position
  double length = 0;                 // [m] tip path length
  double max_speed = 0;              // [m/s] see CrackTipTracker::max_speed()
  double mean_speed = 0;             // [m/s] time average since initiation (once the speed window fills)
  double mean_speed_before_branch = 0;  // [m/s] time average up to the branch time (= mean_speed without one)
  std::optional<BranchEvent> branch;
  std::size_t samples = 0;
};

// Follows the tip of one 2D crack through a run: call update() at each output step, then
// summary() for the numbers the papers tabulate.
// Branching: the crack is cut into slices across the propagation axis (direction, or origin
// to tip), each split at its widest transverse gap. A branch is reported the first time two
// slices within branch_window of the tip show bands farther apart than
// branch_min_separation, or, when the split ends more than that behind the tip (one arm
// stopped), two slices hold a point of one band that far from the other band. The branch point is where straight lines fitted to the two arms
// meet (else the last slice where the crack was one band); its time is when the tip passed
// it. From then on the tip follows the arm that was leading, and samples taken on the other
// arm between the branch and its detection are dropped from the history.
class CrackTipTracker {
 public:
  explicit CrackTipTracker(CrackTipOptions options = {});

  // Records a sample when a crack exists; times must increase. Returns the new sample.
  std::optional<TipSample> update(const PointCloud& points, std::span<const double> damage, double time);

  std::optional<TipSample> current() const;
  const std::vector<TipSample>& history() const { return history_; }
  std::optional<BranchEvent> branch() const { return branch_; }
  // Over the samples whose speed window is full (every sample after the first for a window of 1).
  double max_speed() const;
  double mean_speed() const;  // time-weighted
  TipSummary summary() const;
  const CrackTipOptions& options() const { return options_; }

 private:
  struct Lengths {
    double link, seed, separation, window;
  };
  struct Slice {  // one slice across the axis: its points split at the widest gap
    bool empty = true;
    bool split = false;
    double gap = 0;
    // The farther of the two bands' outer edges from the other band's near edge. An arm that
    // leaves steeply and stops spans a slice's height, so its gap to the other arm stays small
    // while its far end lies well away from it.
    double reach = 0;
    double s = 0;                   // axial position of the slice centre
    double t_low = 0, t_high = 0;   // mean transverse position below / above the gap
    double t_mean = 0;
  };

  Lengths lengths(const PointCloud& points) const;
  void collect_crack(const PointCloud& points, std::span<const double> damage, const Lengths& len);
  void detect_branch(const PointCloud& points, const Vec3& tip, const Lengths& len, double time);
  void slice_crack(const PointCloud& points, const Vec3& e, const Vec3& n, double s_tip, double w);
  double time_at_projection(const Vec3& e, double s) const;
  void refresh(std::size_t k);
  void follow_leading_arm(const Vec3& tip, const Vec3& e, const Vec3& n);
  bool on_trailing_arm(const Vec3& p) const;
  double mean_speed_until(double t_end) const;

  CrackTipOptions options_;
  std::vector<TipSample> history_;
  std::optional<BranchEvent> branch_;
  Vec3 branch_axis_{}, branch_side_{};  // after a branch: points past it on the trailing arm's side are skipped
  double last_time_ = -std::numeric_limits<double>::infinity();
  // Scratch reused between updates.
  std::vector<std::int32_t> crack_;
  std::vector<std::pair<std::int64_t, std::int32_t>> cells_;
  std::vector<std::uint8_t> seen_;
  std::vector<std::pair<std::int64_t, double>> sliced_;
  std::vector<std::size_t> slice_start_;
  std::vector<Slice> slices_;
};

}  // namespace peridot

namespace peridot {

namespace {

Vec3 unit(const Vec3& v) {
  const double n = norm(v);
  return {v[0] / n, v[1] / n, v[2] / n};
}

// Least-squares fit t = a + b s; false when the s values do not spread.
bool fit_line(std::span<const std::pair<double, double>> st, double& a, double& b) {
  if (st.size() < 2) return false;
  double ms = 0, mt = 0;
  for (auto [s, t] : st) {
    ms += s;
    mt += t;
  }
  ms /= double(st.size());
  mt /= double(st.size());
  double sss = 0, sst = 0;
  for (auto [s, t] : st) {
    sss += (s - ms) * (s - ms);
    sst += (s - ms) * (t - mt);
  }
  if (!(sss > 0)) return false;
  b = sst / sss;
  a = mt - b * ms;
  return true;
}

std::int64_t cell_key(std::int64_t cx, std::int64_t cy) { return (cx << 32) + (cy & 0xffffffff); }

}  // namespace

CrackTipTracker::CrackTipTracker(CrackTipOptions o) : options_(std::move(o)) {
  const auto fail = [](const std::string& what) { throw std::invalid_argument("crack tip: " + what); };
  if (!(options_.damage_threshold >= 0 && std::isfinite(options_.damage_threshold)))
    fail("damage_threshold must be a finite number >= 0, got " + std::to_string(options_.damage_threshold));
  if (options_.direction) {
    auto& d = *options_.direction;
    d[2] = 0;
    if (!(norm(d) > 0) || !std::isfinite(norm(d))) fail("direction must be a finite, non-zero vector in the xy plane");
    d = unit(d);
  }
  const auto non_negative = [&](double v, const char* name) {
    if (!(v >= 0) || !std::isfinite(v)) fail(std::string(name) + " must be a finite length >= 0 (0: default), got " + std::to_string(v));
  };
  non_negative(options_.link_distance, "link_distance");
  non_negative(options_.seed_radius, "seed_radius");
  non_negative(options_.branch_min_separation, "branch_min_separation");
  non_negative(options_.branch_window, "branch_window");
  if (options_.speed_window < 1) fail("speed_window must be >= 1");
  if (options_.speed_along_direction && !options_.direction) fail("speed_along_direction needs a direction");
}

CrackTipTracker::Lengths CrackTipTracker::lengths(const PointCloud& pc) const {
  const double h = pc.spacing;
  const auto& o = options_;
  const bool need_h = o.link_distance == 0 || o.seed_radius == 0 || o.branch_min_separation == 0;
  if (need_h && !(h > 0))
    throw std::invalid_argument("crack tip: the point cloud has no spacing; set link_distance, seed_radius and "
                                "branch_min_separation explicitly");
  Lengths len{};
  len.link = o.link_distance > 0 ? o.link_distance : 2 * h;
  len.seed = o.seed_radius > 0 ? o.seed_radius : 5 * h;
  len.separation = o.branch_min_separation > 0 ? o.branch_min_separation : 9 * h;
  len.window = o.branch_window > 0 ? o.branch_window : 3 * len.separation;
  return len;
}

// The crack: cracked points reachable from the seeds near origin through links no longer
// than len.link, found by a breadth-first search on a grid of cells of that size.
void CrackTipTracker::collect_crack(const PointCloud& pc, std::span<const double> damage, const Lengths& len) {
  const auto& x = pc.x;
  const double inv = 1.0 / len.link;
  const auto cell = [&](std::size_t i, int k) { return std::int64_t(std::floor(x[k][i] * inv)); };
  cells_.clear();
  for (std::size_t i = 0; i < pc.size(); ++i)
    if (damage[i] > options_.damage_threshold) cells_.push_back({cell_key(cell(i, 0), cell(i, 1)), std::int32_t(i)});
  std::sort(cells_.begin(), cells_.end());

  crack_.clear();
  seen_.assign(cells_.size(), 0);
  const Vec3& o = options_.origin;
  for (std::size_t k = 0; k < cells_.size(); ++k) {
    const auto i = std::size_t(cells_[k].second);
    if (norm(pc.position(i) - o) <= len.seed) {
      seen_[k] = 1;
      crack_.push_back(std::int32_t(k));  // holds positions in cells_ until the search ends
    }
  }
  const double link2 = len.link * len.link;
  for (std::size_t head = 0; head < crack_.size(); ++head) {
    const auto i = std::size_t(cells_[std::size_t(crack_[head])].second);
    const std::int64_t cx = cell(i, 0), cy = cell(i, 1);
    for (std::int64_t dx = -1; dx <= 1; ++dx)
      for (std::int64_t dy = -1; dy <= 1; ++dy) {
        const std::int64_t key = cell_key(cx + dx, cy + dy);
        auto it = std::lower_bound(cells_.begin(), cells_.end(), std::pair{key, std::int32_t(-1)});
        for (; it != cells_.end() && it->first == key; ++it) {
          const auto k = std::size_t(it - cells_.begin());
          if (seen_[k]) continue;
          const auto j = std::size_t(it->second);
          const double ddx = x[0][j] - x[0][i], ddy = x[1][j] - x[1][i];
          if (ddx * ddx + ddy * ddy > link2) continue;
          seen_[k] = 1;
          crack_.push_back(std::int32_t(k));
        }
      }
  }
  for (auto& k : crack_) k = cells_[std::size_t(k)].second;
}

std::optional<TipSample> CrackTipTracker::update(const PointCloud& pc, std::span<const double> damage, double time) {
  if (pc.dim != 2) throw std::invalid_argument("crack tip: tracking needs a 2D point cloud, got dim = " + std::to_string(pc.dim));
  if (damage.size() != pc.size())
    throw std::invalid_argument("crack tip: damage has " + std::to_string(damage.size()) + " values for " +
                                std::to_string(pc.size()) + " points");
  if (!(time > last_time_) || !std::isfinite(time))
    throw std::invalid_argument("crack tip: update times must increase; got " + std::to_string(time) + " after " +
                                std::to_string(last_time_));
  last_time_ = time;
  const Lengths len = lengths(pc);
  collect_crack(pc, damage, len);

  // The tip: the extreme crack point, restricted after a branch to the arm that led.
  const Vec3& o = options_.origin;
  double best = -std::numeric_limits<double>::infinity();
  std::optional<Vec3> tip;
  for (const auto i : crack_) {
    const Vec3 p = pc.position(std::size_t(i));
    if (on_trailing_arm(p)) continue;
    const double m = options_.direction ? dot(p - o, *options_.direction) : norm(p - o);
    if (m > best) {
      best = m;
      tip = p;
    }
  }
  if (!tip) return std::nullopt;

  history_.push_back({time, *tip, 0, 0});
  refresh(history_.size() - 1);

  if (!branch_) detect_branch(pc, *tip, len, time);
  return history_.back();
}

// Path length and speed of sample k from the samples before it. Speed: least-squares
// velocity over the last speed_window + 1 tips (the plain difference for a window of 1).
void CrackTipTracker::refresh(std::size_t k) {
  TipSample& s = history_[k];
  s.length = k > 0 ? history_[k - 1].length + norm(s.position - history_[k - 1].position) : 0.0;
  s.speed = 0;
  const std::size_t m = std::min(options_.speed_window, k) + 1;
  if (m < 2) return;
  const auto win = std::span(history_).subspan(k + 1 - m, m);
  double mt = 0, mx = 0, my = 0;
  for (const auto& w : win) {
    mt += w.time;
    mx += w.position[0];
    my += w.position[1];
  }
  mt /= double(m);
  mx /= double(m);
  my /= double(m);
  double tt = 0, tx = 0, ty = 0;
  for (const auto& w : win) {
    tt += (w.time - mt) * (w.time - mt);
    tx += (w.time - mt) * (w.position[0] - mx);
    ty += (w.time - mt) * (w.position[1] - my);
  }
  if (options_.speed_along_direction && options_.direction) {
    const Vec3& d = *options_.direction;
    s.speed = std::max(0.0, (tx * d[0] + ty * d[1]) / (tt * std::hypot(d[0], d[1])));
  } else {
    s.speed = std::hypot(tx / tt, ty / tt);
  }
}

void CrackTipTracker::detect_branch(const PointCloud& pc, const Vec3& tip, const Lengths& len, double time) {
  const Vec3& o = options_.origin;
  if (!options_.direction && !(norm(tip - o) > 0)) return;
  const Vec3 e = options_.direction ? *options_.direction : unit(tip - o);
  const Vec3 n{-e[1], e[0], 0};
  const double s_tip = dot(tip - o, e);
  const double w = len.link;  // slice width: a band is never cut by a gap narrower than a link

  slice_crack(pc, e, n, s_tip, w);
  const std::size_t count = slices_.size();
  if (count == 0) return;

  // Detection: two slices within the window where the arms' bands are clearly apart, or, once
  // one arm has stopped, where a point of it lies clearly away from the other.
  const auto window = std::min(count, std::size_t(len.window / w) + 1);
  std::size_t wide = 0, detect = count, far = 0, reached = count;
  for (std::size_t c = 0; c < window; ++c) {
    if (!slices_[c].split) continue;
    if (slices_[c].gap > len.separation) {
      ++wide;
      detect = std::min(detect, c);
    }
    if (slices_[c].reach > len.separation) {
      ++far;
      reached = std::min(reached, c);
    }
  }
  const auto front_of = [&](std::size_t c) {
    while (c > 0 && slices_[c - 1].split) --c;
    return c;
  };
  // While both arms run, their far edges part before their bands do; waiting for the gap keeps
  // the split run long enough to fit the arms' lines. An arm that stopped (the other has run
  // on alone for more than the separation) may never open that gap.
  if (wide < 2) {
    if (far < 2 || !(double(front_of(reached)) * w > len.separation)) return;
    detect = reached;
  }

  // The split run through the detection slice, back to where the crack is one band.
  std::size_t front = front_of(detect), merge = detect;
  while (merge < count && slices_[merge].split) ++merge;
  std::vector<std::pair<double, double>> low, high;
  for (std::size_t c = front; c < merge; ++c) {
    low.push_back({slices_[c].s, slices_[c].t_low});
    high.push_back({slices_[c].s, slices_[c].t_high});
  }
  // Fallback: the boundary between the last single-band slice and the split run.
  const double s_merge = s_tip - double(merge) * w;
  double s_b = s_merge;
  double t_b = merge < count && !slices_[merge].empty ? slices_[merge].t_mean
                                                        : 0.5 * (low.back().second + high.back().second);
  double a_l, b_l, a_h, b_h;
  if (fit_line(low, a_l, b_l) && fit_line(high, a_h, b_h) && b_h - b_l != 0) {
    const double s = (a_l - a_h) / (b_h - b_l);
    // Trust the intersection only within the split run's length behind the merge (lines are
    // extrapolated no farther than they were fitted); strongly curved arms can put it anywhere.
    const double run = (s_tip - double(front) * w) - s_merge;
    if (s >= s_merge - run && s <= s_merge + w) {
      s_b = s;
      t_b = a_h + b_h * s;
    }
  }
  BranchEvent ev;
  ev.position = o + s_b * e + t_b * n;
  ev.time = time_at_projection(e, s_b);
  ev.detected_time = time;
  branch_ = ev;
  follow_leading_arm(tip, e, n);
}

// Cuts the crack into slices of width w across the axis e, counted back from the tip, and
// splits each slice's points at their widest transverse gap.
void CrackTipTracker::slice_crack(const PointCloud& pc, const Vec3& e, const Vec3& n, double s_tip, double w) {
  const Vec3& o = options_.origin;
  // Slice index counted back from the tip, then transverse coordinate.
  sliced_.clear();
  for (const auto i : crack_) {
    const Vec3 p = pc.position(std::size_t(i)) - o;
    const double s = dot(p, e);
    if (s > s_tip) continue;
    sliced_.push_back({std::int64_t((s_tip - s) / w), dot(p, n)});
  }
  slices_.clear();
  if (sliced_.empty()) return;
  std::sort(sliced_.begin(), sliced_.end());
  const auto count = std::size_t(sliced_.back().first) + 1;
  slices_.assign(count, Slice{});
  auto& first = slice_start_;
  first.assign(count + 1, sliced_.size());
  for (std::size_t k = sliced_.size(); k-- > 0;) first[std::size_t(sliced_[k].first)] = k;
  for (std::size_t c = count; c-- > 0;) first[c] = std::min(first[c], first[c + 1]);

  for (std::size_t c = 0; c < count; ++c) {
    const std::size_t a = first[c], b = first[c + 1];
    Slice& sl = slices_[c];
    sl.empty = a == b;
    if (sl.empty) continue;
    std::size_t cut = a;  // first point above the widest gap
    double sum = 0;
    for (std::size_t k = a; k < b; ++k) {
      sum += sliced_[k].second;
      if (k > a && sliced_[k].second - sliced_[k - 1].second > sl.gap) {
        sl.gap = sliced_[k].second - sliced_[k - 1].second;
        cut = k;
      }
    }
    sl.t_mean = sum / double(b - a);
    sl.split = sl.gap > w;
    if (!sl.split) continue;
    double lo = 0, hi = 0;
    for (std::size_t k = a; k < cut; ++k) lo += sliced_[k].second;
    for (std::size_t k = cut; k < b; ++k) hi += sliced_[k].second;
    sl.reach = std::max(sliced_[b - 1].second - sliced_[cut - 1].second, sliced_[cut].second - sliced_[a].second);
    sl.s = s_tip - (double(c) + 0.5) * w;
    sl.t_low = lo / double(cut - a);
    sl.t_high = hi / double(b - cut);
  }
}

// The arm holding the tip leads; update() skips the other one from now on. Symmetric arms
// tie, so tips taken between the branch and its detection may sit on the trailing arm:
// drop those samples and recompute the later path lengths and speeds.
void CrackTipTracker::follow_leading_arm(const Vec3& tip, const Vec3& e, const Vec3& n) {
  branch_axis_ = e;
  branch_side_ = dot(tip - branch_->position, n) >= 0 ? n : -1.0 * n;
  const auto trailing = [&](const TipSample& h) { return on_trailing_arm(h.position); };
  const auto first = std::size_t(std::find_if(history_.begin(), history_.end(), trailing) - history_.begin());
  std::erase_if(history_, trailing);
  for (std::size_t k = first; k < history_.size(); ++k) refresh(k);
}

bool CrackTipTracker::on_trailing_arm(const Vec3& p) const {
  if (!branch_) return false;
  const Vec3 q = p - branch_->position;
  return dot(q, branch_axis_) > 0 && dot(q, branch_side_) < 0;
}

// The time at which the tip's projection on e first reached s (linear between samples).
double CrackTipTracker::time_at_projection(const Vec3& e, double s) const {
  const Vec3& o = options_.origin;
  for (std::size_t k = 0; k < history_.size(); ++k) {
    const double sk = dot(history_[k].position - o, e);
    if (sk < s) continue;
    if (k == 0) return history_[0].time;
    const double sp = dot(history_[k - 1].position - o, e);
    const double f = sk > sp ? (s - sp) / (sk - sp) : 1.0;
    return history_[k - 1].time + f * (history_[k].time - history_[k - 1].time);
  }
  return history_.back().time;
}

std::optional<TipSample> CrackTipTracker::current() const {
  if (history_.empty()) return std::nullopt;
  return history_.back();
}

double CrackTipTracker::max_speed() const {
  double v = 0;
  for (std::size_t k = options_.speed_window; k < history_.size(); ++k) v = std::max(v, history_[k].speed);
  return v;
}

double CrackTipTracker::mean_speed_until(double t_end) const {
  double dist = 0, span = 0;
  for (std::size_t k = options_.speed_window; k < history_.size() && history_[k].time <= t_end; ++k) {
    const double dt = history_[k].time - history_[k - 1].time;
    dist += history_[k].speed * dt;
    span += dt;
  }
  return span > 0 ? dist / span : 0.0;
}

double CrackTipTracker::mean_speed() const { return mean_speed_until(std::numeric_limits<double>::infinity()); }

TipSummary CrackTipTracker::summary() const {
  TipSummary s;
  s.samples = history_.size();
  s.branch = branch_;
  if (history_.empty()) return s;
  s.initiated = true;
  s.initiation_time = history_.front().time;
  s.tip = history_.back().position;
  s.length = history_.back().length;
  s.max_speed = max_speed();
  s.mean_speed = mean_speed();
  s.mean_speed_before_branch = branch_ ? mean_speed_until(branch_->time) : s.mean_speed;
  return s;
}

}  // namespace peridot
