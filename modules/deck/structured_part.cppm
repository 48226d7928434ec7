export module peridot.deck:structured_part;
import peridot.std;
import peridot.parallel;
import :spec;
import :mesh_part;

export namespace peridot {

// A structured mesh made on N MPI ranks with no rank holding it whole. Its nodes are a grid,
// numbered x fastest as one process numbers them, so the ranks own bricks of it (brick_cut, as
// lattice decks are cut; Part::bricks), and each makes only the nodes within depth + 1 bond
// reaches of its brick, and two layers more, with the cells among them (structured_triangles /
// structured_tetrahedra on a box of nodes: the whole mesh's positions, elements and element
// order). The whole mesh's figures are exact reductions, each element counted by the owner of its
// first node: the bounds, the mean edge (an exact sum, so one process's bit for bit) and the
// longest edge. Every rank holds every group's name. Returns nullopt on one rank or where no
// grid of ranks fits the nodes; the caller then makes the mesh on rank 0 (make_mesh_once).
// Collective.
std::optional<MeshSpec::Part> structured_mesh_part(const MeshSpec& ms, int dim, double horizon, int depth, MeshSpec::Summary& summary);

}  // namespace peridot

namespace peridot {

std::optional<MeshSpec::Part> structured_mesh_part(const MeshSpec& ms, int dim, double horizon, int depth, MeshSpec::Summary& summary) {
  const int rank = parallel::rank(), ranks = parallel::ranks();
  if (ranks <= 1) return std::nullopt;
  const std::array<int, 3> cells{ms.nx, ms.ny, dim == 3 ? ms.nz : 0};
  BoxLattice grid;  // the nodes as sites: the same numbering
  grid.dim = dim;
  for (int a = 0; a < dim; ++a) grid.m[std::size_t(a)] = cells[std::size_t(a)] + 1;
  std::shared_ptr<const BrickCut> cut;
  try {
    cut = std::make_shared<const BrickCut>(brick_cut(grid, ranks));
  } catch (const std::invalid_argument&) {
    return std::nullopt;  // every rank alike: too few nodes for the ranks
  }
  MeshSpec::Part part;
  part.bricks = cut;
  for (int q = 0; q < ranks; ++q) part.owned_counts.push_back(cut->count(q, 0));

  // A cell's main diagonal is its longest edge: with the horizon it bounds a bond's reach. The
  // nodes held reach depth + 1 such reaches, and two layers more, past the brick along each
  // axis: every node within depth reaches of an owned node then has all its elements held.
  double diagonal = 0;
  for (int a = 0; a < dim; ++a) diagonal += std::pow((ms.hi[a] - ms.lo[a]) / cells[std::size_t(a)], 2);
  const double bound = std::sqrt(diagonal) * (1 + 1e-9), side = 1.01 * (horizon + bound);
  const auto& brick = cut->box[std::size_t(rank)];  // [lo, hi) per axis, in nodes
  std::array<int, 6> box{0, 0, 0, 0, 0, 0};          // held nodes, inclusive
  for (int a = 0; a < dim; ++a) {
    const double spacing = (ms.hi[a] - ms.lo[a]) / cells[std::size_t(a)];
    const auto margin = std::int64_t(std::min(double(depth + 1) * side / spacing, double(cells[std::size_t(a)]))) + 2;
    box[std::size_t(2 * a)] = int(std::max<std::int64_t>(brick[std::size_t(2 * a)] - margin, 0));
    box[std::size_t(2 * a + 1)] = int(std::min<std::int64_t>(brick[std::size_t(2 * a + 1)] - 1 + margin, cells[std::size_t(a)]));
  }
  // The held nodes' grid indices and global ids (the grid's site numbering), in the part's order
  // (x fastest), and their owners.
  std::vector<std::array<int, 3>> at;
  grid.for_each_run({box[0], box[1] + 1, box[2], box[3] + 1, box[4], box[5] + 1},
                    [&](std::int64_t x0, std::int64_t x1, std::int64_t y, std::int64_t z, std::int64_t first) {
                      for (auto x = x0; x < x1; ++x) {
                        at.push_back({int(x), int(y), int(z)});
                        part.ids.push_back(first + (x - x0));
                      }
                    });
  std::vector<int> owner(at.size());
  for (std::size_t n = 0; n < at.size(); ++n) owner[n] = cut->owner(at[n][0], at[n][1], at[n][2]);

  // The box's mesh; collectives stay outside `together`, which every rank leaves alike.
  std::optional<TriangleMesh> triangles;
  std::optional<TetMesh> tets;
  parallel::together("making the mesh", [&] {
    if (dim == 2) triangles = structured_triangles(ms.lo, ms.hi, ms.nx, ms.ny, ms.lower_left_diagonal, {box[0], box[1], box[2], box[3]});
    else tets = structured_tetrahedra(ms.lo, ms.hi, ms.nx, ms.ny, ms.nz, box);
  });
  const auto& nodes_held = triangles ? triangles->nodes : tets->nodes;

  // The whole mesh's figures, each element counted by the owner of its first node.
  ExactSum edges;
  double longest = 0;
  std::int64_t counted = 0;
  const int nodes_per = dim + 1;
  const auto measure = [&](const auto& elements) {
    for (const auto& e : elements) {
      if (owner[std::size_t(e[0])] != rank) continue;
      ++counted;
      for (int a = 0; a < nodes_per; ++a)
        for (int b = a + 1; b < nodes_per; ++b) {
          const Vec3 &p = nodes_held[std::size_t(e[std::size_t(a)])], &q = nodes_held[std::size_t(e[std::size_t(b)])];
          edges += dim == 2 ? triangle_edge(p, q) : tet_edge(p, q);  // the edges mean_edge sums
          longest = std::max(longest, norm(p - q));
        }
    }
  };
  if (triangles) measure(triangles->triangles);
  else measure(tets->tetrahedra);
  constexpr double inf = std::numeric_limits<double>::infinity();
  std::array<double, 7> extremes{-inf, -inf, -inf, -inf, -inf, -inf, longest};  // -lo, hi, the longest edge
  for (std::size_t k = 0; k < nodes_held.size(); ++k)
    if (owner[k] == rank)
      for (std::size_t a = 0; a < 3; ++a) extremes[a] = std::max(extremes[a], -nodes_held[k][a]), extremes[a + 3] = std::max(extremes[a + 3], nodes_held[k][a]);
  parallel::max_over_ranks(extremes);
  parallel::sum_over_ranks(edges.words_for_reduction());
  edges.normalise();
  std::vector<std::int64_t> count{counted};
  parallel::sum_over_ranks(count);
  if (extremes[6] > bound) throw std::logic_error("structured_mesh_part: an edge longer than its cell's diagonal");
  summary.bounds = {{-extremes[0], -extremes[1], -extremes[2]}, {extremes[3], extremes[4], extremes[5]}};
  summary.mean_edge = edges.value() / double((dim == 2 ? 3 : 6) * count[0]);
  part.longest_edge = extremes[6];

  parallel::together("making the mesh", [&] {
    part.owner = std::move(owner);
    for (std::size_t n = 0; n < at.size(); ++n) {
      // Its elements lie in the cells on either side of it along each axis.
      bool complete = true;
      for (int a = 0; a < dim; ++a) {
        const int q = at[n][std::size_t(a)], lo = box[std::size_t(2 * a)], hi = box[std::size_t(2 * a + 1)];
        complete &= (q > lo || lo == 0) && (q < hi || hi == cells[std::size_t(a)]);
      }
      part.complete.push_back(complete);
    }
    for (const auto& [name, members] : triangles ? triangles->groups : tets->groups) {
      summary.groups[name];
      auto& ids = part.groups[name];
      for (auto i : members) ids.push_back(part.ids[std::size_t(i)]);
    }
    if (triangles) take_part_mesh(part, std::move(*triangles), summary.mean_edge, "structured mesh");
    else take_part_mesh(part, std::move(*tets), summary.mean_edge, "structured mesh");
  });
  part.depth = depth;
  part.cube_origin = summary.bounds.lo;
  part.cube_side = side;
  return part;
}

}  // namespace peridot
