module;
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <vector>
#include <omp.h>
#include <fmt/core.h>
export module peridot.quadrature:element_weights;
import peridot.discretization;

export namespace peridot {

// The kernel J(|y - x| / eps) integrated into V_ij: J = 1, or J = 1 - r (seed 003's choice).
enum class KernelShape { constant, linear };

struct ElementWeightOptions {
  double horizon = 0;                   // eps [m], > 0
  int order = 2;                        // degree of the triangle rule: 1, 2, 4 or 5 (1, 3, 6, 7 points)
  KernelShape kernel = KernelShape::linear;
};

// Nodal finite-element bonds and weights (seed 003 eqs. 79-81), computed in one pass because
// the neighbour set and the weights come from the same quadrature points:
//   V_ij = sum_{e in E_j} sum_q chi(|x_q - x_i| <= eps) J(|x_q - x_i| / eps) phi_j(x_q) w_q,
// with w_q summing to the element area. PD_i is every node j != i of an element with a
// quadrature point inside the ball of i, so it includes nodes outside the ball. The ball
// cuts elements only through the indicator at quadrature points, as in the paper. V_ij sits
// on bond i -> j and V_ji on j -> i: they differ near boundaries and on unstructured meshes.
// Bonds are sorted by partner index; xi, length and intact are filled as for lattice bonds.
BondList element_bonds(const PointCloud& nodes, const ElementWeightOptions& options);

// Barycentric points and weights (summing to 1) of the symmetric triangle rule of a degree.
struct TriangleRule {
  std::vector<std::array<double, 3>> lambda;
  std::vector<double> weight;
};
TriangleRule triangle_rule(int order);

}  // namespace peridot

namespace peridot {

TriangleRule triangle_rule(int order) {
  TriangleRule r;
  const auto orbit3 = [&](double a, double w) {  // (a, a, 1 - 2a) and its permutations
    const double b = 1 - 2 * a;
    r.lambda.insert(r.lambda.end(), {{b, a, a}, {a, b, a}, {a, a, b}});
    r.weight.insert(r.weight.end(), {w, w, w});
  };
  switch (order) {
    case 1:
      r.lambda = {{1.0 / 3, 1.0 / 3, 1.0 / 3}};
      r.weight = {1.0};
      break;
    case 2: orbit3(1.0 / 6, 1.0 / 3); break;  // degree 2, the paper's "second-order rule"
    case 4:  // Dunavant's 6-point rule
      orbit3(0.445948490915965, 0.223381589678011);
      orbit3(0.091576213509771, 0.109951743655322);
      break;
    case 5:  // Dunavant's 7-point rule
      r.lambda = {{1.0 / 3, 1.0 / 3, 1.0 / 3}};
      r.weight = {0.225};
      orbit3(0.470142064105115, 0.132394152788506);
      orbit3(0.101286507323456, 0.125939180544827);
      break;
    default: throw std::invalid_argument(fmt::format("triangle quadrature order = {}: allowed 1, 2, 4, 5", order));
  }
  return r;
}

BondList element_bonds(const PointCloud& pc, const ElementWeightOptions& o) {
  if (pc.triangles.empty()) throw std::invalid_argument("element_bonds: the point cloud has no mesh triangles");
  if (!(o.horizon > 0) || !std::isfinite(o.horizon)) throw std::invalid_argument("element_bonds: horizon must be a finite number > 0");
  const TriangleRule rule = triangle_rule(o.order);
  const std::size_t nq = rule.weight.size(), ne = pc.triangles.size(), n = pc.size();
  const double eps = o.horizon, eps2 = eps * eps;

  // Quadrature points bucketed in square cells of edge eps / 2: the ball of a node lies in the
  // 5 x 5 block of cells around its own.
  const Aabb box = pc.bounds();
  const double cell = 0.5 * eps;
  const long cx = std::max(1L, long((box.hi[0] - box.lo[0]) / cell) + 1), cy = std::max(1L, long((box.hi[1] - box.lo[1]) / cell) + 1);
  if (double(cx) * double(cy) > 4e8) throw std::invalid_argument("element_bonds: horizon too small for the mesh extent (more than 4e8 cells)");
  const auto cell_of = [&](double x, double y) {
    return std::clamp(long((y - box.lo[1]) / cell), 0L, cy - 1) * cx + std::clamp(long((x - box.lo[0]) / cell), 0L, cx - 1);
  };
  struct Q {
    double x, y, w;
    std::int32_t e;
    std::uint8_t q;
  };
  std::vector<Q> qp(ne * nq);
  std::vector<long> cell_start(std::size_t(cx * cy) + 1, 0);
  {
    std::vector<Q> raw(ne * nq);
    std::vector<long> cell_id(ne * nq);
    for (std::size_t e = 0; e < ne; ++e) {
      const auto& t = pc.triangles[e];
      const Vec3 a = pc.position(std::size_t(t[0])), b = pc.position(std::size_t(t[1])), c = pc.position(std::size_t(t[2]));
      const double area = 0.5 * std::abs((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]));
      for (std::size_t q = 0; q < nq; ++q) {
        const auto& l = rule.lambda[q];
        Q& p = raw[e * nq + q];
        p = {l[0] * a[0] + l[1] * b[0] + l[2] * c[0], l[0] * a[1] + l[1] * b[1] + l[2] * c[1], rule.weight[q] * area, std::int32_t(e),
             std::uint8_t(q)};
        cell_id[e * nq + q] = cell_of(p.x, p.y);
        ++cell_start[std::size_t(cell_id[e * nq + q]) + 1];
      }
    }
    for (std::size_t k = 1; k < cell_start.size(); ++k) cell_start[k] += cell_start[k - 1];
    auto fill = cell_start;
    for (std::size_t k = 0; k < raw.size(); ++k) qp[std::size_t(fill[std::size_t(cell_id[k])]++)] = raw[k];
  }

  // Each thread handles a contiguous block of nodes with a dense accumulator over partners,
  // so every node's sums run in the fixed quadrature-point order: the weights do not depend
  // on the thread count.
  const int threads = omp_get_max_threads();
  std::vector<std::vector<std::int32_t>> nb_part(static_cast<std::size_t>(threads));
  std::vector<std::vector<double>> w_part(static_cast<std::size_t>(threads));
  std::vector<std::int64_t> count(n, 0);
#pragma omp parallel num_threads(threads)
  {
    const int tid = omp_get_thread_num(), nt = omp_get_num_threads();
    const std::size_t lo = n * std::size_t(tid) / std::size_t(nt), hi = n * std::size_t(tid + 1) / std::size_t(nt);
    std::vector<double> acc(n, 0.0);
    std::vector<std::uint8_t> seen(n, 0);
    std::vector<std::int32_t> touched;
    auto& nb = nb_part[std::size_t(tid)];
    auto& wt = w_part[std::size_t(tid)];
    for (std::size_t i = lo; i < hi; ++i) {
      const double xi = pc.x[0][i], yi = pc.x[1][i];
      const long ci = long((std::clamp(xi, box.lo[0], box.hi[0]) - box.lo[0]) / cell), cj = long((std::clamp(yi, box.lo[1], box.hi[1]) - box.lo[1]) / cell);
      touched.clear();
      for (long j = std::max(0L, cj - 2); j <= std::min(cy - 1, cj + 2); ++j)
        for (long k = cell_start[std::size_t(j * cx + std::max(0L, ci - 2))]; k < cell_start[std::size_t(j * cx + std::min(cx - 1, ci + 2)) + 1]; ++k) {
          const Q& p = qp[std::size_t(k)];
          const double dx = p.x - xi, dy = p.y - yi, r2 = dx * dx + dy * dy;
          if (r2 > eps2) continue;
          const double J = o.kernel == KernelShape::constant ? 1.0 : 1.0 - std::sqrt(r2) / eps;
          const auto& t = pc.triangles[std::size_t(p.e)];
          const auto& l = rule.lambda[p.q];
          for (int a = 0; a < 3; ++a) {
            const auto j_node = t[std::size_t(a)];
            if (std::size_t(j_node) == i) continue;
            if (!seen[std::size_t(j_node)]) seen[std::size_t(j_node)] = 1, touched.push_back(j_node);
            acc[std::size_t(j_node)] += J * l[std::size_t(a)] * p.w;
          }
        }
      std::sort(touched.begin(), touched.end());
      for (auto j_node : touched) {
        nb.push_back(j_node);
        wt.push_back(acc[std::size_t(j_node)]);
        acc[std::size_t(j_node)] = 0;
        seen[std::size_t(j_node)] = 0;
      }
      count[i] = std::int64_t(touched.size());
    }
  }

  BondList bl;
  bl.horizon = eps;
  bl.offset.assign(n + 1, 0);
  for (std::size_t i = 0; i < n; ++i) bl.offset[i + 1] = bl.offset[i] + count[i];
  const auto m = std::size_t(bl.offset[n]);
  bl.neighbor.reserve(m);
  bl.weight.reserve(m);
  for (std::size_t t = 0; t < nb_part.size(); ++t) {
    bl.neighbor.insert(bl.neighbor.end(), nb_part[t].begin(), nb_part[t].end());
    bl.weight.insert(bl.weight.end(), w_part[t].begin(), w_part[t].end());
    std::vector<std::int32_t>().swap(nb_part[t]);
    std::vector<double>().swap(w_part[t]);
  }
  for (auto& c : bl.xi) c.resize(m);
  bl.length.resize(m);
  bl.intact.assign(m, 1);
  const auto nn = static_cast<std::int64_t>(n);
#pragma omp parallel for schedule(static)
  for (std::int64_t i = 0; i < nn; ++i)
    for (std::int64_t b = bl.offset[std::size_t(i)]; b < bl.offset[std::size_t(i) + 1]; ++b) {
      const auto j = std::size_t(bl.neighbor[std::size_t(b)]);
      double r2 = 0;
      for (int k = 0; k < 3; ++k) {
        const double d = pc.x[k][j] - pc.x[k][std::size_t(i)];
        bl.xi[k][std::size_t(b)] = d;
        r2 += d * d;
      }
      bl.length[std::size_t(b)] = std::sqrt(r2);
    }
  for (std::size_t i = 0; i < n; ++i)
    for (auto b = bl.offset[i]; b < bl.offset[i + 1]; ++b)
      if (!(bl.length[std::size_t(b)] > 0))
        throw std::invalid_argument(fmt::format("element_bonds: mesh nodes {} and {} coincide", i, bl.neighbor[std::size_t(b)]));
  return bl;
}

}  // namespace peridot
