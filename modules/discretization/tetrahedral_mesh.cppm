export module peridot.discretization:tetrahedral_mesh;
import peridot.std;
import peridot.geometry;
import :point_cloud;
import :triangle_mesh;

export namespace peridot {

// det[b - a, c - a, d - a] / 6: > 0 when a, b, c, d are positively oriented [m^3].
double signed_volume(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);
// An edge's length, as mean_edge sums it [m].
double tet_edge(const Vec3& p, const Vec3& q);

// A 3D mesh of linear (P1) tetrahedra: nodes, positively oriented tetrahedra of node indices
// (det[b - a, c - a, d - a] > 0), and named node sets (Gmsh physical groups of dimension 0-3)
// for boundary conditions.
struct TetMesh {
  std::vector<Vec3> nodes;                                     // [m]
  std::vector<std::array<std::int32_t, 4>> tetrahedra;
  std::map<std::string, std::vector<std::int32_t>> groups;    // sorted node indices

  Aabb bounds() const { return bounds_of(nodes); }
  double volume(std::size_t t) const;  // signed: > 0 positively oriented [m^3]
  double mean_edge() const;            // over the six edges of every tetrahedron [m]
};

// The box [lo, hi] in nx x ny x nz cells, each cut into the six tetrahedra around its diagonal
// from the lower corner to the upper one (Kuhn's triangulation: conforming, since every cell is
// cut alike). Groups: left/right (x = lo, hi), bottom/top (y), back/front (z). Nodes are
// numbered x fastest, then y, then z; cells likewise.
// nodes: the node index ranges {i0, i1, j0, j1, k0, k1} (each inclusive) to make, with the
// cells between them, numbered x fastest from (i0, j0, k0) (a rank's part of the whole mesh,
// whose node ids are (k (ny + 1) + j) (nx + 1) + i); each group keeps its name, empty where the
// ranges miss its side.
TetMesh structured_tetrahedra(Vec3 lo, Vec3 hi, int nx, int ny, int nz,
                              std::array<int, 6> nodes = {0, std::numeric_limits<int>::max(), 0, std::numeric_limits<int>::max(), 0,
                                                          std::numeric_limits<int>::max()});

// Throws std::invalid_argument for an empty mesh, node indices out of range, or a degenerate
// or inverted (negative volume) tetrahedron, naming the element.
void validate(const TetMesh& mesh, std::optional<double> mean_edge = std::nullopt);  // as for triangles

// The mesh nodes as a 3D point cloud: each node's volume is a quarter of the volume of the
// tetrahedra around it (the lumped P1 mass); the tetrahedra travel along for output and V_ij.
PointCloud mesh_points(const TetMesh& mesh);

}  // namespace peridot

namespace peridot {

double TetMesh::volume(std::size_t t) const {
  const auto& e = tetrahedra[t];
  return signed_volume(nodes[std::size_t(e[0])], nodes[std::size_t(e[1])], nodes[std::size_t(e[2])], nodes[std::size_t(e[3])]);
}

double signed_volume(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]},
               w[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
  return (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0]) + u[2] * (v[0] * w[1] - v[1] * w[0])) / 6;
}

double tet_edge(const Vec3& p, const Vec3& q) { return std::sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) + (p[2] - q[2]) * (p[2] - q[2])); }

// An exact sum, as TriangleMesh::mean_edge's.
double TetMesh::mean_edge() const {
  ExactSum sum;
  for (const auto& t : tetrahedra)
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) sum += tet_edge(nodes[std::size_t(t[std::size_t(a)])], nodes[std::size_t(t[std::size_t(b)])]);
  return tetrahedra.empty() ? 0.0 : sum.value() / double(6 * tetrahedra.size());
}

TetMesh structured_tetrahedra(Vec3 lo, Vec3 hi, int nx, int ny, int nz, std::array<int, 6> nodes) {
  if (nx < 1 || ny < 1 || nz < 1 || !(hi[0] > lo[0]) || !(hi[1] > lo[1]) || !(hi[2] > lo[2]))
    throw std::invalid_argument("structured_tetrahedra: need nx, ny, nz >= 1 and hi > lo");
  if (double(nx + 1) * double(ny + 1) * double(nz + 1) > 2e9) throw std::invalid_argument("structured_tetrahedra: more than 2e9 nodes");
  const int i0 = std::max(nodes[0], 0), i1 = std::min(nodes[1], nx), j0 = std::max(nodes[2], 0), j1 = std::min(nodes[3], ny),
            k0 = std::max(nodes[4], 0), k1 = std::min(nodes[5], nz);
  if (i0 > i1 || j0 > j1 || k0 > k1) throw std::invalid_argument("structured_tetrahedra: an empty range of nodes");
  TetMesh m;
  m.nodes.reserve(std::size_t(i1 - i0 + 1) * std::size_t(j1 - j0 + 1) * std::size_t(k1 - k0 + 1));
  for (int k = k0; k <= k1; ++k)
    for (int j = j0; j <= j1; ++j)
      for (int i = i0; i <= i1; ++i)
        m.nodes.push_back({lo[0] + (hi[0] - lo[0]) * i / nx, lo[1] + (hi[1] - lo[1]) * j / ny, lo[2] + (hi[2] - lo[2]) * k / nz});
  const auto id = [&](int i, int j, int k) { return std::int32_t(((k - k0) * (j1 - j0 + 1) + (j - j0)) * (i1 - i0 + 1) + (i - i0)); };
  // Each tetrahedron walks from the lower corner to the upper one along the three axes in one
  // of the 3! orders; odd orders run the other way round and swap two nodes to stay positive.
  constexpr std::array<std::array<int, 3>, 6> orders{{{0, 1, 2}, {1, 2, 0}, {2, 0, 1}, {0, 2, 1}, {2, 1, 0}, {1, 0, 2}}};
  m.tetrahedra.reserve(6 * std::size_t(i1 - i0) * std::size_t(j1 - j0) * std::size_t(k1 - k0));
  for (int k = k0; k < k1; ++k)
    for (int j = j0; j < j1; ++j)
      for (int i = i0; i < i1; ++i)
        for (std::size_t o = 0; o < orders.size(); ++o) {
          std::array<int, 3> c{i, j, k};
          std::array<std::int32_t, 4> t{};
          t[0] = id(c[0], c[1], c[2]);
          for (int s = 0; s < 3; ++s) {
            ++c[std::size_t(orders[o][std::size_t(s)])];
            t[std::size_t(s + 1)] = id(c[0], c[1], c[2]);
          }
          if (o >= 3) std::swap(t[1], t[2]);
          m.tetrahedra.push_back(t);
        }
  for (const char* side : {"left", "right", "bottom", "top", "back", "front"}) m.groups[side];
  for (int k = k0; k <= k1; ++k)
    for (int j = j0; j <= j1; ++j)
      for (int i = i0; i <= i1; ++i) {
        const auto n = id(i, j, k);
        if (i == 0) m.groups["left"].push_back(n);
        if (i == nx) m.groups["right"].push_back(n);
        if (j == 0) m.groups["bottom"].push_back(n);
        if (j == ny) m.groups["top"].push_back(n);
        if (k == 0) m.groups["back"].push_back(n);
        if (k == nz) m.groups["front"].push_back(n);
      }
  return m;  // ids grow in loop order, so every group is sorted
}

void validate(const TetMesh& m, std::optional<double> mean_edge) {
  if (m.nodes.empty() || m.tetrahedra.empty()) throw std::invalid_argument("mesh has no tetrahedra");
  const auto n = std::int64_t(m.nodes.size());
  for (std::size_t t = 0; t < m.tetrahedra.size(); ++t)
    for (auto v : m.tetrahedra[t])
      if (v < 0 || v >= n) throw std::invalid_argument(fmt::format("tetrahedron {} refers to node {}, but the mesh has {} nodes", t, v, n));
  // Degenerate relative to the mesh's own scale: a sliver far below round-off of a typical cell.
  const double h = mean_edge ? *mean_edge : m.mean_edge(), tiny = 1e-10 * h * h * h;
  for (std::size_t t = 0; t < m.tetrahedra.size(); ++t) {
    const double v = m.volume(t);
    const auto& e = m.tetrahedra[t];
    if (std::abs(v) <= tiny)
      throw std::invalid_argument(fmt::format("tetrahedron {} (nodes {}, {}, {}, {}) is degenerate: volume {:.3g} m^3", t, e[0], e[1], e[2], e[3], v));
    if (v < 0)
      throw std::invalid_argument(fmt::format("tetrahedron {} (nodes {}, {}, {}, {}) is inverted: negative volume {:.3g} m^3", t, e[0], e[1], e[2],
                                              e[3], v));
  }
}

PointCloud mesh_points(const TetMesh& m) {
  validate(m);
  PointCloud pc = lumped_nodes(m.nodes, m.tetrahedra, [&](std::size_t t) { return m.volume(t); }, "tetrahedron");
  pc.dim = 3;
  pc.spacing = m.mean_edge();
  pc.tetrahedra = m.tetrahedra;
  return pc;
}

}  // namespace peridot
