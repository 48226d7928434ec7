export module peridot.run:parts;
import peridot.std;
import peridot.problem;
import peridot.analysis;
import peridot.observe;
import peridot.live;
import peridot.render;
import :loop;

// What the observers of a run on N ranks share, whichever stepper holds the parts: gathers to
// rank 0, PNGs drawn in parts, fragments joined from the ranks' shares.
export namespace peridot {

// Every rank's `piece` one after another, on rank 0 (empty elsewhere). Collective.
std::vector<double> gathered_on_root(const std::vector<double>& piece);

// Makes each of `sums` the exact sum of every rank's: one rank's result on any cut.
// Collective.
void exact_sums_over_ranks(std::initializer_list<ExactSum*> sums);

// The owned points' rows of `width` values each (row(i, out) writes local point i's), for
// the points keep(local index, global id) selects (all without it), on rank 0 in global id
// order; empty elsewhere. ids: the local points' global ids. Collective.
std::vector<double> owned_rows_on_root(std::span<const std::int64_t> owned, std::span<const std::int64_t> ids, std::size_t width,
                                       const std::function<void(std::size_t, double*)>& row,
                                       const std::function<bool(std::size_t, std::int64_t)>& keep = {});

// What a library user's observers read on rank 0 of a static run on N ranks, whose own
// observers hold no point: the whole body's positions, volumes and roles (once), and u and
// the damage (per report), in global order, as one process's Sample and damage have them.
// Collective.
void whole_points_on_root(const PointCloud& local, std::span<const std::int64_t> owned, std::span<const std::int64_t> ids, PointCloud& whole);
void whole_state_on_root(const VectorField& u, std::span<const double> phi, std::span<const std::int64_t> owned, std::span<const std::int64_t> ids,
                         VectorField& whole_u, std::vector<double>& whole_phi);

// A PNG drawn in parts on N ranks: each rank passes its owned points, and rank 0 gets the image
// one process draws of the whole body (RenderParts over MPI).
RenderParts mpi_render_parts();

// The point spacing and square size the one-rank PNG estimates from the whole body: each rank
// measures its sampled owned points' nearest neighbours among its local points (ghosts
// included, which must hold every owned point's nearest ones), and rank 0 takes the medians of
// all (estimate_spacing's steps); every rank gets the result. `ids`: the local points' global
// indices. Collective.
PointSpacing spacing_of_parts(const PointCloud& local, std::span<const std::int64_t> owned, std::span<const std::int64_t> ids, std::size_t global_size);

// The one-rank fragment count of a body cut into parts: each rank labels the pieces of its part
// (owned points and ghosts), learns its ghosts' pieces from their owners through `halo`, and
// rank 0 joins the shares (nullopt elsewhere). `owned` per local point. Collective.
std::optional<FragmentReport> joined_fragments(const Body& local, std::span<const std::uint8_t> owned, const parallel::Halo& halo,
                                               const FragmentOptions& options);

// The points a run on N ranks sends rank 0's crack trackers and DDS publisher, which the
// one-rank observers take from the whole body: the cracked points (damage at least the
// trackers' lower threshold) with the body's extent along the front's axis, and every
// stride-th point by global id at its deformed position. Steppers of every flavour fill their
// observers' totals through it on the steps these are due.
class TrackedPoints {
 public:
  // ids: the local points' global ids; owned: local indices; snapshot_points:
  // LiveOptions::snapshot_max_points. Collective (the front's extent is a reduction).
  TrackedPoints(const OutputSpec& o, const PointCloud& local, std::span<const std::int64_t> owned, std::span<const std::int64_t> ids,
                std::size_t global_size, std::size_t snapshot_points);
  // Collective on the steps either is due: fills totals.cracked, front_extent, snapshot and
  // points on rank 0. u: the local displacements; phi: the local damage.
  void gather(std::size_t n, bool last, const VectorField& u, std::span<const double> phi, Observers::Totals& totals);
  std::size_t snapshot_stride() const { return stride_; }
  // What a run's MPI line says of DDS snapshots: ", DDS snapshots gather one point in k", or
  // nothing without them.
  std::string snapshot_note() const {
    if (!o_.dds_snapshot_every) return {};
    return stride_ == 1 ? std::string(", DDS snapshots gather every point") : fmt::format(", DDS snapshots gather one point in {}", stride_);
  }

 private:
  // The owned points keep(local index, global id) selects, at x (+ u when deformed) with
  // their damage, on rank 0 in global order. Collective.
  void points_on_root(const std::function<bool(std::size_t, std::int64_t)>& keep, const VectorField* u, std::span<const double> phi,
                      Observers::Points& out) const;

  const OutputSpec& o_;
  const PointCloud& local_;
  std::span<const std::int64_t> owned_, ids_;
  std::size_t global_size_, stride_ = 1;
  std::array<double, 2> extent_{0, 0};
  Observers::Points cracked_, snapshot_;
};

}  // namespace peridot

namespace peridot {

TrackedPoints::TrackedPoints(const OutputSpec& o, const PointCloud& local, std::span<const std::int64_t> owned, std::span<const std::int64_t> ids,
                             std::size_t global_size, std::size_t snapshot_points)
    : o_(o), local_(local), owned_(owned), ids_(ids), global_size_(global_size) {
  if (o.dds_snapshot_every) stride_ = peridot::snapshot_stride(global_size, snapshot_points);
  if (o.crack_front_every) {
    const auto a = std::size_t(o.crack_front_axis);
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (auto j : owned) lo = std::min(lo, local.x[a][std::size_t(j)]), hi = std::max(hi, local.x[a][std::size_t(j)]);
    extent_ = {parallel::min_over_ranks(lo), -parallel::min_over_ranks(-hi)};
  }
}

void TrackedPoints::gather(std::size_t n, bool last, const VectorField& u, std::span<const double> phi, Observers::Totals& totals) {
  if (detail::due(o_.crack_tip_every, n, last) || detail::due(o_.crack_front_every, n, last)) {
    constexpr double inf = std::numeric_limits<double>::infinity();
    const double at_least = std::min(o_.crack_tip_every ? o_.crack_tip_threshold : inf, o_.crack_front_every ? o_.crack_front_threshold : inf);
    points_on_root([&](std::size_t i, std::int64_t) { return phi[i] >= at_least; }, nullptr, phi, cracked_);
    totals.cracked = &cracked_;
    totals.front_extent = extent_;
  }
  if (detail::due(o_.dds_snapshot_every, n, last)) {
    points_on_root([&](std::size_t, std::int64_t g) { return std::size_t(g) % stride_ == 0; }, &u, phi, snapshot_);
    totals.snapshot = &snapshot_;
    totals.points = global_size_;
  }
}

void TrackedPoints::points_on_root(const std::function<bool(std::size_t, std::int64_t)>& keep, const VectorField* u, std::span<const double> phi,
                                   Observers::Points& out) const {
  constexpr std::size_t width = 5;  // x, y, z, volume, damage
  const int dim = local_.dim;
  const auto all = owned_rows_on_root(
      owned_, ids_, width,
      [&](std::size_t i, double* r) {
        for (std::size_t k = 0; k < 3; ++k) r[k] = int(k) < dim ? local_.x[k][i] + (u ? (*u)[k][i] : 0.0) : 0.0;
        r[3] = local_.volume[i];
        r[4] = phi[i];
      },
      keep);
  if (parallel::rank() != 0) return;
  out.points = PointCloud{};
  out.points.dim = dim;
  out.points.spacing = local_.spacing;
  out.damage.clear();
  for (std::size_t r = 0; r < all.size(); r += width) {
    out.points.push_back({all[r], all[r + 1], all[r + 2]}, all[r + 3]);
    out.damage.push_back(all[r + 4]);
  }
}

std::vector<double> owned_rows_on_root(std::span<const std::int64_t> owned, std::span<const std::int64_t> ids, std::size_t width,
                                       const std::function<void(std::size_t, double*)>& row,
                                       const std::function<bool(std::size_t, std::int64_t)>& keep) {
  const std::size_t w = width + 1;  // the global id first
  std::vector<double> mine;
  for (auto j : owned) {
    const auto i = std::size_t(j);
    if (keep && !keep(i, ids[i])) continue;
    mine.resize(mine.size() + w);
    double* r = mine.data() + mine.size() - w;
    r[0] = double(ids[i]);
    row(i, r + 1);
  }
  const auto all = gathered_on_root(mine);
  if (parallel::rank() != 0) return {};
  std::vector<std::size_t> order(all.size() / w);
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return all[w * a] < all[w * b]; });
  std::vector<double> out;
  out.reserve(order.size() * width);
  for (const auto r : order) out.insert(out.end(), all.begin() + std::ptrdiff_t(w * r + 1), all.begin() + std::ptrdiff_t(w * (r + 1)));
  return out;
}

void whole_points_on_root(const PointCloud& local, std::span<const std::int64_t> owned, std::span<const std::int64_t> ids, PointCloud& whole) {
  const auto all = owned_rows_on_root(owned, ids, 5, [&](std::size_t i, double* r) {
    for (std::size_t k = 0; k < 3; ++k) r[k] = local.x[k].empty() ? 0.0 : local.x[k][i];
    r[3] = local.volume[i];
    r[4] = double(static_cast<int>(local.role[i]));
  });
  whole = PointCloud{};
  whole.dim = local.dim;
  whole.spacing = local.spacing;
  for (std::size_t r = 0; r < all.size(); r += 5) whole.push_back({all[r], all[r + 1], all[r + 2]}, all[r + 3], Role(int(all[r + 4])));
}

void whole_state_on_root(const VectorField& u, std::span<const double> phi, std::span<const std::int64_t> owned, std::span<const std::int64_t> ids,
                         VectorField& whole_u, std::vector<double>& whole_phi) {
  const auto all = owned_rows_on_root(owned, ids, 4, [&](std::size_t i, double* r) {
    for (std::size_t k = 0; k < 3; ++k) r[k] = u[k].empty() ? 0.0 : u[k][i];
    r[3] = phi[i];
  });
  if (parallel::rank() != 0) return;
  const std::size_t n = all.size() / 4;
  for (auto& c : whole_u) c.resize(n);
  whole_phi.resize(n);
  for (std::size_t j = 0; j < n; ++j) {
    for (std::size_t k = 0; k < 3; ++k) whole_u[k][j] = all[4 * j + k];
    whole_phi[j] = all[4 * j + 3];
  }
}

void exact_sums_over_ranks(std::initializer_list<ExactSum*> sums) {
  for (ExactSum* s : sums) {
    parallel::sum_over_ranks(s->words_for_reduction());
    s->normalise();
  }
}

std::vector<double> gathered_on_root(const std::vector<double>& piece) {
  if (parallel::ranks() <= 1) return piece;  // also where MPI never started (in-process use)
  const auto sizes = parallel::all_gather(std::uint64_t(piece.size()));
  std::vector<std::size_t> starts{0};
  for (auto n : sizes) starts.push_back(starts.back() + std::size_t(n));
  std::vector<double> whole(parallel::rank() == 0 ? starts.back() : 0);
  parallel::gather_to_root(piece, whole, starts);
  return whole;
}

RenderParts mpi_render_parts() {
  return {.root = parallel::rank() == 0,
          .sum = [](std::span<double> v) {
            for (auto& x : v) x = parallel::sum_over_ranks(x);
          },
          .max = [](std::span<double> v) { parallel::max_over_ranks(v); },
          .max_to_root = [](std::span<std::int16_t> v) { parallel::max_to_root(v); }};
}

std::optional<FragmentReport> joined_fragments(const Body& local, std::span<const std::uint8_t> owned, const parallel::Halo& halo,
                                               const FragmentOptions& options) {
  std::size_t count = 0;
  const auto label = piece_labels(local, count, owned);
  const auto counts = parallel::all_gather(std::uint64_t(count));
  double offset = 0;
  for (int r = 0; r < parallel::rank(); ++r) offset += double(counts[std::size_t(r)]);
  std::vector<double> owner_piece(label.size());
  for (std::size_t i = 0; i < label.size(); ++i) owner_piece[i] = offset + double(label[i]);
  const std::array<double*, 1> a{owner_piece.data()};
  halo.exchange(a);
  const auto share = fragment_share(local, label, count, owned, offset, owner_piece);
  const auto pieces = gathered_on_root(share.pieces), joins = gathered_on_root(share.joins);
  const double debris = parallel::sum_over_ranks(share.debris), debris_mass = parallel::sum_over_ranks(share.debris_mass),
               total_mass = parallel::sum_over_ranks(share.total_mass);
  if (parallel::rank() != 0) return std::nullopt;
  return join_fragment_shares(pieces, joins, debris, debris_mass, total_mass, options);
}

PointSpacing spacing_of_parts(const PointCloud& local, std::span<const std::int64_t> owned, std::span<const std::int64_t> ids, std::size_t global_size) {
  const auto stride = spacing_sample_stride(global_size);
  std::vector<std::size_t> sample;
  for (auto j : owned)
    if (std::size_t(ids[std::size_t(j)]) % stride == 0) sample.push_back(std::size_t(j));
  const auto& x = local.x;
  const auto pairs = gathered_on_root(nearest_distances({x[0], x[1], x[2]}, local.dim, sample));
  const PointSpacing root = parallel::rank() == 0 ? spacing_from_nearest(pairs) : PointSpacing{0, 0};
  // Adding zeros from the other ranks leaves rank 0's values exact.
  return {local.spacing > 0 ? local.spacing : parallel::sum_over_ranks(root.spacing), parallel::sum_over_ranks(root.solid_size)};
}

}  // namespace peridot
