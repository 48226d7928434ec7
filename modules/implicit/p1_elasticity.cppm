module;
#include <Eigen/CholmodSupport>
#include <Eigen/SparseCore>
export module peridot.implicit:p1_elasticity;
import peridot.std;
import peridot.models;

export namespace peridot {

// Classical 2D linear elasticity with linear (P1) triangles: the reference the peridynamic
// solutions converge to. Body force by one-point (centroid) quadrature; Dirichlet nodes fixed
// at zero; solved with a sparse Cholesky factorisation.
struct P1Problem {
  ElasticConstants material;                                  // in-plane lambda, mu [Pa]
  std::function<std::array<double, 2>(const Vec3&)> body_force;   // [N/m^3]
  std::function<bool(const Vec3&)> clamped;                   // node held at u = 0
};

std::vector<std::array<double, 2>> solve_p1_elasticity(const TriangleMesh& mesh, const P1Problem& problem);

// u at a point inside the mesh by linear interpolation (throws if outside every triangle).
std::array<double, 2> interpolate(const TriangleMesh& mesh, const std::vector<std::array<double, 2>>& u, const Vec3& x);

}  // namespace peridot

namespace peridot {

namespace {

// Shape-function gradients and area of a triangle.
struct P1Element {
  double area;
  double bx[3], by[3];
};

P1Element element(const TriangleMesh& m, const std::array<std::int32_t, 3>& t) {
  const Vec3 &p0 = m.nodes[t[0]], &p1 = m.nodes[t[1]], &p2 = m.nodes[t[2]];
  const double det = (p1[0] - p0[0]) * (p2[1] - p0[1]) - (p2[0] - p0[0]) * (p1[1] - p0[1]);
  if (!(det > 0)) throw std::invalid_argument("P1 elasticity: a triangle is degenerate or clockwise");
  P1Element e{0.5 * det, {p1[1] - p2[1], p2[1] - p0[1], p0[1] - p1[1]}, {p2[0] - p1[0], p0[0] - p2[0], p1[0] - p0[0]}};
  for (int k = 0; k < 3; ++k) e.bx[k] /= det, e.by[k] /= det;
  return e;
}

}  // namespace

std::vector<std::array<double, 2>> solve_p1_elasticity(const TriangleMesh& m, const P1Problem& p) {
  const std::size_t n = m.nodes.size();
  std::vector<long> dof(2 * n, -1);
  long N = 0;
  for (std::size_t i = 0; i < n; ++i)
    if (!p.clamped || !p.clamped(m.nodes[i])) dof[2 * i] = N++, dof[2 * i + 1] = N++;
  if (N == 0) throw std::invalid_argument("P1 elasticity: every node is clamped");
  const double lam = p.material.lambda, mu = p.material.mu;
  std::vector<Eigen::Triplet<double, long>> trip;
  Eigen::VectorXd F = Eigen::VectorXd::Zero(N);
  for (const auto& t : m.triangles) {
    const auto e = element(m, t);
    // B (3 x 6) for (eps_xx, eps_yy, 2 eps_xy); D for isotropic in-plane elasticity.
    double B[3][6] = {};
    for (int a = 0; a < 3; ++a) {
      B[0][2 * a] = e.bx[a];
      B[1][2 * a + 1] = e.by[a];
      B[2][2 * a] = e.by[a];
      B[2][2 * a + 1] = e.bx[a];
    }
    const double D[3][3] = {{lam + 2 * mu, lam, 0}, {lam, lam + 2 * mu, 0}, {0, 0, mu}};
    for (int r = 0; r < 6; ++r) {
      const long gr = dof[2 * std::size_t(t[r / 2]) + std::size_t(r % 2)];
      if (gr < 0) continue;
      for (int c = 0; c < 6; ++c) {
        const long gc = dof[2 * std::size_t(t[c / 2]) + std::size_t(c % 2)];
        if (gc < 0) continue;
        double k = 0;
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b) k += B[a][r] * D[a][b] * B[b][c];
        trip.emplace_back(gr, gc, k * e.area);
      }
    }
    if (p.body_force) {
      const Vec3 centroid = (1.0 / 3.0) * (m.nodes[t[0]] + m.nodes[t[1]] + m.nodes[t[2]]);
      const auto f = p.body_force(centroid);
      for (int a = 0; a < 3; ++a)
        for (int k = 0; k < 2; ++k)
          if (const long g = dof[2 * std::size_t(t[a]) + std::size_t(k)]; g >= 0) F[g] += f[std::size_t(k)] * e.area / 3;
    }
  }
  Eigen::SparseMatrix<double, Eigen::ColMajor, long> K(N, N);
  K.setFromTriplets(trip.begin(), trip.end());
  Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double, Eigen::ColMajor, long>> llt(K);
  if (llt.info() != Eigen::Success) throw std::runtime_error("P1 elasticity: the stiffness matrix is not positive definite (is anything clamped?)");
  const Eigen::VectorXd u = llt.solve(F);
  std::vector<std::array<double, 2>> out(n, {0, 0});
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t k = 0; k < 2; ++k)
      if (dof[2 * i + k] >= 0) out[i][k] = u[dof[2 * i + k]];
  return out;
}

std::array<double, 2> interpolate(const TriangleMesh& m, const std::vector<std::array<double, 2>>& u, const Vec3& x) {
  for (const auto& t : m.triangles) {
    const auto e = element(m, t);
    const Vec3& p0 = m.nodes[t[0]];
    // Barycentric coordinates from the shape-function gradients.
    double l[3];
    for (int a = 0; a < 3; ++a) l[a] = (a == 0 ? 1.0 : 0.0) + e.bx[a] * (x[0] - p0[0]) + e.by[a] * (x[1] - p0[1]);
    if (l[0] >= -1e-12 && l[1] >= -1e-12 && l[2] >= -1e-12) {
      std::array<double, 2> v{0, 0};
      for (int a = 0; a < 3; ++a)
        for (int k = 0; k < 2; ++k) v[std::size_t(k)] += l[a] * u[std::size_t(t[a])][std::size_t(k)];
      return v;
    }
  }
  throw std::invalid_argument(fmt::format("interpolate: ({:g}, {:g}) is outside the mesh", x[0], x[1]));
}

}  // namespace peridot
