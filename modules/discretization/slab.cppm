module;
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>
#include <fmt/core.h>
export module peridot.discretization:slab;
import :point_cloud;

export namespace peridot {

// One rank's share of a lattice body cut into slabs of whole lattice layers across one axis,
// the axis with the most layers (the thinnest cross-sections, so the least halo). Slabs are
// balanced by point count. A rank holds its owned points and the ghost layers (`reach` on each
// side) that their bonds read; its local points keep the global order, so each point's
// stencil, and its bond sum, are those of the one-rank body.
// On one rank nothing is listed: the global ids are the local ones.
struct Slab {
  int rank = 0, ranks = 1;
  int axis = 0;                                 // the lattice axis cut into slabs (0 = x)
  std::size_t global_size = 0;
  std::vector<std::int64_t> local_ids;          // global ids of the local points, ascending
  std::vector<std::int64_t> owned;              // local indices of the owned points, ascending
  std::vector<std::uint8_t> is_owned;           // per local point
  std::vector<std::int64_t> ghost;              // local indices of the ghosts
  std::vector<int> ghost_owner;                 // the rank that owns each ghost
  std::vector<std::int64_t> ghost_owner_index;  // and the ghost's local index there
  std::vector<std::size_t> owned_starts;        // ranks + 1: where each rank's owned points start in gather order
  std::vector<std::int64_t> gather_ids;         // rank 0 only: global ids in gather order (rank by rank, ascending)

  bool distributed() const { return ranks > 1; }
  std::size_t local_size() const { return distributed() ? local_ids.size() : global_size; }
  std::size_t owned_size() const { return distributed() ? owned.size() : global_size; }
  // Local index of global id g, or -1 when this rank does not hold it.
  std::int64_t local_of(std::int64_t g) const {
    if (!distributed()) return g >= 0 && std::size_t(g) < global_size ? g : -1;
    const auto it = std::lower_bound(local_ids.begin(), local_ids.end(), g);
    return it != local_ids.end() && *it == g ? std::int64_t(it - local_ids.begin()) : -1;
  }
};

// The slab of `rank` among `ranks` over a lattice cloud (collective in nothing: every rank
// computes every rank's layout from the whole cloud). Throws std::invalid_argument when the
// points are not on one lattice or the body has fewer layers than ranks.
Slab slab_of(const PointCloud& whole, int rank, int ranks, int reach);

// The points with the given global ids, in that order.
PointCloud subset(const PointCloud& whole, const std::vector<std::int64_t>& ids);

}  // namespace peridot

namespace peridot {

Slab slab_of(const PointCloud& pc, int rank, int ranks, int reach) {
  const std::size_t n = pc.size();
  if (ranks < 1 || rank < 0 || rank >= ranks) throw std::invalid_argument(fmt::format("slab_of: rank {} of {}", rank, ranks));
  if (reach < 0) throw std::invalid_argument("slab_of: negative reach");
  Slab s;
  s.rank = rank;
  s.ranks = ranks;
  s.global_size = n;
  s.axis = pc.dim - 1;
  if (ranks == 1) return s;
  const double h = pc.spacing;
  if (!(h > 0) || n == 0) throw std::invalid_argument("slab_of: the body is not a lattice");
  // Layers along each axis; the axis with the most (the last one on a tie) is cut.
  std::vector<long> layers(std::size_t(pc.dim), 0);
  std::vector<double> lo(std::size_t(pc.dim));
  for (int a = 0; a < pc.dim; ++a) {
    lo[std::size_t(a)] = *std::min_element(pc.x[a].begin(), pc.x[a].end());
    for (std::size_t i = 0; i < n; ++i) {
      const double t = (pc.x[a][i] - lo[std::size_t(a)]) / h;
      const long l = std::lround(t);
      if (std::abs(t - double(l)) > 1e-6) throw std::invalid_argument("slab_of: the points are not on one lattice");
      layers[std::size_t(a)] = std::max(layers[std::size_t(a)], l + 1);
    }
  }
  for (int a = pc.dim - 1; a >= 0; --a)
    if (layers[std::size_t(a)] > layers[std::size_t(s.axis)]) s.axis = a;
  const auto L = std::size_t(layers[std::size_t(s.axis)]);
  if (L < std::size_t(ranks))
    throw std::invalid_argument(fmt::format("the body has at most {} lattice layers along any axis, fewer than the {} MPI ranks; use at most {} ranks",
                                            L, ranks, L));
  std::vector<std::int32_t> layer(n);
  std::vector<std::size_t> count(L + 1, 0);
  for (std::size_t i = 0; i < n; ++i) {
    layer[i] = std::int32_t(std::lround((pc.x[s.axis][i] - lo[std::size_t(s.axis)]) / h));
    ++count[std::size_t(layer[i]) + 1];
  }
  for (std::size_t l = 0; l < L; ++l) count[l + 1] += count[l];  // count[l]: points below layer l
  // Rank r starts at the layer boundary nearest to where its share of the points begins; each
  // gets at least one layer.
  std::vector<std::size_t> first(std::size_t(ranks) + 1, L);
  first[0] = 0;
  for (int r = 1; r < ranks; ++r) {
    const std::size_t target = n * std::size_t(r) / std::size_t(ranks);
    auto l = std::size_t(std::lower_bound(count.begin(), count.begin() + std::ptrdiff_t(L), target) - count.begin());
    if (l > 0 && target - count[l - 1] < count[std::min(l, L)] - target) --l;  // the nearer layer boundary
    first[std::size_t(r)] = std::clamp(l, first[std::size_t(r) - 1] + 1, L - std::size_t(ranks - r));
  }
  std::vector<int> owner_of(L);
  for (int r = 0; r < ranks; ++r)
    for (std::size_t l = first[std::size_t(r)]; l < first[std::size_t(r) + 1]; ++l) owner_of[l] = r;
  const auto held_by = [&](int r, std::int32_t l) {
    const auto lo_r = std::int64_t(first[std::size_t(r)]) - reach, hi_r = std::int64_t(first[std::size_t(r) + 1]) + reach;
    return l >= lo_r && l < hi_r;
  };
  for (std::size_t i = 0; i < n; ++i) {
    if (!held_by(rank, layer[i])) continue;
    const bool mine = owner_of[std::size_t(layer[i])] == rank;
    if (mine) s.owned.push_back(std::int64_t(s.local_ids.size()));
    else {
      s.ghost.push_back(std::int64_t(s.local_ids.size()));
      s.ghost_owner.push_back(owner_of[std::size_t(layer[i])]);
    }
    s.is_owned.push_back(mine);
    s.local_ids.push_back(std::int64_t(i));
  }
  // A ghost's index on its owner: how many points that rank holds below it.
  s.ghost_owner_index.assign(s.ghost.size(), -1);
  std::vector<int> neighbours(s.ghost_owner);
  std::sort(neighbours.begin(), neighbours.end());
  neighbours.erase(std::unique(neighbours.begin(), neighbours.end()), neighbours.end());
  for (int r : neighbours) {
    std::int64_t held = 0;
    std::size_t g = 0;
    for (std::size_t i = 0; i < n; ++i) {
      if (!held_by(r, layer[i])) continue;
      for (; g < s.ghost.size() && s.local_ids[std::size_t(s.ghost[g])] < std::int64_t(i); ++g) {}
      if (g < s.ghost.size() && s.local_ids[std::size_t(s.ghost[g])] == std::int64_t(i) && s.ghost_owner[g] == r) s.ghost_owner_index[g] = held;
      ++held;
    }
  }
  s.owned_starts.assign(std::size_t(ranks) + 1, 0);
  for (int r = 0; r < ranks; ++r)
    s.owned_starts[std::size_t(r) + 1] = s.owned_starts[std::size_t(r)] + count[first[std::size_t(r) + 1]] - count[first[std::size_t(r)]];
  if (rank == 0) {
    s.gather_ids.resize(n);
    std::vector<std::size_t> next(s.owned_starts.begin(), s.owned_starts.end() - 1);
    for (std::size_t i = 0; i < n; ++i) s.gather_ids[next[std::size_t(owner_of[std::size_t(layer[i])])]++] = std::int64_t(i);
  }
  return s;
}

PointCloud subset(const PointCloud& whole, const std::vector<std::int64_t>& ids) {
  PointCloud out;
  out.dim = whole.dim;
  out.spacing = whole.spacing;
  for (int k = 0; k < 3; ++k) {
    out.x[k].resize(ids.size());
    for (std::size_t j = 0; j < ids.size(); ++j) out.x[k][j] = whole.x[k][std::size_t(ids[j])];
  }
  out.volume.resize(ids.size());
  out.role.resize(ids.size());
  for (std::size_t j = 0; j < ids.size(); ++j) {
    out.volume[j] = whole.volume[std::size_t(ids[j])];
    out.role[j] = whole.role[std::size_t(ids[j])];
  }
  return out;
}

}  // namespace peridot
