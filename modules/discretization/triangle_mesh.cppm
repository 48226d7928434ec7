export module peridot.discretization:triangle_mesh;
import peridot.std;
import peridot.geometry;
import :point_cloud;

export namespace peridot {

// The smallest box holding every node (all zero for none).
Aabb bounds_of(const std::vector<Vec3>& nodes);

// A P1 mesh's nodes as a point cloud (dim and spacing left to the caller): each node's volume
// is 1/N of the measure of each element around it (the lumped P1 mass). A node no element uses
// (Gmsh geometry points, say) would have no mass and no bonds: refused, naming the node.
// The volumes alone, summed over the elements in their order (zero where none is listed).
template <std::size_t N, class Measure>
std::vector<double> lumped_volumes(std::size_t nodes, const std::vector<std::array<std::int32_t, N>>& elements, Measure measure) {
  std::vector<double> vol(nodes, 0.0);
  for (std::size_t t = 0; t < elements.size(); ++t)
    for (auto v : elements[t]) vol[std::size_t(v)] += measure(t) / double(N);
  return vol;
}
template <std::size_t N, class Measure>
PointCloud lumped_nodes(const std::vector<Vec3>& nodes, const std::vector<std::array<std::int32_t, N>>& elements, Measure measure,
                        const char* element) {
  PointCloud pc;
  const std::vector<double> vol = lumped_volumes(nodes.size(), elements, measure);
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    if (!(vol[i] > 0)) throw std::invalid_argument(fmt::format("mesh node {} belongs to no {}", i, element));
    pc.push_back(nodes[i], vol[i]);
  }
  return pc;
}

// Half the cross product of b - a and c - a in the xy plane: > 0 counter-clockwise [m^2].
double signed_area(const Vec3& a, const Vec3& b, const Vec3& c);
// An edge's length in the xy plane, as mean_edge sums it [m].
double triangle_edge(const Vec3& a, const Vec3& b);

// A 2D mesh of linear (P1) triangles: nodes, counter-clockwise triangles of node indices,
// and named node sets (Gmsh physical groups) for boundary conditions.
struct TriangleMesh {
  std::vector<Vec3> nodes;                                     // z = 0 [m]
  std::vector<std::array<std::int32_t, 3>> triangles;
  std::map<std::string, std::vector<std::int32_t>> groups;    // sorted node indices

  Aabb bounds() const { return bounds_of(nodes); }
  double area(std::size_t t) const;  // signed: > 0 counter-clockwise [m^2]
  double mean_edge() const;          // [m]
};

// The rectangle [lo, hi] in nx x ny cells, each split into two triangles along the diagonal
// from its lower-left to upper-right corner (or the other diagonal). Groups: left, right,
// bottom, top (the nodes on each side). Nodes are numbered row by row, cells likewise.
// nodes: the node index ranges [i0, i1] and [j0, j1] ({i0, i1, j0, j1}) to make, with the cells
// between them, numbered x fastest from (i0, j0) (a rank's part of the whole mesh, whose node
// ids are j (nx + 1) + i); each group keeps its name, empty where the ranges miss its side.
TriangleMesh structured_triangles(Vec3 lo, Vec3 hi, int nx, int ny, bool lower_left_diagonal = true,
                                  std::array<int, 4> nodes = {0, std::numeric_limits<int>::max(), 0, std::numeric_limits<int>::max()});

// Throws std::invalid_argument for an empty mesh, node indices out of range, or a degenerate
// or inverted (clockwise) triangle, naming the element.
// mean_edge: the scale of "degenerate", by default the mesh's own mean edge (a part of a mesh
// gives the whole mesh's).
void validate(const TriangleMesh& mesh, std::optional<double> mean_edge = std::nullopt);

// The mesh nodes as a point cloud: each node's volume is a third of the area of the triangles
// around it (the lumped P1 mass); the triangles travel along for output and interpolation.
PointCloud mesh_points(const TriangleMesh& mesh);

// Finds the triangle containing a point in O(1) on average (a uniform grid of triangle boxes),
// and evaluates P1 interpolants there.
class MeshLocator {
 public:
  explicit MeshLocator(const TriangleMesh& mesh);
  // Triangle and barycentric coordinates of x, or nothing if x is outside every triangle.
  struct Hit {
    std::int32_t triangle;
    std::array<double, 3> lambda;
  };
  std::optional<Hit> locate(const Vec3& x) const;
  // sum_a lambda_a f[node_a] at x; throws if x is outside the mesh.
  double interpolate(const std::vector<double>& nodal, const Vec3& x) const;

 private:
  const TriangleMesh* mesh_;
  double lo_[2], cell_;
  int nx_, ny_;
  std::vector<std::int32_t> start_, items_;
};

}  // namespace peridot

namespace peridot {

Aabb bounds_of(const std::vector<Vec3>& nodes) {
  Aabb b{{0, 0, 0}, {0, 0, 0}};
  if (nodes.empty()) return b;
  b.lo = b.hi = nodes[0];
  for (const auto& p : nodes)
    for (int k = 0; k < 3; ++k) b.lo[k] = std::min(b.lo[k], p[k]), b.hi[k] = std::max(b.hi[k], p[k]);
  return b;
}

double TriangleMesh::area(std::size_t t) const {
  return signed_area(nodes[std::size_t(triangles[t][0])], nodes[std::size_t(triangles[t][1])], nodes[std::size_t(triangles[t][2])]);
}

double signed_area(const Vec3& a, const Vec3& b, const Vec3& c) {
  return 0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]));
}

double triangle_edge(const Vec3& a, const Vec3& b) { return std::hypot(b[0] - a[0], b[1] - a[1]); }

// An exact sum: a rank that holds part of the mesh (read_mesh_part) sums its triangles' edges
// in another order and gets the same mean.
double TriangleMesh::mean_edge() const {
  ExactSum sum;
  for (const auto& t : triangles)
    for (int k = 0; k < 3; ++k) sum += triangle_edge(nodes[std::size_t(t[k])], nodes[std::size_t(t[(k + 1) % 3])]);
  return triangles.empty() ? 0.0 : sum.value() / double(3 * triangles.size());
}

TriangleMesh structured_triangles(Vec3 lo, Vec3 hi, int nx, int ny, bool lld, std::array<int, 4> nodes) {
  if (nx < 1 || ny < 1 || !(hi[0] > lo[0]) || !(hi[1] > lo[1])) throw std::invalid_argument("structured_triangles: need nx, ny >= 1 and hi > lo");
  if (double(nx + 1) * double(ny + 1) > 2e9) throw std::invalid_argument("structured_triangles: more than 2e9 nodes");
  const int i0 = std::max(nodes[0], 0), i1 = std::min(nodes[1], nx), j0 = std::max(nodes[2], 0), j1 = std::min(nodes[3], ny);
  if (i0 > i1 || j0 > j1) throw std::invalid_argument("structured_triangles: an empty range of nodes");
  TriangleMesh m;
  m.nodes.reserve(std::size_t(i1 - i0 + 1) * std::size_t(j1 - j0 + 1));
  for (int j = j0; j <= j1; ++j)
    for (int i = i0; i <= i1; ++i)
      m.nodes.push_back({lo[0] + (hi[0] - lo[0]) * i / nx, lo[1] + (hi[1] - lo[1]) * j / ny, 0});
  const auto id = [&](int i, int j) { return std::int32_t((j - j0) * (i1 - i0 + 1) + (i - i0)); };
  for (int j = j0; j < j1; ++j)
    for (int i = i0; i < i1; ++i) {
      const auto a = id(i, j), b = id(i + 1, j), c = id(i + 1, j + 1), d = id(i, j + 1);
      if (lld) {
        m.triangles.push_back({a, b, c});
        m.triangles.push_back({a, c, d});
      } else {
        m.triangles.push_back({a, b, d});
        m.triangles.push_back({b, c, d});
      }
    }
  for (const char* side : {"left", "right", "bottom", "top"}) m.groups[side];
  for (int j = j0; j <= j1; ++j)
    for (int i = i0; i <= i1; ++i) {
      if (i == 0) m.groups["left"].push_back(id(i, j));
      if (i == nx) m.groups["right"].push_back(id(i, j));
      if (j == 0) m.groups["bottom"].push_back(id(i, j));
      if (j == ny) m.groups["top"].push_back(id(i, j));
    }
  return m;  // ids grow in loop order, so every group is sorted
}

void validate(const TriangleMesh& m, std::optional<double> mean_edge) {
  if (m.nodes.empty() || m.triangles.empty()) throw std::invalid_argument("mesh has no triangles");
  const auto n = std::int64_t(m.nodes.size());
  // Every node in range before any edge is measured.
  for (std::size_t t = 0; t < m.triangles.size(); ++t)
    for (auto v : m.triangles[t])
      if (v < 0 || v >= n) throw std::invalid_argument(fmt::format("triangle {} refers to node {}, but the mesh has {} nodes", t, v, n));
  // Degenerate relative to the mesh's own scale: a sliver far below round-off of a typical cell.
  const double h = mean_edge ? *mean_edge : m.mean_edge(), tiny = 1e-10 * h * h;
  for (std::size_t t = 0; t < m.triangles.size(); ++t) {
    const double a = m.area(t);
    const auto& tr = m.triangles[t];
    if (std::abs(a) <= tiny)
      throw std::invalid_argument(fmt::format("triangle {} (nodes {}, {}, {}) is degenerate: area {:.3g} m^2", t, tr[0], tr[1], tr[2], a));
    if (a < 0)
      throw std::invalid_argument(fmt::format("triangle {} (nodes {}, {}, {}) is inverted: its nodes run clockwise (signed area {:.3g} m^2)", t,
                                              tr[0], tr[1], tr[2], a));
  }
}

PointCloud mesh_points(const TriangleMesh& m) {
  validate(m);
  PointCloud pc = lumped_nodes(m.nodes, m.triangles, [&](std::size_t t) { return m.area(t); }, "triangle");
  pc.dim = 2;
  pc.spacing = m.mean_edge();
  pc.triangles = m.triangles;
  return pc;
}

MeshLocator::MeshLocator(const TriangleMesh& m) : mesh_(&m) {
  const Aabb b = m.bounds();
  cell_ = std::max(m.mean_edge(), 1e-300);
  lo_[0] = b.lo[0];
  lo_[1] = b.lo[1];
  nx_ = std::max(1, int(std::ceil((b.hi[0] - b.lo[0]) / cell_)) + 1);
  ny_ = std::max(1, int(std::ceil((b.hi[1] - b.lo[1]) / cell_)) + 1);
  // Counting sort of triangles into every cell their box overlaps.
  std::vector<std::array<int, 4>> span(m.triangles.size());
  start_.assign(std::size_t(nx_) * std::size_t(ny_) + 1, 0);
  for (std::size_t t = 0; t < m.triangles.size(); ++t) {
    double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
    for (auto v : m.triangles[t]) {
      const Vec3& p = m.nodes[std::size_t(v)];
      x0 = std::min(x0, p[0]), x1 = std::max(x1, p[0]), y0 = std::min(y0, p[1]), y1 = std::max(y1, p[1]);
    }
    const auto cx = [&](double x) { return std::clamp(int((x - lo_[0]) / cell_), 0, nx_ - 1); };
    const auto cy = [&](double y) { return std::clamp(int((y - lo_[1]) / cell_), 0, ny_ - 1); };
    span[t] = {cx(x0), cx(x1), cy(y0), cy(y1)};
    for (int j = span[t][2]; j <= span[t][3]; ++j)
      for (int i = span[t][0]; i <= span[t][1]; ++i) ++start_[std::size_t(j) * std::size_t(nx_) + std::size_t(i) + 1];
  }
  for (std::size_t c = 1; c < start_.size(); ++c) start_[c] += start_[c - 1];
  items_.resize(std::size_t(start_.back()));
  auto fill = start_;
  for (std::size_t t = 0; t < m.triangles.size(); ++t)
    for (int j = span[t][2]; j <= span[t][3]; ++j)
      for (int i = span[t][0]; i <= span[t][1]; ++i) items_[std::size_t(fill[std::size_t(j) * std::size_t(nx_) + std::size_t(i)]++)] = std::int32_t(t);
}

std::optional<MeshLocator::Hit> MeshLocator::locate(const Vec3& x) const {
  const int i = int(std::floor((x[0] - lo_[0]) / cell_)), j = int(std::floor((x[1] - lo_[1]) / cell_));
  if (i < 0 || j < 0 || i >= nx_ || j >= ny_) return std::nullopt;
  const std::size_t c = std::size_t(j) * std::size_t(nx_) + std::size_t(i);
  const auto& m = *mesh_;
  for (auto k = start_[c]; k < start_[c + 1]; ++k) {
    const auto t = items_[std::size_t(k)];
    const auto& tr = m.triangles[std::size_t(t)];
    const Vec3 &a = m.nodes[std::size_t(tr[0])], &b = m.nodes[std::size_t(tr[1])], &d = m.nodes[std::size_t(tr[2])];
    const double det = (b[0] - a[0]) * (d[1] - a[1]) - (d[0] - a[0]) * (b[1] - a[1]);
    const double l1 = ((x[0] - a[0]) * (d[1] - a[1]) - (d[0] - a[0]) * (x[1] - a[1])) / det;
    const double l2 = ((b[0] - a[0]) * (x[1] - a[1]) - (x[0] - a[0]) * (b[1] - a[1])) / det;
    const double l0 = 1 - l1 - l2, tol = -1e-12;
    if (l0 >= tol && l1 >= tol && l2 >= tol) return Hit{t, {l0, l1, l2}};
  }
  return std::nullopt;
}

double MeshLocator::interpolate(const std::vector<double>& f, const Vec3& x) const {
  const auto hit = locate(x);
  if (!hit) throw std::invalid_argument(fmt::format("interpolate: ({:g}, {:g}) is outside the mesh", x[0], x[1]));
  const auto& tr = mesh_->triangles[std::size_t(hit->triangle)];
  return hit->lambda[0] * f[std::size_t(tr[0])] + hit->lambda[1] * f[std::size_t(tr[1])] + hit->lambda[2] * f[std::size_t(tr[2])];
}

}  // namespace peridot
