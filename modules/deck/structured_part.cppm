export module peridot.deck:structured_part;
import peridot.std;
import peridot.parallel;
import :spec;
import :mesh_part;

export namespace peridot {

// A structured mesh made on N MPI ranks with no rank holding it whole. One process numbers its
// nodes row by row (in 3D layer by layer along z), so rank r owns the run [N r / ranks,
// N (r + 1) / ranks) of that numbering, and makes only the rows (layers) within depth + 1 bond
// reaches of its run, with the cells between them (structured_triangles / structured_tetrahedra
// on a range of rows): the same positions, elements and element order as the whole mesh's. The
// whole mesh's figures are exact reductions, each element counted by the owner of its first node:
// the bounds, the mean edge (an exact sum, so one process's bit for bit) and the longest edge.
// Every rank holds every group's name. Returns nullopt on one rank or where a rank would own no
// node; the caller then makes the mesh on rank 0 (make_mesh_once). Collective.
std::optional<MeshSpec::Part> structured_mesh_part(const MeshSpec& ms, int dim, double horizon, int depth, MeshSpec::Summary& summary);

}  // namespace peridot

namespace peridot {

std::optional<MeshSpec::Part> structured_mesh_part(const MeshSpec& ms, int dim, double horizon, int depth, MeshSpec::Summary& summary) {
  const int rank = parallel::rank(), ranks = parallel::ranks();
  if (ranks <= 1) return std::nullopt;
  const int axis = dim - 1;  // the slowest index of the numbering: rows (y) in 2D, layers (z) in 3D
  const int layers = dim == 2 ? ms.ny : ms.nz;
  const std::uint64_t per_layer = std::uint64_t(ms.nx + 1) * (dim == 2 ? 1 : std::uint64_t(ms.ny + 1));
  const std::uint64_t nodes = per_layer * std::uint64_t(layers + 1);
  if (nodes < std::uint64_t(ranks)) return std::nullopt;  // every rank alike
  MeshSpec::Part part;
  std::vector<std::uint64_t> start(std::size_t(ranks) + 1);
  for (int q = 0; q <= ranks; ++q) start[std::size_t(q)] = nodes * std::uint64_t(q) / std::uint64_t(ranks);
  for (int q = 0; q < ranks; ++q) part.owned_counts.push_back(start[std::size_t(q) + 1] - start[std::size_t(q)]);

  // A cell's main diagonal is its longest edge: with the horizon it bounds a bond's reach. The
  // rows held reach depth + 1 such reaches, and two rows more, past the owned ones: every node
  // within depth reaches of an owned node then has all its elements held.
  double diagonal = 0;
  for (int k = 0; k < dim; ++k) diagonal += std::pow((ms.hi[k] - ms.lo[k]) / (k == 0 ? ms.nx : k == 1 ? ms.ny : ms.nz), 2);
  const double bound = std::sqrt(diagonal) * (1 + 1e-9), side = 1.01 * (horizon + bound);
  const double spacing = (ms.hi[axis] - ms.lo[axis]) / layers;
  const int margin = int(std::min(double(depth + 1) * side / spacing, double(layers))) + 2;
  const auto layer_of = [&](std::uint64_t id) { return int(id / per_layer); };
  const int own_first = layer_of(start[std::size_t(rank)]), own_last = layer_of(start[std::size_t(rank) + 1] - 1);
  const int first = std::max(0, own_first - margin), last = std::min(layers, own_last + margin);
  const std::uint64_t offset = std::uint64_t(first) * per_layer;
  const auto owner = [&](std::uint64_t id) { return int(std::upper_bound(start.begin() + 1, start.end(), id) - start.begin()) - 1; };

  // The rows' mesh; collectives stay outside `together`, which every rank leaves alike.
  std::optional<TriangleMesh> triangles;
  std::optional<TetMesh> tets;
  parallel::together("making the mesh", [&] {
    if (dim == 2) triangles = structured_triangles(ms.lo, ms.hi, ms.nx, ms.ny, ms.lower_left_diagonal, {first, last});
    else tets = structured_tetrahedra(ms.lo, ms.hi, ms.nx, ms.ny, ms.nz, {first, last});
  });
  const auto& nodes_held = triangles ? triangles->nodes : tets->nodes;

  // The whole mesh's figures, each element counted by the owner of its first node.
  ExactSum edges;
  double longest = 0;
  std::int64_t counted = 0;
  const int nodes_per = dim + 1;
  const auto measure = [&](const auto& elements) {
    for (const auto& e : elements) {
      if (owner(offset + std::uint64_t(e[0])) != rank) continue;
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
    if (owner(offset + k) == rank)
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
    for (std::size_t k = 0; k < nodes_held.size(); ++k) {
      const std::uint64_t id = offset + k;
      const int layer = layer_of(id);
      part.ids.push_back(std::int64_t(id));
      part.owner.push_back(owner(id));
      // Its elements lie in the cells on either side of its row.
      part.complete.push_back((layer > first || first == 0) && (layer < last || last == layers));
    }
    for (const auto& [name, members] : triangles ? triangles->groups : tets->groups) {
      summary.groups[name];
      auto& ids = part.groups[name];
      for (auto i : members) ids.push_back(std::int64_t(offset) + i);
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
