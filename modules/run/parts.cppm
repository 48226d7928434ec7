export module peridot.run:parts;
import peridot.std;
import peridot.problem;
import peridot.analysis;
import peridot.render;

// What the observers of a run on N ranks share, whichever stepper holds the parts: gathers to
// rank 0, PNGs drawn in parts, fragments joined from the ranks' shares.
export namespace peridot {

// Every rank's `piece` one after another, on rank 0 (empty elsewhere). Collective.
std::vector<double> gathered_on_root(const std::vector<double>& piece);

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

}  // namespace peridot

namespace peridot {

std::vector<double> gathered_on_root(const std::vector<double>& piece) {
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
