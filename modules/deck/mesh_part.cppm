export module peridot.deck:mesh_part;
import peridot.std;
import peridot.io;
import peridot.parallel;
import :spec;

export namespace peridot {

// A .msh mesh read on N MPI ranks with no rank holding it whole: each rank streams the file
// (stream_msh: mapped, the pages read handed back) and keeps its part. Every rank reads:
//   1. the nodes' bounding box;
//   2. a histogram of the nodes' Morton keys over it (their top bits: 2^20 cells in 2D, 2^21 in
//      3D), which cuts the keys into `ranks` ranges of about equal node counts. Rank r owns the
//      nodes whose keys fall in its range, and every rank knows every range;
//   3. the nodes within depth + 1 bond reaches of its cells (on cubes of a bond reach's side,
//      following the run's shape: a run of the Morton order can be blocks far apart);
//   4. the elements whose nodes it all holds, each entity's in file order (the one-process mesh
//      order). Each element is counted by the owner of its first node: its orientation, its edges
//      for the mean and the longest, whether an element there reaches past the held nodes.
// The whole mesh's figures are exact reductions (min, max, integer and exact sums), so every
// rank has one process's bounds, mean edge and per-surface orientation bit for bit. Nodes are
// numbered as one process numbers them in spatial order (morton_order), by the same keys: a
// rank's owned nodes are a run of the numbering, and its ghosts learn their numbers from their
// owners. Elements longer than guessed grow the margin and the nodes and elements are read again.
// What it checks is what read_gmsh_mesh checks (the errors, std::invalid_argument, may name a
// node or element differently).
// Returns nullopt on every rank where it cannot number the nodes as one process does: a node
// no element uses at the mesh's bounding box (the numbering's box is the used nodes'), two
// nodes in one Morton cell (2^-21 of the mesh's side), a rank that would own no node, node tags
// above 64 times the node count (too sparse for a bit per tag). The
// caller then reads the mesh on rank 0 (make_mesh_once). Collective.
std::optional<MeshSpec::Part> read_mesh_part(const std::filesystem::path& file, int dim, double horizon, int depth, MeshSpec::Summary& summary);

// The part's nodes (indices into it, ascending) within depth * reach of an owned node (reach <=
// part.cube_side, a bond reach): every element of each is in the part when depth <= part.depth.
std::vector<std::int64_t> nodes_near_owned(const MeshSpec::Part& part, int rank, int depth, double reach);

}  // namespace peridot

namespace peridot {

// The part's points from the mesh of its held nodes and the elements among them: the elements
// checked at the whole mesh's mean edge (a failure named after `source`), lumped volumes
// (whole where a node's elements are all held), the elements kept for V_ij and output.
template <class Mesh>
void take_part_mesh(MeshSpec::Part& part, Mesh mesh, double mean_edge, const std::string& source) {
  try {
    validate(mesh, mean_edge);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(fmt::format("{}: {}", source, e.what()));
  }
  PointCloud& points = part.points;
  const auto take = [&](const auto& list, auto measure) {
    const auto vol = lumped_volumes(mesh.nodes.size(), list, measure);
    for (std::size_t k = 0; k < mesh.nodes.size(); ++k) points.push_back(mesh.nodes[k], vol[k]);
  };
  if constexpr (std::is_same_v<Mesh, TriangleMesh>) {
    take(mesh.triangles, [&](std::size_t t) { return mesh.area(t); });
    points.triangles = std::move(mesh.triangles);
    points.dim = 2;
  } else {
    take(mesh.tetrahedra, [&](std::size_t t) { return mesh.volume(t); });
    points.tetrahedra = std::move(mesh.tetrahedra);
    points.dim = 3;
  }
  points.spacing = mean_edge;
}

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

Aabb empty_box() { return {{kInf, kInf, kInf}, {-kInf, -kInf, -kInf}}; }

void grow(Aabb& b, const Vec3& x, int dim) {
  for (int k = 0; k < dim; ++k) b.lo[k] = std::min(b.lo[k], x[k]), b.hi[k] = std::max(b.hi[k], x[k]);
}

// The box over every rank, exact.
Aabb reduced(Aabb b) {
  std::array<double, 6> v{-b.lo[0], -b.lo[1], -b.lo[2], b.hi[0], b.hi[1], b.hi[2]};
  parallel::max_over_ranks(v);
  return {{-v[0], -v[1], -v[2]}, {v[3], v[4], v[5]}};
}

// The Morton cells of a key's top bits and the ranks' ranges of them.
struct KeyCut {
  MortonGrid grid;
  int per_axis = 0;                  // bits per axis of a cell index
  int shift = 0;                     // key >> shift: the cell
  std::vector<std::uint64_t> first;  // ranks + 1: rank r owns cells [first[r], first[r + 1])
  std::vector<std::uint32_t> counts;  // nodes per cell

  std::uint64_t cell(std::uint64_t key) const { return key >> shift; }
  int owner(std::uint64_t key) const {
    return int(std::upper_bound(first.begin() + 1, first.end(), cell(key)) - first.begin()) - 1;
  }
  // Cell k's box, grown by one quantisation step.
  Aabb box(std::uint64_t k) const {
    const double side = double(std::uint64_t(1) << (MortonGrid::bits - per_axis)) / grid.scale, quantum = 1 / grid.scale;
    Aabb b{};
    for (int a = 0; a < grid.dim; ++a) {
      std::uint64_t q = 0;  // the cell's index along a: every dim-th bit of k
      for (int bit = 0; bit < per_axis; ++bit) q |= ((k >> (bit * grid.dim + a)) & 1) << bit;
      b.lo[a] = grid.box.lo[a] + double(q) * side - quantum;
      b.hi[a] = grid.box.lo[a] + double(q + 1) * side + quantum;
    }
    return b;
  }
};

// The cut of `counts` (nodes per cell) into `ranks` runs of about equal counts; empty where a
// rank would own no node.
std::optional<KeyCut> cut_keys(const MortonGrid& grid, int per_axis, std::vector<std::uint32_t> counts, std::uint64_t nodes, int ranks) {
  KeyCut c{grid, per_axis, grid.dim * (MortonGrid::bits - per_axis), {0}, std::move(counts)};
  std::uint64_t below = 0;
  std::size_t b = 0;
  for (int r = 1; r < ranks; ++r) {
    const std::uint64_t target = nodes * std::uint64_t(r) / std::uint64_t(ranks);
    while (b < c.counts.size() && below + c.counts[b] <= target) below += c.counts[b++];
    // The cell that crosses the target goes to the side it is nearer to.
    if (b < c.counts.size() && target - below > below + c.counts[b] - target) below += c.counts[b++];
    c.first.push_back(b);
  }
  c.first.push_back(c.counts.size());
  for (int r = 0; r < ranks; ++r)
    if (std::all_of(c.counts.begin() + std::ptrdiff_t(c.first[std::size_t(r)]), c.counts.begin() + std::ptrdiff_t(c.first[std::size_t(r) + 1]),
                    [](std::uint32_t n) { return n == 0; }))
      return std::nullopt;
  return c;
}

// Cubes of side `side` from `origin`, a rank's neighbourhood on them: the cubes within some
// count of those its nodes (or cells) touch. A run of the Morton order can be two blocks far
// apart; the cubes follow its shape where the box around it would take in all between.
struct Cubes {
  Vec3 origin{};
  double side = 1;
  int dim = 2;
  static constexpr int bits = 21;  // per axis in a packed index

  std::array<std::int64_t, 3> index(const Vec3& x) const {
    std::array<std::int64_t, 3> i{0, 0, 0};
    for (int a = 0; a < dim; ++a) i[std::size_t(a)] = std::int64_t(std::floor((x[a] - origin[a]) / side));
    return i;
  }
  static std::uint64_t pack(const std::array<std::int64_t, 3>& i) {
    return std::uint64_t(i[0]) | std::uint64_t(i[1]) << bits | std::uint64_t(i[2]) << (2 * bits);
  }
  bool fits(const Aabb& box) const {
    for (int a = 0; a < dim; ++a)
      if ((box.hi[a] - origin[a]) / side + 8 >= double(std::int64_t(1) << bits)) return false;
    return true;
  }
  static std::array<std::int64_t, 3> unpack(std::uint64_t c) {
    constexpr std::uint64_t mask = (std::uint64_t(1) << bits) - 1;
    return {std::int64_t(c & mask), std::int64_t((c >> bits) & mask), std::int64_t(c >> (2 * bits))};
  }
  // The cubes within `grow` of the given ones (packed, any order, repeats allowed), packed,
  // ascending. Memory: the distinct cubes times (2 grow + 1)^dim, not the cubes listed.
  std::vector<std::uint64_t> around(std::vector<std::uint64_t> cubes, int grow) const {
    std::ranges::sort(cubes);
    cubes.erase(std::unique(cubes.begin(), cubes.end()), cubes.end());
    std::vector<std::uint64_t> out;
    for (auto c : cubes) {
      const auto q = unpack(c);
      const std::int64_t gz = dim == 3 ? grow : 0;
      for (auto k = std::max<std::int64_t>(q[2] - gz, 0); k <= q[2] + gz; ++k)
        for (auto j = std::max<std::int64_t>(q[1] - grow, 0); j <= q[1] + grow; ++j)
          for (auto i = std::max<std::int64_t>(q[0] - grow, 0); i <= q[0] + grow; ++i) out.push_back(pack({i, j, k}));
    }
    std::ranges::sort(out);
    out.erase(std::unique(out.begin(), out.end()), out.end());
    return out;
  }
  bool in(const std::vector<std::uint64_t>& cubes, const Vec3& x) const { return std::ranges::binary_search(cubes, pack(index(x))); }
};

// One reading of the nodes and elements with the held margin `margin`: what a rank keeps, and
// what it adds to the whole mesh's figures (reduced by the caller).
struct Reading {
  // Held nodes, in file order.
  std::vector<std::size_t> tag;
  std::vector<Vec3> x;
  std::vector<std::uint64_t> key;
  std::vector<std::uint8_t> owned, used;
  std::vector<std::uint32_t> refs;  // top elements that use the node (all of them: every rank reads every element)
  // Elements whose nodes it all holds, per top entity (ascending tag), each in file order.
  std::map<long long, std::vector<std::array<std::int32_t, 4>>> kept;
  // (dim, entity) of the blocks with held nodes, and the pairs (block, held node) of their elements.
  std::vector<std::pair<int, long long>> blocks;
  std::vector<std::pair<std::int32_t, std::int32_t>> members;
  std::set<int> types;                                   // of the non-empty blocks
  std::set<long long> top_entities;                      // with top elements (the same on every rank)
  std::map<long long, std::array<std::int64_t, 2>> sign;  // per top entity: owned elements of positive, negative measure
  ExactSum edges;
  double longest = 0;
  std::int64_t counted = 0, top = 0;  // top elements this rank owns; top elements in the file
  bool reaches_out = false;           // an owned element with a node not held: the margin was too small
  MshHeader header;                   // with the physical tags of every entity (format 2.2 names them with the elements)
};

double measure(const std::array<Vec3, 4>& p, int dim) { return dim == 2 ? signed_area(p[0], p[1], p[2]) : signed_volume(p[0], p[1], p[2], p[3]); }

// held: the cubes whose nodes this rank keeps.
Reading read_part(const std::filesystem::path& file, int dim, const KeyCut& cut, int rank, const Cubes& cubes, const std::vector<std::uint64_t>& held_cubes) {
  Reading r;
  const int nodes_per = dim + 1, type = dim == 2 ? 2 : 4;
  stream_msh(file, {.nodes_only = true, .node = [&](std::size_t tag, const std::array<double, 3>& a) {
                      const Vec3 x{a[0], a[1], a[2]};
                      if (!cubes.in(held_cubes, x)) return;
                      const auto key = cut.grid.key(x);
                      r.tag.push_back(tag);
                      r.x.push_back(x);
                      r.key.push_back(key);
                      r.owned.push_back(cut.owner(key) == rank);
                    }});
  TagMap held(r.tag);
  for (std::size_t i = 0; i < r.tag.size(); ++i) held.set(r.tag[i], std::int64_t(i));
  held.done();  // the tags are unique: read_mesh_part checked every one
  r.used.assign(r.tag.size(), 0);
  r.refs.assign(r.tag.size(), 0);
  int block_dim = -1, block_type = 0;
  long long block_entity = 0;
  std::int32_t block = -1;  // index into r.blocks once an element of the block holds a held node
  std::array<std::int32_t, 27> local{};  // held index of each node of the element, -1: not held
  r.header = stream_msh(file, {.block = [&](int d, int t, long long entity) { block_dim = d, block_type = t, block_entity = entity, block = -1; },
                    .element = [&](std::size_t, std::span<const std::size_t> nodes) {
                      r.types.insert(block_type);
                      if (block_dim > dim) return;
                      const bool top = block_dim == dim && block_type == type;
                      int held_here = 0;
                      for (std::size_t a = 0; a < nodes.size(); ++a) held_here += (local[a] = std::int32_t(held.find(nodes[a]))) >= 0;
                      if (held_here > 0 && block < 0) {
                        block = std::int32_t(r.blocks.size());
                        r.blocks.push_back({block_dim, block_entity});
                      }
                      for (std::size_t a = 0; a < nodes.size(); ++a)
                        if (local[a] >= 0 && (r.members.empty() || r.members.back() != std::pair{block, local[a]})) r.members.push_back({block, local[a]});
                      if (!top) return;
                      ++r.top;
                      r.top_entities.insert(block_entity);
                      for (int a = 0; a < nodes_per; ++a)
                        if (local[std::size_t(a)] >= 0) r.used[std::size_t(local[std::size_t(a)])] = 1, ++r.refs[std::size_t(local[std::size_t(a)])];
                      const bool mine_first = local[0] >= 0 && r.owned[std::size_t(local[0])];
                      if (held_here < nodes_per) {
                        for (int a = 0; a < nodes_per; ++a) r.reaches_out |= local[std::size_t(a)] >= 0 && r.owned[std::size_t(local[std::size_t(a)])];
                        return;
                      }
                      r.kept[block_entity].push_back({local[0], local[1], local[2], local[3]});
                      if (!mine_first) return;
                      ++r.counted;
                      std::array<Vec3, 4> p{};
                      for (int a = 0; a < nodes_per; ++a) p[std::size_t(a)] = r.x[std::size_t(local[std::size_t(a)])];
                      const double m = measure(p, dim);
                      auto& s = r.sign[block_entity];
                      s[0] += m > 0, s[1] += m < 0;
                      for (int a = 0; a < nodes_per; ++a)
                        for (int b = a + 1; b < nodes_per; ++b) {
                          // The edges mean_edge sums: a triangle's three, a tetrahedron's six.
                          r.edges += dim == 2 ? triangle_edge(p[std::size_t(a)], p[std::size_t(b)]) : tet_edge(p[std::size_t(a)], p[std::size_t(b)]);
                          r.longest = std::max(r.longest, norm(p[std::size_t(a)] - p[std::size_t(b)]));
                        }
                    }});
  return r;
}

}  // namespace

std::vector<std::int64_t> nodes_near_owned(const MeshSpec::Part& part, int rank, int depth, double reach) {
  if (!(reach <= part.cube_side)) throw std::logic_error("nodes_near_owned: a reach beyond the part's cubes");
  const Cubes cubes{part.cube_origin, part.cube_side, part.points.dim};
  // The owned nodes by cube.
  std::vector<std::pair<std::uint64_t, std::int32_t>> owned;
  for (std::size_t i = 0; i < part.ids.size(); ++i)
    if (part.owner[i] == rank) owned.push_back({Cubes::pack(cubes.index(part.points.position(i))), std::int32_t(i)});
  std::ranges::sort(owned);
  const double r2 = double(depth) * reach * double(depth) * reach;
  const int dim = part.points.dim;
  const auto near_owned = [&](const Vec3& x) {
    const auto c = cubes.index(x);
    for (std::int64_t dk = dim == 3 ? -depth : 0; dk <= (dim == 3 ? depth : 0); ++dk)
      for (std::int64_t dj = -depth; dj <= depth; ++dj)
        for (std::int64_t di = -depth; di <= depth; ++di) {
          const std::array<std::int64_t, 3> q{c[0] + di, c[1] + dj, c[2] + dk};
          if (q[0] < 0 || q[1] < 0 || q[2] < 0) continue;
          const auto key = Cubes::pack(q);
          for (auto it = std::lower_bound(owned.begin(), owned.end(), std::pair<std::uint64_t, std::int32_t>{key, 0}); it != owned.end() && it->first == key; ++it) {
            const Vec3 d = part.points.position(std::size_t(it->second)) - x;
            if (d[0] * d[0] + d[1] * d[1] + d[2] * d[2] <= r2) return true;
          }
        }
    return false;
  };
  std::vector<std::int64_t> near;
  for (std::size_t i = 0; i < part.ids.size(); ++i)
    if (part.owner[i] == rank || near_owned(part.points.position(i))) near.push_back(std::int64_t(i));
  return near;
}

std::optional<MeshSpec::Part> read_mesh_part(const std::filesystem::path& file, int dim, double horizon, int depth, MeshSpec::Summary& summary) {
  const int rank = parallel::rank(), ranks = parallel::ranks();
  const std::string reading = "reading the mesh";
  // 1 and 2: every rank reads every node, so each finds the same box and histogram alone.
  Aabb all = empty_box();
  std::uint64_t nodes = 0;
  std::size_t largest_tag = 0;
  std::optional<KeyCut> cut;
  parallel::together(reading, [&] {
    stream_msh(file, {.nodes_only = true, .node = [&](std::size_t tag, const std::array<double, 3>& x) {
                        grow(all, {x[0], x[1], x[2]}, dim);
                        largest_tag = std::max(largest_tag, tag);
                        ++nodes;
                      }});
    if (nodes < std::uint64_t(ranks)) return;
    // A node tag given twice, anywhere in the file: one bit per tag (N / 8 bytes where Gmsh
    // numbers the nodes 1..N, as it does). Checked here on every node, since two far apart are
    // held by no one rank. Tags far sparser than that go through rank 0, which checks the file
    // whole.
    if (largest_tag > 64 * nodes + 1024) return;
    const MortonGrid grid = morton_grid(all, dim);
    if (!(grid.scale > 0)) return;
    const int per_axis = dim == 2 ? 10 : 7;
    std::vector<std::uint32_t> counts(std::size_t(1) << (dim * per_axis), 0);
    std::vector<std::uint64_t> seen(largest_tag / 64 + 1, 0);
    std::optional<std::size_t> repeated;  // the least tag given twice, as the whole-mesh reader names it
    const int shift = dim * (MortonGrid::bits - per_axis);
    stream_msh(file, {.nodes_only = true, .node = [&](std::size_t tag, const std::array<double, 3>& x) {
                        ++counts[grid.key({x[0], x[1], x[2]}) >> shift];
                        auto& word = seen[tag / 64];
                        const std::uint64_t bit = std::uint64_t(1) << (tag % 64);
                        if (word & bit) repeated = std::min(repeated.value_or(tag), tag);
                        word |= bit;
                      }});
    // Every rank found it; rank 0 says so, once.
    if (repeated && rank == 0) throw std::invalid_argument(fmt::format("{}: Gmsh cannot read it: node tag {} appears twice", file.string(), *repeated));
    if (!repeated) cut = cut_keys(grid, per_axis, counts, nodes, ranks);
  });
  if (!cut) return std::nullopt;  // every rank alike: the same file, the same arithmetic

  // 3 and 4 on cubes of a bond reach's side, 1.01 (horizon + longest edge), so that every node
  // within `depth` reaches of an owned node lies within `depth` cubes of its cube, and its
  // elements' nodes within one more. The longest edge is guessed (four mean spacings) and the
  // guess grown until no owned element reaches past the held nodes and the measured longest
  // edge is within it.
  double extent = 1;
  for (int k = 0; k < dim; ++k) extent *= std::max(all.hi[k] - all.lo[k], 1e-300);
  double longest = 4 * std::pow(extent / double(nodes), 1.0 / dim);
  const double diagonal = norm(all.hi - all.lo);
  Reading r;
  Cubes cubes{all.lo, 1, dim};
  std::array<double, 2> figures{};
  for (;;) {
    cubes.side = 1.01 * (horizon + longest);
    if (!cubes.fits(all)) return std::nullopt;  // every rank alike
    parallel::together(reading, [&] {
      // The cubes this rank's cells touch, grown by depth + 1.
      std::vector<std::uint64_t> touched;
      for (std::uint64_t k = cut->first[std::size_t(rank)]; k < cut->first[std::size_t(rank) + 1]; ++k)
        if (cut->counts[k]) {
          const Aabb b = cut->box(k);
          const auto lo = cubes.index(b.lo), hi = cubes.index(b.hi);
          for (auto z = lo[2]; z <= hi[2]; ++z)
            for (auto y = lo[1]; y <= hi[1]; ++y)
              for (auto x = lo[0]; x <= hi[0]; ++x) touched.push_back(Cubes::pack({std::max<std::int64_t>(x, 0), std::max<std::int64_t>(y, 0), std::max<std::int64_t>(z, 0)}));
          if (touched.size() > (std::size_t(1) << 20)) {  // keep the list to the distinct cubes as it grows
            std::ranges::sort(touched);
            touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
          }
        }
      r = read_part(file, dim, *cut, rank, cubes, cubes.around(std::move(touched), depth + 1));
    });
    figures = {r.reaches_out ? 1.0 : 0.0, r.longest};
    parallel::max_over_ranks(figures);
    if (figures[0] == 0 && figures[1] <= longest) break;
    if (longest > 2 * diagonal) {
      // Every node is held and an element still reaches past them: it names a node that does not exist.
      throw std::invalid_argument(fmt::format("{}: an element refers to a node that $Nodes does not list", file.string()));
    }
    longest = std::max(2 * longest, figures[1]);
  }

  // The whole mesh's figures: exact sums and maxima, so every rank has one process's.
  std::vector<std::int64_t> sums{r.counted};
  for (long long entity : r.top_entities) {
    const auto it = r.sign.find(entity);
    sums.push_back(it == r.sign.end() ? 0 : it->second[0]);
    sums.push_back(it == r.sign.end() ? 0 : it->second[1]);
  }
  parallel::sum_over_ranks(sums);
  ExactSum edge_sum = r.edges;
  parallel::sum_over_ranks(edge_sum.words_for_reduction());
  edge_sum.normalise();
  const int nodes_per = dim + 1;
  std::vector<long long> flipped;  // top entities whose elements all run the other way
  parallel::together(reading, [&] {
    std::vector<int> types(r.types.begin(), r.types.end());
    require_msh_element_types(file, dim, types);
    if (sums[0] != r.top) throw std::invalid_argument(fmt::format("{}: an element refers to a node that $Nodes does not list", file.string()));
    std::size_t k = 1;
    for (long long entity : r.top_entities) {
      const auto positive = sums[k++], negative = sums[k++];
      if (positive > 0 && negative > 0)
        throw std::invalid_argument(fmt::format("{}: inverted elements: {} of the {} of {} {} run opposite to the other {}", file.string(),
                                                std::min(positive, negative), positive + negative, dim == 2 ? "surface" : "volume", entity,
                                                std::max(positive, negative)));
      if (negative > 0) flipped.push_back(entity);
    }
  });
  const double mean_edge = r.top > 0 ? edge_sum.value() / double((dim == 2 ? 3 : 6) * r.top) : 0.0;

  // The used nodes: their box must be the box the keys were cut on, or the numbering's keys
  // (over the used nodes, as one process makes them) would differ from the cut's.
  Aabb used_box = empty_box();
  for (std::size_t i = 0; i < r.x.size(); ++i)
    if (r.used[i] && r.owned[i]) grow(used_box, r.x[i], dim);
  used_box = reduced(used_box);
  // Owned used nodes in key order; a tie (two nodes in one Morton cell) is numbered by tag by one
  // process, which the owners' keys alone cannot say to the ghosts' holders.
  std::vector<std::int32_t> mine;
  for (std::size_t i = 0; i < r.x.size(); ++i)
    if (r.used[i] && r.owned[i]) mine.push_back(std::int32_t(i));
  std::ranges::sort(mine, [&](std::int32_t a, std::int32_t b) { return std::pair(r.key[std::size_t(a)], r.tag[std::size_t(a)]) < std::pair(r.key[std::size_t(b)], r.tag[std::size_t(b)]); });
  bool tie = false;
  for (std::size_t k = 1; k < mine.size(); ++k) tie |= r.key[std::size_t(mine[k])] == r.key[std::size_t(mine[k - 1])];
  bool same_box = true;
  for (int k = 0; k < dim; ++k) same_box &= used_box.lo[k] == all.lo[k] && used_box.hi[k] == all.hi[k];
  if (parallel::max_over_ranks(tie || mine.empty() || !same_box ? 1 : 0) != 0) return std::nullopt;

  MeshSpec::Part part;
  part.owned_counts.resize(std::size_t(ranks));
  {
    const auto counts = parallel::all_gather(std::uint64_t(mine.size()));
    for (int q = 0; q < ranks; ++q) part.owned_counts[std::size_t(q)] = counts[std::size_t(q)];
  }
  const std::uint64_t first_id = std::accumulate(part.owned_counts.begin(), part.owned_counts.begin() + rank, std::uint64_t(0));
  // Global ids: owned nodes by their place in key order; ghosts ask their owners where their
  // keys stand among the owners' (index_on_owners, keys as ids: below 2^63).
  std::vector<std::int64_t> id(r.x.size(), -1);
  std::vector<std::int64_t> owned_keys(mine.size());
  for (std::size_t k = 0; k < mine.size(); ++k) id[std::size_t(mine[k])] = std::int64_t(first_id + k), owned_keys[k] = std::int64_t(r.key[std::size_t(mine[k])]);
  std::vector<std::int64_t> ghost_keys;
  std::vector<int> ghost_owner;
  std::vector<std::int32_t> ghosts;
  for (std::size_t i = 0; i < r.x.size(); ++i)
    if (r.used[i] && !r.owned[i]) {
      ghosts.push_back(std::int32_t(i));
      ghost_keys.push_back(std::int64_t(r.key[i]));
      ghost_owner.push_back(cut->owner(r.key[i]));
    }
  const auto at = parallel::index_on_owners(ghost_keys, ghost_owner, owned_keys);
  std::vector<std::uint64_t> starts(std::size_t(ranks) + 1, 0);
  for (int q = 0; q < ranks; ++q) starts[std::size_t(q) + 1] = starts[std::size_t(q)] + part.owned_counts[std::size_t(q)];

  parallel::together(reading, [&] {
    for (std::size_t k = 0; k < ghosts.size(); ++k) {
      if (at[k] < 0) throw std::logic_error("read_mesh_part: a used node's owner does not hold it");
      id[std::size_t(ghosts[k])] = std::int64_t(starts[std::size_t(ghost_owner[k])]) + at[k];
    }
    // The held used nodes by global id; the unused ones go.
    std::vector<std::int32_t> order;
    for (std::size_t i = 0; i < r.x.size(); ++i)
      if (r.used[i]) order.push_back(std::int32_t(i));
    std::ranges::sort(order, [&](std::int32_t a, std::int32_t b) { return id[std::size_t(a)] < id[std::size_t(b)]; });
    std::vector<std::int32_t> to(r.x.size(), -1);
    for (std::size_t k = 0; k < order.size(); ++k) to[std::size_t(order[k])] = std::int32_t(k);
    // 2D: z must be 0 (relative to the mesh's size), as the whole-mesh reader requires.
    const double flat = 1e-10 * std::max({used_box.hi[0] - used_box.lo[0], used_box.hi[1] - used_box.lo[1], 1e-300});
    std::vector<Vec3> x(order.size());
    part.ids.resize(order.size());
    part.owner.resize(order.size());
    for (std::size_t k = 0; k < order.size(); ++k) {
      const auto i = std::size_t(order[k]);
      x[k] = r.x[i];
      if (dim == 2) {
        if (std::abs(x[k][2]) > flat) throw std::invalid_argument(fmt::format("{}: the mesh is not planar in z = 0: node {} has z = {:g} m", file.string(), r.tag[i], x[k][2]));
        x[k][2] = 0;
      }
      part.ids[k] = id[i];
      part.owner[k] = cut->owner(r.key[i]);
    }
    // The elements in mesh order (entities ascending, each in file order), renumbered, those of
    // an entity meshed the other way turned (two nodes swapped) as the whole-mesh reader turns them.
    std::vector<std::array<std::int32_t, 4>> elements;
    std::vector<std::uint32_t> kept_refs(order.size(), 0);
    for (auto& [entity, list] : r.kept) {
      const bool turn = std::ranges::binary_search(flipped, entity);
      for (auto e : list) {
        for (int a = 0; a < nodes_per; ++a) e[std::size_t(a)] = to[std::size_t(e[std::size_t(a)])], ++kept_refs[std::size_t(e[std::size_t(a)])];
        if (turn) std::swap(e[1], e[2]);
        elements.push_back(e);
      }
    }
    part.complete.resize(order.size());
    for (std::size_t k = 0; k < order.size(); ++k) part.complete[k] = kept_refs[k] == r.refs[std::size_t(order[k])];
    if (dim == 2) {
      TriangleMesh m;
      m.nodes = std::move(x);
      for (const auto& e : elements) m.triangles.push_back({e[0], e[1], e[2]});
      take_part_mesh(part, std::move(m), mean_edge, file.string());
    } else {
      TetMesh m;
      m.nodes = std::move(x);
      m.tetrahedra = std::move(elements);
      take_part_mesh(part, std::move(m), mean_edge, file.string());
    }
    // Groups: the used nodes of every block whose entity carries the group's physical tag, as
    // the whole-mesh reader gathers them.
    const auto group_names = [&](int d, long long entity) {
      std::vector<std::string> names;
      if (const auto it = r.header.physicals.find({d, entity}); it != r.header.physicals.end())
        for (long long t : it->second) {
          const auto named = r.header.names.find({d, t});
          names.push_back(msh_group_name(named == r.header.names.end() ? std::string() : named->second, d, t, dim));
        }
      return names;
    };
    for (const auto& [entity, tags] : r.header.physicals)
      if (entity.first <= dim)
        for (const auto& name : group_names(entity.first, entity.second)) {
          summary.groups[name];
          part.groups[name];
        }
    std::vector<std::vector<std::string>> block_groups;
    for (const auto& [d, entity] : r.blocks) block_groups.push_back(group_names(d, entity));
    for (const auto& [b, node] : r.members)
      if (to[std::size_t(node)] >= 0)
        for (const auto& name : block_groups[std::size_t(b)]) part.groups[name].push_back(part.ids[std::size_t(to[std::size_t(node)])]);
    for (auto& [name, ids] : part.groups) {
      std::ranges::sort(ids);
      ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
    }
  });
  part.longest_edge = figures[1];
  part.depth = depth;
  part.cube_origin = cubes.origin;
  part.cube_side = cubes.side;
  summary.bounds = {{used_box.lo[0], used_box.lo[1], dim == 3 ? used_box.lo[2] : 0.0}, {used_box.hi[0], used_box.hi[1], dim == 3 ? used_box.hi[2] : 0.0}};
  summary.mean_edge = mean_edge;
  return part;
}

}  // namespace peridot
