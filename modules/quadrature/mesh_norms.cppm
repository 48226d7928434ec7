export module peridot.quadrature:mesh_norms;
import peridot.std;
import peridot.discretization;
import :element_weights;

export namespace peridot {

// A 2D vector field at the nodes of a mesh, interpolated linearly on each triangle.
struct P1Field {
  const TriangleMesh* mesh = nullptr;
  std::array<const std::vector<double>*, 2> u{};  // nodal components
};

// ||a - b||_L2 over a's mesh for P1 fields on two meshes that need not be nested (seed 003
// Sec. 4.1 compares h = eps/12 with eps/16): the integrand is sampled at the quadrature
// points of a's triangles (degree 5, 7 points), where b is evaluated by locating the point
// in b's mesh. Exact when b's mesh refines a's; otherwise the error of the rule is of the
// order of the P1 interpolation error of b across its element edges.
double l2_difference(const P1Field& a, const P1Field& b, const MeshLocator& b_locator);

// ||a||_L2 over its own mesh (same rule).
double l2_norm(const P1Field& a);

// The lumped-mass (nodal) norm (sum_i V_i |a_i - b(x_i)|^2)^(1/2) over a's nodes, V_i a third of
// the area around node i, with b interpolated at x_i. Equivalent to the L2 norm of P1 fields
// (seed 003 eq. 14). Unlike l2_difference, it does not see a jump of b that lies on a grid
// line of both meshes: volume-constrained layers make the peridynamic solution jump at the
// layer's edge, and the P1 interpolant smears that jump over one element, an O(h^1/2) error.
double nodal_l2_difference(const P1Field& a, const P1Field& b, const MeshLocator& b_locator);

}  // namespace peridot

namespace peridot {

namespace {

template <class Other>
double integrate_squared(const P1Field& a, Other&& other) {
  const auto rule = triangle_rule(5);
  const auto& m = *a.mesh;
  double sum = 0;
  for (std::size_t t = 0; t < m.triangles.size(); ++t) {
    const auto& tr = m.triangles[t];
    const double area = m.area(t);
    for (std::size_t q = 0; q < rule.weight.size(); ++q) {
      Vec3 x{0, 0, 0};
      std::array<double, 2> v{0, 0};
      for (std::size_t k = 0; k < 3; ++k) {
        const auto n = std::size_t(tr[k]);
        for (int c = 0; c < 2; ++c) x[c] += rule.lambda[q][k] * m.nodes[n][c], v[std::size_t(c)] += rule.lambda[q][k] * (*a.u[std::size_t(c)])[n];
      }
      const auto w = other(x);
      const double dx = v[0] - w[0], dy = v[1] - w[1];
      sum += rule.weight[q] * area * (dx * dx + dy * dy);
    }
  }
  return std::sqrt(sum);
}

}  // namespace

double l2_difference(const P1Field& a, const P1Field& b, const MeshLocator& loc) {
  return integrate_squared(a, [&](const Vec3& x) {
    return std::array<double, 2>{loc.interpolate(*b.u[0], x), loc.interpolate(*b.u[1], x)};
  });
}

double nodal_l2_difference(const P1Field& a, const P1Field& b, const MeshLocator& loc) {
  const auto& m = *a.mesh;
  std::vector<double> volume(m.nodes.size(), 0.0);
  for (std::size_t t = 0; t < m.triangles.size(); ++t)
    for (auto v : m.triangles[t]) volume[std::size_t(v)] += m.area(t) / 3;
  double sum = 0;
  for (std::size_t i = 0; i < m.nodes.size(); ++i) {
    const double dx = (*a.u[0])[i] - loc.interpolate(*b.u[0], m.nodes[i]);
    const double dy = (*a.u[1])[i] - loc.interpolate(*b.u[1], m.nodes[i]);
    sum += volume[i] * (dx * dx + dy * dy);
  }
  return std::sqrt(sum);
}

double l2_norm(const P1Field& a) {
  return integrate_squared(a, [](const Vec3&) { return std::array<double, 2>{0, 0}; });
}

}  // namespace peridot
