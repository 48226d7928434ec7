module;
#include <malloc.h>
#include <omp.h>
export module peridot.quadrature:element_weights;
import peridot.std;
import peridot.discretization;

export namespace peridot {

// The kernel J(|y - x| / eps) integrated into V_ij: J = 1, or J = 1 - r (seed 003's choice).
enum class KernelShape { constant, linear };

struct ElementWeightOptions {
  double horizon = 0;                   // eps [m], > 0
  // Degree of the element rule. Triangles: 1, 2, 4 or 5 (1, 3, 6, 7 points);
  // tetrahedra: 1, 2 or 5 (1, 4, 15 points).
  int order = 2;
  KernelShape kernel = KernelShape::linear;
  // The box of the quadrature-point buckets; empty: the nodes' bounds. A rank that builds a part
  // of a mesh passes the whole mesh's box, so that each node sums its quadrature points in the
  // one-rank order and its weights are the one-rank weights bit for bit.
  std::optional<Aabb> grid;
  bool geometry = true;  // store xi and |xi|; false: a compact list (BondList::compact)
  bool lean = false;      // partner, float weight and mask only (BondList::lean; no xi, |xi|)
};

// Nodal finite-element bonds and weights (seed 003 eqs. 79-81), computed in one pass because
// the neighbour set and the weights come from the same quadrature points:
//   V_ij = sum_{e in E_j} sum_q chi(|x_q - x_i| <= eps) J(|x_q - x_i| / eps) phi_j(x_q) w_q,
// with w_q summing to the element's area (triangles) or volume (tetrahedra). PD_i is every
// node j != i of an element with a quadrature point inside the ball of i, so it includes nodes
// outside the ball. The ball cuts elements only through the indicator at quadrature points, as
// in the paper. V_ij sits on bond i -> j and V_ji on j -> i: they differ near boundaries and on
// unstructured meshes. Bonds are sorted by partner index; xi, length and intact are filled as
// for lattice bonds. The cloud's tetrahedra are used when it has any, else its triangles.
BondList element_bonds(const PointCloud& nodes, const ElementWeightOptions& options);

// Barycentric points and weights (summing to 1) of a symmetric rule on a simplex of N nodes.
template <std::size_t N>
struct SimplexRule {
  std::vector<std::array<double, N>> lambda;
  std::vector<double> weight;
};
using TriangleRule = SimplexRule<3>;
using TetrahedronRule = SimplexRule<4>;
TriangleRule triangle_rule(int order);
TetrahedronRule tetrahedron_rule(int order);

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

TetrahedronRule tetrahedron_rule(int order) {
  TetrahedronRule r;
  const auto orbit4 = [&](double a, double w) {  // (1 - 3a, a, a, a) and its permutations
    const double b = 1 - 3 * a;
    r.lambda.insert(r.lambda.end(), {{b, a, a, a}, {a, b, a, a}, {a, a, b, a}, {a, a, a, b}});
    r.weight.insert(r.weight.end(), 4, w);
  };
  const auto orbit6 = [&](double a, double w) {  // (a, a, 1/2 - a, 1/2 - a) and its permutations
    const double b = 0.5 - a;
    r.lambda.insert(r.lambda.end(), {{a, a, b, b}, {a, b, a, b}, {a, b, b, a}, {b, a, a, b}, {b, a, b, a}, {b, b, a, a}});
    r.weight.insert(r.weight.end(), 6, w);
  };
  switch (order) {
    case 1:
      r.lambda = {{0.25, 0.25, 0.25, 0.25}};
      r.weight = {1.0};
      break;
    case 2: orbit4((5 - std::sqrt(5.0)) / 20, 0.25); break;
    case 5:  // Keast's 15-point rule, all weights positive (his weights times 6)
      r.lambda = {{0.25, 0.25, 0.25, 0.25}};
      r.weight = {0.1817020685825351136};
      orbit4(1.0 / 3, 0.0361607142857142958);
      orbit4(1.0 / 11, 0.0698714945161738452);
      orbit6(0.0665501535736642813, 0.0656948493683187204);
      break;
    default: throw std::invalid_argument(fmt::format("tetrahedron quadrature order = {}: allowed 1, 2, 5", order));
  }
  return r;
}

namespace {

double measure(const PointCloud& pc, const std::array<std::int32_t, 3>& t) {
  return std::abs(signed_area(pc.position(std::size_t(t[0])), pc.position(std::size_t(t[1])), pc.position(std::size_t(t[2]))));
}

double measure(const PointCloud& pc, const std::array<std::int32_t, 4>& t) {
  return std::abs(signed_volume(pc.position(std::size_t(t[0])), pc.position(std::size_t(t[1])), pc.position(std::size_t(t[2])),
                                pc.position(std::size_t(t[3]))));
}

// A thread's bonds as they are found, in blocks of a fixed size: nothing is copied while they
// grow, where a doubling vector holds up to twice its size and leaves its old buffers in the
// heap (the set-up's peak).
template <class T>
struct Blocks {
  static constexpr std::size_t block = std::size_t(1) << 20;
  std::vector<std::vector<T>> data;
  void push_back(T v) {
    if (data.empty() || data.back().size() == block) data.emplace_back().reserve(block);
    data.back().push_back(v);
  }
  // Appends every value to `out`, freeing each block once copied.
  template <class Out>
  void move_to(Out& out) {
    for (auto& b : data) {
      out.insert(out.end(), b.begin(), b.end());
      std::vector<T>().swap(b);
    }
    data.clear();
  }
};

template <std::size_t N>
BondList simplex_bonds(const PointCloud& pc, const std::vector<std::array<std::int32_t, N>>& elements, const SimplexRule<N>& rule,
                       const ElementWeightOptions& o) {
  const std::size_t nq = rule.weight.size(), ne = elements.size(), n = pc.size();
  const double eps = o.horizon, eps2 = eps * eps;

  // Quadrature points bucketed in cubic cells of edge eps / 2 (one layer in 2D, where z = 0):
  // the ball of a node lies in the 5 x 5 x 5 block of cells around its own.
  const Aabb box = o.grid ? *o.grid : pc.bounds();
  const double cell = 0.5 * eps;
  long c[3];
  for (int k = 0; k < 3; ++k) c[k] = std::max(1L, long((box.hi[k] - box.lo[k]) / cell) + 1);
  if (double(c[0]) * double(c[1]) * double(c[2]) > 4e8)
    throw std::invalid_argument("element_bonds: horizon too small for the mesh extent (more than 4e8 cells)");
  const auto axis_cell = [&](double x, int k) { return std::clamp(long((x - box.lo[k]) / cell), 0L, c[k] - 1); };
  struct Q {
    double x[3], w;
    std::int32_t e;
    std::uint8_t q;
  };
  std::vector<Q> qp(ne * nq);
  std::vector<long> cell_start(std::size_t(c[0] * c[1] * c[2]) + 1, 0);
  {
    std::vector<Q> raw(ne * nq);
    std::vector<long> cell_id(ne * nq);
    for (std::size_t e = 0; e < ne; ++e) {
      const auto& t = elements[e];
      const double size = measure(pc, t);
      for (std::size_t q = 0; q < nq; ++q) {
        const auto& l = rule.lambda[q];
        Q& p = raw[e * nq + q];
        p = {{0, 0, 0}, rule.weight[q] * size, std::int32_t(e), std::uint8_t(q)};
        for (int k = 0; k < 3; ++k)
          for (std::size_t a = 0; a < N; ++a) p.x[k] += l[a] * pc.x[std::size_t(k)][std::size_t(t[a])];
        cell_id[e * nq + q] = (axis_cell(p.x[2], 2) * c[1] + axis_cell(p.x[1], 1)) * c[0] + axis_cell(p.x[0], 0);
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
  std::vector<Blocks<std::int32_t>> nb_part(static_cast<std::size_t>(threads));
  // A lean list's weights are rounded to float as they are found.
  std::vector<Blocks<double>> w_part(static_cast<std::size_t>(threads));
  std::vector<Blocks<float>> wf_part(static_cast<std::size_t>(threads));
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
    auto& wf = wf_part[std::size_t(tid)];
    for (std::size_t i = lo; i < hi; ++i) {
      const double xi[3] = {pc.x[0][i], pc.x[1][i], pc.x[2][i]};
      long ci[3];
      for (int k = 0; k < 3; ++k) ci[k] = axis_cell(std::clamp(xi[k], box.lo[k], box.hi[k]), k);
      touched.clear();
      for (long z = std::max(0L, ci[2] - 2); z <= std::min(c[2] - 1, ci[2] + 2); ++z)
        for (long y = std::max(0L, ci[1] - 2); y <= std::min(c[1] - 1, ci[1] + 2); ++y) {
          const long row = (z * c[1] + y) * c[0];
          for (long k = cell_start[std::size_t(row + std::max(0L, ci[0] - 2))]; k < cell_start[std::size_t(row + std::min(c[0] - 1, ci[0] + 2)) + 1]; ++k) {
            const Q& p = qp[std::size_t(k)];
            const double dx = p.x[0] - xi[0], dy = p.x[1] - xi[1], dz = p.x[2] - xi[2], r2 = dx * dx + dy * dy + dz * dz;
            if (r2 > eps2) continue;
            const double J = o.kernel == KernelShape::constant ? 1.0 : 1.0 - std::sqrt(r2) / eps;
            const auto& t = elements[std::size_t(p.e)];
            const auto& l = rule.lambda[p.q];
            for (std::size_t a = 0; a < N; ++a) {
              const auto j_node = t[a];
              if (std::size_t(j_node) == i) continue;
              if (!seen[std::size_t(j_node)]) seen[std::size_t(j_node)] = 1, touched.push_back(j_node);
              acc[std::size_t(j_node)] += J * l[a] * p.w;
            }
          }
        }
      std::sort(touched.begin(), touched.end());
      for (auto j_node : touched) {
        nb.push_back(j_node);
        if (o.lean) wf.push_back(float(acc[std::size_t(j_node)]));
        else wt.push_back(acc[std::size_t(j_node)]);
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
  if (o.lean) bl.weight_f.reserve(m);
  else bl.weight.reserve(m);
  for (std::size_t t = 0; t < nb_part.size(); ++t) {
    nb_part[t].move_to(bl.neighbor);
    if (o.lean) wf_part[t].move_to(bl.weight_f);
    else w_part[t].move_to(bl.weight);
  }
  // The blocks' pages go back to the system: the heap keeps freed blocks resident, and the
  // bond geometry allocated next (32 B per bond) cannot reuse them, being larger than each.
  malloc_trim(0);
  bl.intact.assign(m, 1);
  const auto length_of = [&](std::size_t i, std::int64_t b, double* d) {
    const auto j = std::size_t(bl.neighbor[std::size_t(b)]);
    for (int k = 0; k < 3; ++k) d[k] = pc.x[k][j] - pc.x[k][i];
    return bond_length(d[0], d[1], d[2]);
  };
  const bool geometry = o.geometry && !o.lean;
  if (geometry) {
    for (auto& cx : bl.xi) cx.resize(m);
    bl.length.resize(m);
    const auto nn = static_cast<std::int64_t>(n);
#pragma omp parallel for schedule(static)
    for (std::int64_t i = 0; i < nn; ++i)
      for (std::int64_t b = bl.offset[std::size_t(i)]; b < bl.offset[std::size_t(i) + 1]; ++b) {
        double d[3];
        bl.length[std::size_t(b)] = length_of(std::size_t(i), b, d);
        for (int k = 0; k < 3; ++k) bl.xi[k][std::size_t(b)] = d[k];
      }
  }
  for (std::size_t i = 0; i < n; ++i)
    for (auto b = bl.offset[i]; b < bl.offset[i + 1]; ++b) {
      double d[3];
      if (!((geometry ? bl.length[std::size_t(b)] : length_of(i, b, d)) > 0))
        throw std::invalid_argument(fmt::format("element_bonds: mesh nodes {} and {} coincide", i, bl.neighbor[std::size_t(b)]));
    }
  return bl;
}

}  // namespace

BondList element_bonds(const PointCloud& pc, const ElementWeightOptions& o) {
  if (pc.triangles.empty() && pc.tetrahedra.empty()) throw std::invalid_argument("element_bonds: the point cloud has no mesh triangles or tetrahedra");
  if (!(o.horizon > 0) || !std::isfinite(o.horizon)) throw std::invalid_argument("element_bonds: horizon must be a finite number > 0");
  return pc.tetrahedra.empty() ? simplex_bonds(pc, pc.triangles, triangle_rule(o.order), o)
                               : simplex_bonds(pc, pc.tetrahedra, tetrahedron_rule(o.order), o);
}

}  // namespace peridot
