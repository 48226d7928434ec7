export module peridot.discretization:slab;
import peridot.std;
import :point_cloud;
import :bond_list;

export namespace peridot {

// One rank's share of a body on N MPI ranks: the points it owns and the ghosts their bonds
// read, in the global order, so each point's bonds, and its bond sum, are those of the one-rank
// body. Two cuts make one:
//   - slab_of (lattice stencils): bricks of whole lattice layers, on the process grid with the
//     least cut area (brick_grid): slabs across the axis with the most layers for a few ranks,
//     bricks cut across two or three axes once those cost less halo; balanced by point count
//     (nested cuts), with `reach` ghost layers on every side;
//   - rcb_of (bond lists, any cloud or mesh): recursive coordinate bisection, each cut across
//     the longest side of its part; the ghosts are exactly the owned rows' partners (depth 1),
//     and for state-based models, whose forces read their partners' dilatations, also those
//     partners' partners (depth 2).
// On one rank nothing is listed: the global ids are the local ones.
struct Slab {
  int rank = 0, ranks = 1;
  int axis = 0;                                 // slab_of: the lattice axis cut into slabs (0 = x), -2 for bricks; rcb_of: -1; a mesh read in parts: -3, a structured mesh made in parts: -4 (with grid)
  std::array<int, 3> grid{1, 1, 1};             // slab_of: ranks along x, y, z
  std::size_t global_size = 0;
  std::vector<std::int64_t> local_ids;          // global ids of the local points, ascending
  std::vector<std::int64_t> owned;              // local indices of the owned points, ascending
  std::vector<std::uint8_t> is_owned;           // per local point
  std::vector<std::int64_t> ghost;              // local indices of the ghosts
  std::vector<int> ghost_owner;                 // the rank that owns each ghost
  std::vector<std::int64_t> ghost_owner_index;  // and the ghost's local index there
  std::vector<std::size_t> owned_starts;        // ranks + 1: where each rank's owned points start in gather order
  std::vector<std::int64_t> gather_ids;         // rank 0 only: global ids in gather order (rank by rank, ascending)
  std::vector<std::size_t> bond_starts;         // rcb_of: ranks + 1, where each rank's owned rows' bonds start in gather order
  std::vector<std::uint8_t> full_row;           // rcb_of: per local point, 1 when its bond row is held (owned points; at depth 2 also the ghosts next to them)
  std::size_t near_points = 0;                  // rcb_part: the points this rank built bonds for (its neighbourhood); 0 when cut from the whole body
  bool gathers_bonds = true;                    // rank 0 holds the whole bond list and gathers bond states (else per-point fields only)

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

// The slab or brick of `rank` among `ranks` over a lattice cloud (collective in nothing: every
// rank computes every rank's layout from the whole cloud). Throws std::invalid_argument when the
// points are not on one lattice or no process grid fits the body's layers.
Slab slab_of(const PointCloud& whole, int rank, int ranks, int reach);
// The same share on a lattice of any shape from its grid alone (no whole cloud): memory and time
// in the rank's own points and its grid's rows (rank 0 also lists the gather order, 8 B per
// point).
Slab slab_of(const BoxLattice& grid, int rank, int ranks, int reach);

// The share of `rank` among `ranks` of a body with a bond list, cut by recursive coordinate
// bisection (every rank computes every rank's part from the whole body), with ghosts `depth`
// (1 or 2) bonds deep. Throws std::invalid_argument when the body has fewer points than ranks.
Slab rcb_of(const PointCloud& whole, const BondList& bonds, int rank, int ranks, int depth = 1);
// How a Slab's parts were cut, for a run's MPI line: slabs or bricks of lattice layers, or
// recursive coordinate bisection.
std::string cut_name(const Slab& slab);

// A cut made without the whole bond list, so that no rank builds the whole body:
//   - rcb_owners: the owner of every point under rcb_of's bisection, from positions alone;
//   - points_near_part: the global ids (ascending) of the points inside the box of rank's owned
//     points grown by `grow` on every side (a superset of its ghosts when grow is `depth` bond
//     reaches);
//   - rcb_part: rank's share from `near` (ascending global ids) and the bond list built on
//     subset(whole, near), whose rows must be complete for the owned points and the points up
//     to depth - 1 bonds from them (the outermost ghosts are only found, as partners). The
//     result equals rcb_of's on the whole body except for what other ranks know:
//     ghost_owner_index (-1 here; the owners answer it) and bond_starts (empty; every rank's
//     count is needed). `held` gets each local point's index into `near`.
std::vector<int> rcb_owners(const PointCloud& whole, int ranks);
std::vector<std::int64_t> points_near_part(const PointCloud& whole, const std::vector<int>& owner, int rank, double grow);
// points_near_part for every rank at once, in about one pass over the points (the parts' grown
// boxes are binned on a coarse grid), for a rank that cuts the whole body for all of them.
std::vector<std::vector<std::int64_t>> points_near_parts(const PointCloud& whole, const std::vector<int>& owner, int ranks, double grow);
// The pieces of points_near_part: the bounding box of rank's owned points, and the ids
// (ascending) of the points of a cloud inside a box grown by `grow` on every side.
Aabb part_box(const PointCloud& whole, const std::vector<int>& owner, int rank);
std::vector<std::int64_t> points_in_box(const PointCloud& pc, const Aabb& box, double grow);
bool in_box(const Aabb& box, double grow, const Vec3& x);
Slab rcb_part(const std::vector<int>& owner, std::span<const std::int64_t> near, const BondList& near_bonds, int rank, int ranks,
              int depth, std::vector<std::int64_t>& held);
// The same for a rank that knows only its near points' owners (a cut made on rank 0 and sent):
// near_owner[j] owns near[j], owned_counts[r] is rank r's owned count (ranks entries), and
// root_owner, on rank 0 only, every point's owner, for the gather order (nullptr elsewhere).
Slab rcb_part(std::span<const int> near_owner, std::span<const std::uint64_t> owned_counts, const std::vector<int>* root_owner,
              std::span<const std::int64_t> near, const BondList& near_bonds, int rank, int depth, std::vector<std::int64_t>& held);

// The same share on a lattice (perturbed or not, of any shape: BoxLattice) without any whole
// cloud: the ranks own bricks of sites (brick_cut: slab_of's cut of the grid, balanced by the
// points each layer holds), a rank makes the points of its brick grown by enough layers to hold
// every point up to `depth` bond reaches away (brick_sites, ascending ids), builds bonds on
// them, and brick_part classifies them as rcb_part does. Memory and time in the rank's own
// neighbourhood; rank 0 also lists the gather order.
struct BrickCut {
  int dim = 2;
  std::array<std::int64_t, 3> m{1, 1, 1};       // sites per axis
  BoxLattice lattice;                           // the grid cut (its runs, where it is no box)
  std::array<int, 3> grid{1, 1, 1};             // ranks along x, y, z
  int axis = 0;                                 // the one axis cut, or -2 for bricks
  std::vector<std::array<std::int64_t, 6>> box;  // per rank: [lo, hi) per axis, in sites
  struct Node {
    int axis = -1;                    // -1: a leaf, rank's brick
    std::vector<std::int64_t> start;  // the pieces' first layers, then the layer count
    std::vector<std::size_t> child;
    int rank = -1;
  };
  std::vector<Node> tree;
  int owner(std::int64_t x, std::int64_t y, std::int64_t z) const;
  int owner_of(std::int64_t id) const;
  // Rank r's brick grown by `grow` layers on every side, clipped to the grid, and its points.
  std::array<std::int64_t, 6> brick(int r, std::int64_t grow) const;
  std::size_t count(int r, std::int64_t grow) const;
};
// Throws std::invalid_argument when no process grid fits the lattice's layers.
BrickCut brick_cut(const BoxLattice& grid, int ranks);
// Whether every rank's brick holds a point: a body that is no box can leave one empty (a ring's
// middle), and callers then cut by coordinate bisection, which gives every rank points.
bool every_brick_holds_points(const BrickCut& cut);
std::vector<std::int64_t> brick_sites(const BrickCut& cut, int rank, std::int64_t grow);
Slab brick_part(const BrickCut& cut, std::span<const std::int64_t> near, const BondList& near_bonds, int rank, int depth,
                std::vector<std::int64_t>& held);

// local_bonds in place, for a rank that built `bonds` on its near points only (by_near: the
// rank's Slab with local_ids the indices into the near points): held rows move down, partners
// are renumbered, and no second copy of the list is made (a set-up's peak is one list). The
// arrays keep their capacity.
void keep_held_rows(BondList& bonds, const Slab& by_near);

// The points with the given global ids, in that order.
PointCloud subset(const PointCloud& whole, const std::vector<std::int64_t>& ids);

// A rank's bond list: the held rows (Slab::full_row) of the whole list, partners renumbered to
// local indices, with every per-bond array the whole list stores. The other rows are empty, so
// a force pass leaves those ghosts at zero force and never breaks a bond there. A held ghost
// row sees the same displacements as its owner's, so it breaks the same bonds.
BondList local_bonds(const BondList& whole, const Slab& slab);

}  // namespace peridot

namespace peridot {

namespace {

// Where each rank's owned points start in rank 0's gather order, and on rank 0 that order.
// root_owner: every point's owner, needed on rank 0 only.
void fill_gather_order(Slab& s, std::span<const std::uint64_t> owned_counts, const std::vector<int>* root_owner) {
  s.owned_starts.assign(std::size_t(s.ranks) + 1, 0);
  for (int r = 0; r < s.ranks; ++r) s.owned_starts[std::size_t(r) + 1] = s.owned_starts[std::size_t(r)] + std::size_t(owned_counts[std::size_t(r)]);
  if (s.rank == 0) {
    if (!root_owner) throw std::logic_error("fill_gather_order: rank 0 needs every point's owner");
    const auto& owner = *root_owner;
    const std::size_t n = owner.size();
    s.gather_ids.resize(n);
    std::vector<std::size_t> next(s.owned_starts.begin(), s.owned_starts.end() - 1);
    for (std::size_t i = 0; i < n; ++i) s.gather_ids[next[std::size_t(owner[i])]++] = std::int64_t(i);
  }
}

void fill_gather_order(Slab& s, const std::vector<int>& owner) {
  std::vector<std::uint64_t> counts(std::size_t(s.ranks), 0);
  for (int o : owner) ++counts[std::size_t(o)];
  fill_gather_order(s, counts, &owner);
}

// Fills s's lists from every point's owner and `mark(r, levels)`, which sets levels[i] to 0 for
// the points rank r does not hold, 1 for those it owns and k + 1 for ghosts k bonds (or layers)
// away. full_depth > 0 also lists the held rows: levels up to full_depth.
template <class Mark>
void fill_layout(Slab& s, const std::vector<int>& owner, Mark mark, int full_depth) {
  const std::size_t n = owner.size();
  std::vector<std::uint8_t> held(n);
  mark(s.rank, held);
  for (std::size_t i = 0; i < n; ++i) {
    if (!held[i]) continue;
    const bool mine = owner[i] == s.rank;
    if (full_depth > 0) s.full_row.push_back(held[i] <= full_depth);
    if (mine) s.owned.push_back(std::int64_t(s.local_ids.size()));
    else {
      s.ghost.push_back(std::int64_t(s.local_ids.size()));
      s.ghost_owner.push_back(owner[i]);
    }
    s.is_owned.push_back(mine);
    s.local_ids.push_back(std::int64_t(i));
  }
  // A ghost's index on its owner: how many points that rank holds below it.
  s.ghost_owner_index.assign(s.ghost.size(), -1);
  std::vector<int> neighbours(s.ghost_owner);
  std::sort(neighbours.begin(), neighbours.end());
  neighbours.erase(std::unique(neighbours.begin(), neighbours.end()), neighbours.end());
  std::vector<std::int64_t> below(n);
  for (int r : neighbours) {
    mark(r, held);
    std::int64_t count = 0;
    for (std::size_t i = 0; i < n; ++i) {
      below[i] = count;
      count += held[i] != 0;
    }
    for (std::size_t g = 0; g < s.ghost.size(); ++g)
      if (s.ghost_owner[g] == r) s.ghost_owner_index[g] = below[std::size_t(s.local_ids[std::size_t(s.ghost[g])])];
  }
  fill_gather_order(s, owner);
}

}  // namespace

namespace {

// The process grid of a lattice with `layers` along each axis and n points: ranks = p0 p1 p2,
// p_a <= layers_a, with the least cut area, sum over axes of (p_a - 1) n / layers_a (each cut
// across axis a costs one mean cross-section of ghosts). Slabs (one axis cut) win ties; among
// them the axis with the most layers, the last on a tie. nullopt: no grid fits.
std::optional<std::array<int, 3>> brick_grid(const std::vector<long>& layers, std::size_t n, int ranks) {
  const int dim = int(layers.size());
  std::optional<std::array<int, 3>> best;
  double best_cost = std::numeric_limits<double>::infinity();
  int best_axes = 4;
  for (int p0 = 1; p0 <= ranks; ++p0) {
    if (ranks % p0) continue;
    for (int p1 = 1; p1 <= ranks / p0; ++p1) {
      if ((ranks / p0) % p1) continue;
      const std::array<int, 3> p{p0, p1, ranks / p0 / p1};
      bool fits = true;
      double cost = 0;
      int axes = 0;
      for (int a = 0; a < 3; ++a) {
        const long L = a < dim ? layers[std::size_t(a)] : 1;
        fits = fits && p[std::size_t(a)] <= L;
        if (p[std::size_t(a)] > 1) cost += double(p[std::size_t(a)] - 1) * double(n) / double(L), ++axes;
      }
      if (!fits) continue;
      const bool tie = cost <= best_cost * (1 + 1e-12) && cost >= best_cost * (1 - 1e-12);
      // Slabs tie when two axes have as many layers: the later axis wins.
      const auto axis_of = [](const std::array<int, 3>& q) { return int(std::find_if(q.begin(), q.end(), [](int v) { return v > 1; }) - q.begin()); };
      const bool better = cost < best_cost * (1 - 1e-12) || (tie && axes < best_axes) ||
                          (tie && axes == 1 && best_axes == 1 && axis_of(p) > axis_of(*best));
      if (better) best = p, best_cost = cost, best_axes = axes;
    }
  }
  return best;
}

}  // namespace

namespace {

// The process grid (brick_grid) and the cut axis of a lattice with `layers` and n points, into s.
void set_grid(Slab& s, const std::vector<long>& layers, std::size_t n) {
  const auto grid = brick_grid(layers, n, s.ranks);
  if (!grid) {
    std::string shape;
    for (long L : layers) shape += (shape.empty() ? "" : " x ") + std::to_string(L);
    throw std::invalid_argument(fmt::format("no grid of {} MPI ranks fits the body's {} lattice layers (each rank needs a layer along "
                                            "every axis it is cut across); use fewer ranks",
                                            s.ranks, shape));
  }
  s.grid = *grid;
  const int cut_axes = int(std::count_if(s.grid.begin(), s.grid.end(), [](int p) { return p > 1; }));
  s.axis = cut_axes == 1 ? int(std::find_if(s.grid.begin(), s.grid.end(), [](int p) { return p > 1; }) - s.grid.begin()) : -2;
}

// rank's Slab of n points before any cut (all there is on one rank), after checking the arguments.
Slab uncut(int rank, int ranks, int reach, std::size_t n, int dim) {
  if (ranks < 1 || rank < 0 || rank >= ranks) throw std::invalid_argument(fmt::format("slab_of: rank {} of {}", rank, ranks));
  if (reach < 0) throw std::invalid_argument("slab_of: negative reach");
  Slab s;
  s.rank = rank;
  s.ranks = ranks;
  s.global_size = n;
  s.axis = dim - 1;
  return s;
}

// The axes in cutting order: most layers first.
std::vector<int> cut_order(const std::vector<long>& layers) {
  std::vector<int> order(layers.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return layers[std::size_t(a)] > layers[std::size_t(b)]; });
  return order;
}

// Where each of `pieces` starts across an axis of L = count.size() - 1 layers, count[l] the
// points below layer l (of `points`), then L: piece p starts at the layer boundary nearest to
// where its share of the points begins, and each gets at least one layer.
std::vector<std::size_t> piece_starts(const std::vector<std::size_t>& count, std::size_t points, int pieces) {
  const std::size_t L = count.size() - 1;
  std::vector<std::size_t> start(std::size_t(pieces) + 1, L);
  start[0] = 0;
  for (int p = 1; p < pieces; ++p) {
    const std::size_t target = points * std::size_t(p) / std::size_t(pieces);
    auto l = std::size_t(std::lower_bound(count.begin(), count.begin() + std::ptrdiff_t(L), target) - count.begin());
    if (l > 0 && target - count[l - 1] < count[std::min(l, L)] - target) --l;  // the nearer layer boundary
    start[std::size_t(p)] = std::clamp(l, start[std::size_t(p) - 1] + 1, L - std::size_t(pieces - p));
  }
  return start;
}

}  // namespace

Slab slab_of(const PointCloud& pc, int rank, int ranks, int reach) {
  const std::size_t n = pc.size();
  Slab s = uncut(rank, ranks, reach, n, pc.dim);
  if (ranks == 1) return s;
  const double h = pc.spacing;
  if (!(h > 0) || n == 0) throw std::invalid_argument("slab_of: the body is not a lattice");
  // Layers along each axis.
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
  std::vector<std::array<std::int32_t, 3>> at(n);  // each point's layer along each axis
  for (std::size_t i = 0; i < n; ++i)
    for (int a = 0; a < pc.dim; ++a) at[i][std::size_t(a)] = std::int32_t(std::lround((pc.x[a][i] - lo[std::size_t(a)]) / h));
  set_grid(s, layers, n);
  // Nested cuts, most layers first: each group of points is split across the next axis by its
  // own point counts, so bricks stay balanced on bodies that are not boxes. Every brick is a
  // box of layers; box[r] is rank r's, [lo, hi) per axis.
  const auto order = cut_order(layers);
  std::vector<std::array<std::int64_t, 6>> box(static_cast<std::size_t>(ranks));
  std::vector<int> owner(n);
  std::vector<std::int64_t> all(n);
  std::iota(all.begin(), all.end(), std::int64_t(0));
  // Splits `ids` (first rank `first`, `count` ranks) across order[k] and recurses.
  const auto split = [&](auto&& self, std::vector<std::int64_t>& ids, int first, std::array<std::int64_t, 6> b, std::size_t k) -> void {
    if (k == order.size()) {
      box[std::size_t(first)] = b;
      for (auto i : ids) owner[std::size_t(i)] = first;
      return;
    }
    const int a = order[k];
    int below = 1;  // ranks per piece across axis a
    for (std::size_t q = k + 1; q < order.size(); ++q) below *= s.grid[std::size_t(order[q])];
    const int pieces = s.grid[std::size_t(a)];
    const auto L = std::size_t(layers[std::size_t(a)]);
    std::vector<std::size_t> count(L + 1, 0);
    for (auto i : ids) ++count[std::size_t(at[std::size_t(i)][std::size_t(a)]) + 1];
    for (std::size_t l = 0; l < L; ++l) count[l + 1] += count[l];  // count[l]: points below layer l
    const auto start = piece_starts(count, ids.size(), pieces);
    std::vector<std::vector<std::int64_t>> part(static_cast<std::size_t>(pieces));
    for (auto i : ids) {
      const auto l = std::size_t(at[std::size_t(i)][std::size_t(a)]);
      const auto p = std::size_t(std::upper_bound(start.begin() + 1, start.end() - 1, l) - start.begin() - 1);
      part[p].push_back(i);
    }
    std::vector<std::int64_t>().swap(ids);
    for (int p = 0; p < pieces; ++p) {
      auto c = b;
      c[std::size_t(2 * a)] = std::int64_t(start[std::size_t(p)]);
      c[std::size_t(2 * a + 1)] = std::int64_t(start[std::size_t(p) + 1]);
      self(self, part[std::size_t(p)], first + p * below, c, k + 1);
    }
  };
  std::array<std::int64_t, 6> whole_box{0, 1, 0, 1, 0, 1};
  for (int a = 0; a < pc.dim; ++a) whole_box[std::size_t(2 * a + 1)] = layers[std::size_t(a)];
  split(split, all, 0, whole_box, 0);
  // Rank r holds its brick and `reach` more layers on every side.
  fill_layout(
      s, owner,
      [&](int r, std::vector<std::uint8_t>& held) {
        const auto& b = box[std::size_t(r)];
        for (std::size_t i = 0; i < n; ++i) {
          bool in = true;
          for (int a = 0; a < pc.dim; ++a) {
            const auto l = std::int64_t(at[i][std::size_t(a)]);
            in = in && l >= b[std::size_t(2 * a)] - reach && l < b[std::size_t(2 * a + 1)] + reach;
          }
          held[i] = !in ? 0 : owner[i] == r ? 1 : 2;
        }
      },
      0);
  return s;
}

std::string cut_name(const Slab& slab) {
  if (slab.axis >= 0) return fmt::format("slabs of lattice layers across {}", "xyz"[slab.axis]);
  if (slab.axis == -2) {
    const auto& g = slab.grid;
    return g[2] > 1 ? fmt::format("bricks of lattice layers, {} x {} x {}", g[0], g[1], g[2]) : fmt::format("bricks of lattice layers, {} x {}", g[0], g[1]);
  }
  if (slab.axis == -3) return "runs of the mesh's Morton order, each rank reading its part of the file";
  if (slab.axis == -4) {
    const auto& g = slab.grid;
    return fmt::format("bricks of the structured mesh's nodes, {}, each rank making its part",
                       g[2] > 1 ? fmt::format("{} x {} x {}", g[0], g[1], g[2]) : fmt::format("{} x {}", g[0], g[1]));
  }
  return "parts by recursive coordinate bisection";
}

BrickCut brick_cut(const BoxLattice& g, int ranks) {
  if (ranks < 1) throw std::invalid_argument(fmt::format("brick_cut: {} ranks", ranks));
  BrickCut c;
  c.dim = g.dim;
  c.m = g.m;
  c.lattice = g;
  std::vector<long> layers(std::size_t(g.dim));
  for (int a = 0; a < g.dim; ++a) layers[std::size_t(a)] = long(g.m[std::size_t(a)]);
  Slab s;
  s.ranks = ranks;
  set_grid(s, layers, g.size());
  c.grid = s.grid;
  c.axis = s.axis;
  // slab_of's nested cuts: an axis not yet cut spans all its layers in each piece, whose points
  // per layer come from the grid's runs (products on a full grid). The cuts form a tree (a node
  // per piece, its children across the next axis) that finds a point's owner in a few searches.
  const auto order = cut_order(layers);
  c.box.resize(static_cast<std::size_t>(ranks));
  const auto split = [&](auto&& self, std::array<std::int64_t, 6> b, std::size_t k, int first) -> std::size_t {
    if (k == order.size()) {
      c.box[std::size_t(first)] = b;
      c.tree.push_back({-1, {}, {}, first});
      return c.tree.size() - 1;
    }
    const int a = order[k];
    int below = 1;  // ranks per piece across axis a
    for (std::size_t q = k + 1; q < order.size(); ++q) below *= c.grid[std::size_t(order[q])];
    const int pieces = c.grid[std::size_t(a)];
    const auto L = std::size_t(layers[std::size_t(a)]);
    std::vector<std::size_t> count(L + 1, 0);  // count[l]: the piece's points below layer l
    g.for_each_run(b, [&](std::int64_t x0, std::int64_t x1, std::int64_t y, std::int64_t z, std::int64_t) {
      if (a == 0) {
        ++count[std::size_t(x0) + 1];
        if (std::size_t(x1) < L) --count[std::size_t(x1) + 1];  // size_t wraps and unwraps exactly
      } else {
        count[std::size_t(a == 1 ? y : z) + 1] += std::size_t(x1 - x0);
      }
    });
    if (a == 0)
      for (std::size_t l = 1; l <= L; ++l) count[l] += count[l - 1];  // points on each layer
    for (std::size_t l = 0; l < L; ++l) count[l + 1] += count[l];
    const auto cuts = piece_starts(count, count[L], pieces);
    const std::vector<std::int64_t> start(cuts.begin(), cuts.end());
    const std::size_t node = c.tree.size();
    c.tree.push_back({a, start, {}, -1});
    for (int p = 0; p < pieces; ++p) {
      auto piece = b;
      piece[std::size_t(2 * a)] = start[std::size_t(p)];
      piece[std::size_t(2 * a + 1)] = start[std::size_t(p) + 1];
      const std::size_t child = self(self, piece, k + 1, first + p * below);
      c.tree[node].child.push_back(child);
    }
    return node;
  };
  std::array<std::int64_t, 6> whole_box{0, 1, 0, 1, 0, 1};
  for (int a = 0; a < g.dim; ++a) whole_box[std::size_t(2 * a + 1)] = g.m[std::size_t(a)];
  split(split, whole_box, 0, 0);
  return c;
}

int BrickCut::owner(std::int64_t x, std::int64_t y, std::int64_t z) const {
  const std::array<std::int64_t, 3> at{x, y, z};
  std::size_t node = 0;
  while (tree[node].axis >= 0) {
    const auto& st = tree[node].start;
    const auto p = std::size_t(std::upper_bound(st.begin() + 1, st.end() - 1, at[std::size_t(tree[node].axis)]) - st.begin() - 1);
    node = tree[node].child[p];
  }
  return tree[node].rank;
}

int BrickCut::owner_of(std::int64_t id) const {
  const std::int64_t site = lattice.site_of(id);
  return owner(site % m[0], (site / m[0]) % m[1], site / (m[0] * m[1]));
}

std::array<std::int64_t, 6> BrickCut::brick(int r, std::int64_t grow) const {
  auto b = box[std::size_t(r)];
  for (int a = 0; a < dim; ++a) {
    b[std::size_t(2 * a)] = std::max<std::int64_t>(0, b[std::size_t(2 * a)] - grow);
    b[std::size_t(2 * a + 1)] = std::min<std::int64_t>(m[std::size_t(a)], b[std::size_t(2 * a + 1)] + grow);
  }
  return b;
}

std::size_t BrickCut::count(int r, std::int64_t grow) const { return lattice.count_in(brick(r, grow)); }

bool every_brick_holds_points(const BrickCut& cut) {
  for (int r = 0; r < int(cut.box.size()); ++r)
    if (cut.count(r, 0) == 0) return false;
  return true;
}

std::vector<std::int64_t> brick_sites(const BrickCut& c, int rank, std::int64_t grow) { return c.lattice.ids_in(c.brick(rank, grow)); }

namespace {

// Where each rank's owned points start in gather order (brick after brick), and on rank 0 the
// order itself.
void fill_brick_gather_order(Slab& s, const BrickCut& c) {
  s.owned_starts.assign(std::size_t(s.ranks) + 1, 0);
  for (int r = 0; r < s.ranks; ++r) s.owned_starts[std::size_t(r) + 1] = s.owned_starts[std::size_t(r)] + c.count(r, 0);
  if (s.rank != 0) return;
  s.gather_ids.reserve(s.global_size);
  for (int r = 0; r < s.ranks; ++r) {
    const auto ids = brick_sites(c, r, 0);
    s.gather_ids.insert(s.gather_ids.end(), ids.begin(), ids.end());
  }
}

}  // namespace

Slab slab_of(const BoxLattice& g, int rank, int ranks, int reach) {
  const std::size_t n = g.size();
  Slab s = uncut(rank, ranks, reach, n, g.dim);
  if (ranks == 1) return s;
  const BrickCut c = brick_cut(g, ranks);
  s.grid = c.grid;
  s.axis = c.axis;
  // A ghost's index on its owner r: its number among the points r holds (r's brick grown by
  // reach), in site order.
  std::map<int, BoxNumbering> held_by;
  const auto index_on = [&](int r, std::int64_t x, std::int64_t y, std::int64_t z) {
    auto at = held_by.find(r);
    if (at == held_by.end()) at = held_by.emplace(r, BoxNumbering(g, c.brick(r, reach))).first;
    return at->second.index(x, y, z);
  };
  g.for_each_run(c.brick(rank, reach), [&](std::int64_t x0, std::int64_t x1, std::int64_t y, std::int64_t z, std::int64_t first) {
    for (auto x = x0; x < x1; ++x) {
      const int r = c.owner(x, y, z);
      const bool mine = r == rank;
      if (mine) s.owned.push_back(std::int64_t(s.local_ids.size()));
      else {
        s.ghost.push_back(std::int64_t(s.local_ids.size()));
        s.ghost_owner.push_back(r);
        s.ghost_owner_index.push_back(index_on(r, x, y, z));
      }
      s.is_owned.push_back(mine);
      s.local_ids.push_back(first + (x - x0));
    }
  });
  fill_brick_gather_order(s, c);
  return s;
}

namespace {

// Owner rank of every point: each part is cut across its longest side at the point count its
// ranks' share asks for. Ties in the coordinate are broken by the global id, so every rank cuts
// identically.
void bisect(const PointCloud& pc, std::int64_t* ids, std::size_t count, int first_rank, int ranks, std::vector<int>& owner) {
  if (ranks == 1) {
    for (std::size_t j = 0; j < count; ++j) owner[std::size_t(ids[j])] = first_rank;
    return;
  }
  int axis = 0;
  double longest = -1;
  for (int a = 0; a < pc.dim; ++a) {
    const auto [lo, hi] = std::minmax_element(ids, ids + count, [&](auto p, auto q) { return pc.x[a][std::size_t(p)] < pc.x[a][std::size_t(q)]; });
    const double extent = pc.x[a][std::size_t(*hi)] - pc.x[a][std::size_t(*lo)];
    if (extent > longest) longest = extent, axis = a;
  }
  const int left = ranks / 2;
  const std::size_t cut = count * std::size_t(left) / std::size_t(ranks);
  const auto& x = pc.x[axis];
  std::nth_element(ids, ids + cut, ids + count, [&](auto p, auto q) {
    const double a = x[std::size_t(p)], b = x[std::size_t(q)];
    return a < b || (a == b && p < q);
  });
  bisect(pc, ids, cut, first_rank, left, owner);
  bisect(pc, ids + cut, count - cut, first_rank + left, ranks - left, owner);
}

// Bond `from` of `src` into bond `to` of `dst` (which may be `src`): state, weight and, in a
// full list, the reference vector and length. Partners are renumbered by the caller.
void copy_bond_data(const BondList& src, std::size_t from, BondList& dst, std::size_t to) {
  dst.intact[to] = src.intact[from];
  if (src.weight.empty()) {
    dst.weight_f[to] = src.weight_f[from];
    return;
  }
  dst.weight[to] = src.weight[from];
  if (!src.stores_geometry()) return;
  for (std::size_t k = 0; k < 3; ++k) dst.xi[k][to] = src.xi[k][from];
  dst.length[to] = src.length[from];
}

// Marks the points rank r holds in `held`: its owned points 1, the ghosts k bonds away k + 1,
// up to depth; 0 for the rest.
void mark_held(const BondList& bonds, std::span<const int> owner, int r, int depth, std::vector<std::uint8_t>& held) {
  std::fill(held.begin(), held.end(), 0);
  for (std::size_t i = 0; i < owner.size(); ++i)
    if (owner[i] == r) held[i] = 1;
  for (int level = 1; level <= depth; ++level)
    for (std::size_t i = 0; i < owner.size(); ++i)
      if (held[i] == level)
        for (auto j : bonds.neighbors(i))
          if (!held[std::size_t(j)]) held[std::size_t(j)] = std::uint8_t(level + 1);
}

}  // namespace

Slab rcb_of(const PointCloud& pc, const BondList& bonds, int rank, int ranks, int depth) {
  const std::size_t n = pc.size();
  if (ranks < 1 || rank < 0 || rank >= ranks) throw std::invalid_argument(fmt::format("rcb_of: rank {} of {}", rank, ranks));
  if (depth < 1 || depth > 2) throw std::invalid_argument(fmt::format("rcb_of: ghost depth {} (1 or 2)", depth));
  if (bonds.points() != n) throw std::invalid_argument("rcb_of: the bond list is not of this cloud");
  Slab s;
  s.rank = rank;
  s.ranks = ranks;
  s.global_size = n;
  s.axis = -1;
  if (ranks == 1) return s;
  if (n < std::size_t(ranks))
    throw std::invalid_argument(fmt::format("the body has {} points, fewer than the {} MPI ranks; use at most {} ranks", n, ranks, n));
  const std::vector<int> owner = rcb_owners(pc, ranks);
  fill_layout(s, owner, [&](int r, std::vector<std::uint8_t>& held) { mark_held(bonds, owner, r, depth, held); }, depth);
  s.bond_starts.assign(std::size_t(ranks) + 1, 0);
  for (std::size_t i = 0; i < n; ++i) s.bond_starts[std::size_t(owner[i]) + 1] += bonds.count(i);
  for (int r = 0; r < ranks; ++r) s.bond_starts[std::size_t(r) + 1] += s.bond_starts[std::size_t(r)];
  return s;
}

std::vector<int> rcb_owners(const PointCloud& pc, int ranks) {
  const std::size_t n = pc.size();
  if (ranks < 1) throw std::invalid_argument(fmt::format("rcb_owners: {} ranks", ranks));
  if (n < std::size_t(ranks))
    throw std::invalid_argument(fmt::format("the body has {} points, fewer than the {} MPI ranks; use at most {} ranks", n, ranks, n));
  std::vector<int> owner(n, 0);
  std::vector<std::int64_t> ids(n);
  std::iota(ids.begin(), ids.end(), std::int64_t(0));
  bisect(pc, ids.data(), n, 0, ranks, owner);
  return owner;
}

namespace {

// A box holding no point yet, and the same grown to hold point i.
Aabb empty_box() {
  Aabb box;
  box.lo.fill(std::numeric_limits<double>::infinity());
  box.hi.fill(-std::numeric_limits<double>::infinity());
  return box;
}
void include(Aabb& box, const PointCloud& pc, std::size_t i) {
  for (std::size_t a = 0; a < 3; ++a) {
    box.lo[a] = std::min(box.lo[a], pc.x[a][i]);
    box.hi[a] = std::max(box.hi[a], pc.x[a][i]);
  }
}

}  // namespace

Aabb part_box(const PointCloud& pc, const std::vector<int>& owner, int rank) {
  if (owner.size() != pc.size()) throw std::invalid_argument("part_box: the owners are not of this cloud");
  Aabb box = empty_box();
  for (std::size_t i = 0; i < pc.size(); ++i)
    if (owner[i] == rank) include(box, pc, i);
  return box;
}

bool in_box(const Aabb& box, double grow, const Vec3& x) {
  for (std::size_t a = 0; a < 3; ++a)
    if (!(x[a] >= box.lo[a] - grow && x[a] <= box.hi[a] + grow)) return false;
  return true;
}

std::vector<std::int64_t> points_in_box(const PointCloud& pc, const Aabb& box, double grow) {
  std::vector<std::int64_t> near;
  for (std::size_t i = 0; i < pc.size(); ++i)
    if (in_box(box, grow, pc.position(i))) near.push_back(std::int64_t(i));
  return near;
}

std::vector<std::int64_t> points_near_part(const PointCloud& pc, const std::vector<int>& owner, int rank, double grow) {
  return points_in_box(pc, part_box(pc, owner, rank), grow);
}

std::vector<std::vector<std::int64_t>> points_near_parts(const PointCloud& pc, const std::vector<int>& owner, int ranks, double grow) {
  if (owner.size() != pc.size()) throw std::invalid_argument("points_near_parts: the owners are not of this cloud");
  std::vector<Aabb> boxes(static_cast<std::size_t>(ranks), empty_box());
  for (std::size_t i = 0; i < pc.size(); ++i) include(boxes[std::size_t(owner[i])], pc, i);
  std::vector<std::vector<std::int64_t>> near(static_cast<std::size_t>(ranks));
  if (pc.size() == 0) return near;
  // A grid of about 8 cells per part; each cell lists the grown boxes that reach into it. Cell
  // indices are clamped to the grid on both sides, so a point inside a grown box always finds
  // the box in its cell.
  const Aabb all = pc.bounds();
  const int dims = pc.dim == 3 ? 3 : 2;
  const auto per_axis = std::int64_t(std::ceil(std::pow(8.0 * ranks, 1.0 / dims)));
  std::array<std::int64_t, 3> cells{1, 1, 1};
  std::array<double, 3> inv{0, 0, 0};
  for (std::size_t a = 0; a < std::size_t(dims); ++a) {
    const double extent = all.hi[a] - all.lo[a];
    if (extent > 0) cells[a] = per_axis, inv[a] = double(per_axis) / extent;
  }
  const auto cell_of = [&](std::size_t a, double x) {
    return std::clamp(std::int64_t(std::floor((x - all.lo[a]) * inv[a])), std::int64_t(0), cells[a] - 1);
  };
  std::vector<std::vector<int>> in_cell(std::size_t(cells[0] * cells[1] * cells[2]));
  for (int r = 0; r < ranks; ++r) {
    const Aabb& b = boxes[std::size_t(r)];
    if (!(b.lo[0] <= b.hi[0])) continue;  // no point
    std::array<std::int64_t, 3> lo{}, hi{};
    for (std::size_t a = 0; a < 3; ++a) lo[a] = cell_of(a, b.lo[a] - grow), hi[a] = cell_of(a, b.hi[a] + grow);
    for (auto z = lo[2]; z <= hi[2]; ++z)
      for (auto y = lo[1]; y <= hi[1]; ++y)
        for (auto x = lo[0]; x <= hi[0]; ++x) in_cell[std::size_t((z * cells[1] + y) * cells[0] + x)].push_back(r);
  }
  for (std::size_t i = 0; i < pc.size(); ++i) {
    const Vec3 x = pc.position(i);
    const auto c = std::size_t((cell_of(2, x[2]) * cells[1] + cell_of(1, x[1])) * cells[0] + cell_of(0, x[0]));
    for (int r : in_cell[c])
      if (in_box(boxes[std::size_t(r)], grow, x)) near[std::size_t(r)].push_back(std::int64_t(i));
  }
  return near;
}

namespace {

// A part from its near points (ascending global ids), their owners and the bonds built on them:
// the owned points and the ghosts `depth` bonds deep, in global order. `held` gets each local
// point's index into `near`. Gather order and the ghosts' indices on their owners are the
// caller's.
Slab part_of_near(std::span<const std::int64_t> near, std::span<const int> near_owner, const BondList& near_bonds, std::size_t global_size,
                  int rank, int ranks, int depth, std::vector<std::int64_t>& held) {
  if (ranks < 2 || rank < 0 || rank >= ranks) throw std::invalid_argument(fmt::format("rcb_part: rank {} of {}", rank, ranks));
  if (depth < 1 || depth > 3) throw std::invalid_argument(fmt::format("rcb_part: ghost depth {} (1 to 3)", depth));
  if (near_bonds.points() != near.size()) throw std::invalid_argument("rcb_part: the bond list is not of the near points");
  Slab s;
  s.rank = rank;
  s.ranks = ranks;
  s.global_size = global_size;
  s.axis = -1;
  std::vector<std::uint8_t> level(near.size());
  mark_held(near_bonds, near_owner, rank, depth, level);
  held.clear();
  for (std::size_t j = 0; j < near.size(); ++j) {
    if (!level[j]) continue;
    const bool mine = near_owner[j] == rank;
    s.full_row.push_back(level[j] <= depth);
    (mine ? s.owned : s.ghost).push_back(std::int64_t(s.local_ids.size()));
    if (!mine) s.ghost_owner.push_back(near_owner[j]);
    s.is_owned.push_back(mine);
    s.local_ids.push_back(near[j]);
    held.push_back(std::int64_t(j));
  }
  s.ghost_owner_index.assign(s.ghost.size(), -1);
  s.near_points = near.size();
  return s;
}

}  // namespace

Slab rcb_part(const std::vector<int>& owner, std::span<const std::int64_t> near, const BondList& near_bonds, int rank, int ranks,
              int depth, std::vector<std::int64_t>& held) {
  std::vector<int> near_owner(near.size());
  for (std::size_t j = 0; j < near.size(); ++j) near_owner[j] = owner[std::size_t(near[j])];
  Slab s = part_of_near(near, near_owner, near_bonds, owner.size(), rank, ranks, depth, held);
  fill_gather_order(s, owner);
  return s;
}

Slab rcb_part(std::span<const int> near_owner, std::span<const std::uint64_t> owned_counts, const std::vector<int>* root_owner,
              std::span<const std::int64_t> near, const BondList& near_bonds, int rank, int depth, std::vector<std::int64_t>& held) {
  if (near_owner.size() != near.size()) throw std::invalid_argument("rcb_part: one owner per near point");
  const int ranks = int(owned_counts.size());
  const auto global_size = std::size_t(std::accumulate(owned_counts.begin(), owned_counts.end(), std::uint64_t(0)));
  Slab s = part_of_near(near, near_owner, near_bonds, global_size, rank, ranks, depth, held);
  fill_gather_order(s, owned_counts, rank == 0 ? root_owner : nullptr);
  return s;
}

Slab brick_part(const BrickCut& cut, std::span<const std::int64_t> near, const BondList& near_bonds, int rank, int depth,
                std::vector<std::int64_t>& held) {
  std::vector<int> near_owner(near.size());
  for (std::size_t j = 0; j < near.size(); ++j) near_owner[j] = cut.owner_of(near[j]);
  const int ranks = int(cut.box.size());
  Slab s = part_of_near(near, near_owner, near_bonds, cut.lattice.size(), rank, ranks, depth, held);
  s.axis = cut.axis;
  s.grid = cut.grid;
  fill_brick_gather_order(s, cut);
  return s;
}

BondList local_bonds(const BondList& whole, const Slab& slab) {
  if (!slab.distributed()) return whole;
  const std::size_t n = slab.local_size();
  std::vector<std::int32_t> local(whole.points(), -1);
  for (std::size_t j = 0; j < n; ++j) local[std::size_t(slab.local_ids[j])] = std::int32_t(j);
  BondList out;
  out.horizon = whole.horizon;
  out.offset.resize(n + 1);
  out.offset[0] = 0;
  for (std::size_t j = 0; j < n; ++j)
    out.offset[j + 1] = out.offset[j] + (slab.full_row[j] ? std::int64_t(whole.count(std::size_t(slab.local_ids[j]))) : 0);
  const auto m = std::size_t(out.offset[n]);
  const bool full = !whole.weight.empty();
  out.neighbor.resize(m);
  out.intact.resize(m);
  if (full) {
    if (whole.stores_geometry()) {
      for (auto& c : out.xi) c.resize(m);
      out.length.resize(m);
    }
    out.weight.resize(m);
  } else {
    out.weight_f.resize(m);
  }
  for (std::size_t j = 0; j < n; ++j) {
    if (!slab.full_row[j]) continue;
    const auto g = std::size_t(slab.local_ids[j]);
    for (std::int64_t b = whole.begin(g), c = out.offset[j]; b < whole.end(g); ++b, ++c) {
      const auto from = std::size_t(b), to = std::size_t(c);
      const std::int32_t partner = local[std::size_t(whole.neighbor[from])];
      if (partner < 0) throw std::logic_error("local_bonds: a partner of a held row is not held");
      out.neighbor[to] = partner;
      copy_bond_data(whole, from, out, to);
    }
  }
  return out;
}

void keep_held_rows(BondList& bl, const Slab& by_near) {
  const std::size_t n = by_near.local_ids.size();
  std::vector<std::int32_t> local(bl.points(), -1);
  for (std::size_t j = 0; j < n; ++j) local[std::size_t(by_near.local_ids[j])] = std::int32_t(j);
  const bool full = !bl.weight.empty();
  std::int64_t to = 0;
  // Row j's source starts at or after its destination (rows only drop out), so a forward copy
  // never overwrites what it has yet to read.
  std::vector<std::int64_t> offset(n + 1, 0);
  for (std::size_t j = 0; j < n; ++j) {
    if (by_near.full_row[j]) {
      const auto g = std::size_t(by_near.local_ids[j]);
      for (std::int64_t b = bl.begin(g); b < bl.end(g); ++b, ++to) {
        const auto from = std::size_t(b), at = std::size_t(to);
        const std::int32_t partner = local[std::size_t(bl.neighbor[from])];
        if (partner < 0) throw std::logic_error("keep_held_rows: a partner of a held row is not held");
        bl.neighbor[at] = partner;
        copy_bond_data(bl, from, bl, at);
      }
    }
    offset[j + 1] = to;
  }
  const auto m = std::size_t(to);
  bl.offset.resize(n + 1);
  std::copy(offset.begin(), offset.end(), bl.offset.begin());
  bl.neighbor.resize(m);
  bl.intact.resize(m);
  if (full) {
    if (bl.stores_geometry()) {
      for (auto& c : bl.xi) c.resize(m);
      bl.length.resize(m);
    }
    bl.weight.resize(m);
  } else {
    bl.weight_f.resize(m);
  }
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
