module;
#include <Eigen/Dense>
#include <Eigen/SparseCore>
#include <Eigen/SparseLU>
#include <Eigen/UmfPackSupport>
export module peridot.implicit:osb_static;
import peridot.std;
import peridot.models;
import :static_lps;
import peridot.parallel;
import :replicated_solve;

export namespace peridot {

// Seed 004: static linearised OSB on a rectangle of lattice cells, with boundary conditions at
// boundary nodes on the cell sides (Sec. 3.2, 4.5). With the correction, fictitious nodes
// (Role::fictitious) fill a layer of thickness delta around the body; their displacements
// are Taylor extrapolations of order taylor_order from the nearest real node (Sec. 3.2),
// their dilatations one order lower, and the conditions enter as Lagrange rows B u = c:
// a displacement component is one row, a traction component one row of the force flux (60).
// Without it (outermost_nodes), displacements are imposed on the outermost real nodes and
// tractions enter as a body force p / h on them (spec 004 Sec. 6).

// A side of the rectangle and, per component, what is imposed on it.
enum class Edge { left, right, bottom, top };
struct ComponentCondition {
  bool displacement = false;  // true: u_c = value [m]; false: traction t_c = value [Pa]
  double value = 0;
};
struct EdgeConditions {
  std::array<std::array<ComponentCondition, 2>, 4> edge{};  // [Edge][component]; default: free
};

struct OsbStaticProblem {
  EdgeConditions conditions;
  std::function<std::array<double, 2>(const Vec3&)> body_force;  // [N/m^3]; empty: none
  bool corrected = true;      // fictitious Taylor layer; false: outermost_nodes
  int taylor_order = 1;       // n_max = 1, 2, 3
};

struct OsbStaticOptions {
  // UMFPACK. Eigen's SparseLU returned wrong solutions of this saddle-point system with tiny
  // residuals in some runs (see the closing note of issue 11); it stays selectable for comparison.
  LinearSolver solver = LinearSolver::umfpack;
  // solver = petsc (N MPI ranks): LU by MUMPS whatever the size, since BoomerAMG does not take a
  // saddle point, refined three times; a deck's or the command line's options override it.
  parallel::KspOptions petsc{.direct_below = std::numeric_limits<std::int64_t>::max(), .refinement = 3};
  // Sequentially linear fracture (Sec. 6): > 0 removes the `bonds_per_solve` most stretched
  // bonds with e / |xi| >= critical_stretch and solves again, until none is left or
  // `max_solves` is reached.
  double critical_stretch = 0;
  int bonds_per_solve = 4;
  std::size_t max_solves = 100000;
  std::function<void(std::size_t solve, std::size_t broken)> progress;
  // UMFPACK: re-solves reuse the first solve's fill-reducing ordering and frontal structure (the
  // matrix keeps its pattern; only values change). false analyses every matrix afresh.
  bool reuse_ordering = true;
};

struct OsbStaticResult {
  VectorField u;                     // every point: real solved, fictitious extrapolated [m]
  std::vector<double> theta;         // every point
  std::vector<double> pair_force;    // g_b per directed bond (Osb::pair_forces semantics)
  std::vector<double> multipliers;   // one per constraint row, in force-density units [N/m^3]
  // Boundary nodes (cell-side centroids) in order left (bottom to top), right, bottom (left to
  // right), top: position, outward normal, traction tau(x_b, n_b) (60) after the solve.
  std::vector<Vec3> boundary_position;
  std::vector<std::array<double, 2>> boundary_normal, boundary_traction;
  std::size_t real_points = 0, constraints = 0, nonzeros = 0;
  std::size_t solves = 0, broken = 0;  // linear solves, bonds removed (undirected)
  std::size_t orderings = 0;           // UMFPACK's symbolic analyses (1 when re-solves reuse it)
  bool stopped_singular = false;       // fracture ended because equilibrium became impossible
  double residual = 0;                 // |A x - b| / |b| of the last solve
  double assembly_seconds = 0, factor_seconds = 0;
};

// The body holds real points (Role::interior) filling an nx-by-ny box of a lattice and, when
// corrected, fictitious points around it; bonds carry the model's weights. The model's m must
// be set: real points from their bonds, fictitious ones the bulk value (Sec. 3.1).
OsbStaticResult solve_osb_static(Body& body, const Osb& model, const OsbStaticProblem& problem, const OsbStaticOptions& options = {});

// The same solve a re-solve at a time, for a run loop that observes each one: advance() removes
// the bonds the previous solve chose (none before the first) and solves once, so that after it
// the body holds the bonds the solution was solved on. done() once no bond is over s_c,
// max_solves is reached or equilibrium became impossible.
// Holds references to the body and model, which must outlive it.
class OsbStaticSolver {
 public:
  OsbStaticSolver(Body& body, const Osb& model, const OsbStaticProblem& problem, const OsbStaticOptions& options = {});
  OsbStaticSolver(OsbStaticSolver&&) noexcept;
  OsbStaticSolver& operator=(OsbStaticSolver&&) noexcept;
  ~OsbStaticSolver();
  bool done() const;
  void advance();
  // u, theta, pair forces and tractions of the last solve; counts of solves and removed bonds.
  const OsbStaticResult& result() const;

 private:
  struct Impl;  // the grid box and boundary sides live in the implementation
  std::unique_ptr<Impl> impl_;
};

// Weights w_k with f(target) = sum_k w_k f(stencil_k) for every polynomial of total degree
// <= order, on a stencil of grid offsets (1D collinear or the 2D triangular one): the Taylor
// extrapolation of Sec. 3.2 (eqs. 37-42) in closed form.
std::vector<double> taylor_weights(int order, const std::vector<std::array<int, 2>>& stencil, std::array<double, 2> target);

}  // namespace peridot

namespace peridot {

namespace {

using SpMat = Eigen::SparseMatrix<double, Eigen::ColMajor, long>;
using Trip = Eigen::Triplet<double, long>;

double since(std::chrono::steady_clock::time_point t) { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count(); }

// Real grid box and index maps.
struct Box {
  LatticeGrid grid;
  int ox = 0, oy = 0, nx = 0, ny = 0;            // real box [ox, ox + nx) x [oy, oy + ny)
  std::vector<std::int64_t> dof;                 // point -> real index, or -1
  std::vector<std::size_t> real;                 // real index -> point
  std::int64_t real_at(int ix, int iy) const {
    const auto p = grid.at(ix, iy);
    return p < 0 ? -1 : dof[std::size_t(p)];
  }
};

Box make_box(const Body& body) {
  Box b;
  b.grid = lattice_grid(body.points);
  const auto& pc = body.points;
  int lo[2] = {1 << 30, 1 << 30}, hi[2] = {-(1 << 30), -(1 << 30)};
  b.dof.assign(pc.size(), -1);
  for (std::size_t i = 0; i < pc.size(); ++i) {
    if (pc.role[i] != Role::interior) continue;
    b.dof[i] = std::int64_t(b.real.size());
    b.real.push_back(i);
    lo[0] = std::min(lo[0], b.grid.gx[i]), hi[0] = std::max(hi[0], b.grid.gx[i]);
    lo[1] = std::min(lo[1], b.grid.gy[i]), hi[1] = std::max(hi[1], b.grid.gy[i]);
  }
  if (b.real.empty()) throw std::invalid_argument("osb static: the body has no real points");
  b.ox = lo[0], b.oy = lo[1], b.nx = hi[0] - lo[0] + 1, b.ny = hi[1] - lo[1] + 1;
  if (std::size_t(b.nx) * std::size_t(b.ny) != b.real.size())
    throw std::invalid_argument("osb static: the real points must fill a rectangle of lattice cells");
  return b;
}

// Sparse linear form over the real points: point p of the grid (possibly outside the box) as
// Taylor extrapolation from the nearest real node (Sec. 3.2), order n.
void extrapolation_row(const Box& b, double gx, double gy, int order, std::vector<std::pair<std::int64_t, double>>& row) {
  row.clear();
  const int jx = std::clamp(int(std::lround(gx)), b.ox, b.ox + b.nx - 1), jy = std::clamp(int(std::lround(gy)), b.oy, b.oy + b.ny - 1);
  const double lx = gx - jx, ly = gy - jy;
  if (lx == 0 && ly == 0) {
    row.emplace_back(b.real_at(jx, jy), 1.0);
    return;
  }
  const int sx = lx > 0 ? 1 : -1, sy = ly > 0 ? 1 : -1;
  std::vector<std::array<int, 2>> stencil;
  if (lx != 0 && ly != 0) {
    for (int s = 0; s <= order; ++s)
      for (int q = 0; q <= s; ++q) stencil.push_back({-sx * (s - q), -sy * q});
  } else {
    for (int k = 0; k <= order; ++k) stencil.push_back(lx != 0 ? std::array<int, 2>{-sx * k, 0} : std::array<int, 2>{0, -sy * k});
  }
  const auto w = taylor_weights(order, stencil, {lx, ly});
  for (std::size_t k = 0; k < stencil.size(); ++k) {
    const auto r = b.real_at(jx + stencil[k][0], jy + stencil[k][1]);
    if (r < 0) throw std::invalid_argument(fmt::format("osb static: Taylor order {} needs at least {} real nodes across the body", order, order + 1));
    if (w[k] != 0) row.emplace_back(r, w[k]);
  }
}

// Every point (real or fictitious) as a linear form over the real values, as a sparse matrix.
SpMat extrapolation_matrix(const Body& body, const Box& b, int order) {
  std::vector<Trip> t;
  std::vector<std::pair<std::int64_t, double>> row;
  for (std::size_t p = 0; p < body.size(); ++p) {
    extrapolation_row(b, b.grid.gx[p], b.grid.gy[p], order, row);
    for (auto [r, w] : row) t.emplace_back(long(p), long(r), w);
  }
  SpMat P(long(body.size()), long(b.real.size()));
  P.setFromTriplets(t.begin(), t.end());
  return P;
}

struct Side {
  Edge edge;
  GridSegment segment;
  int normal_sign;
  double gx, gy;  // centroid in grid units
};

std::vector<Side> boundary_sides(const Box& b) {
  std::vector<Side> s;
  for (int iy = b.oy; iy < b.oy + b.ny; ++iy) s.push_back({Edge::left, {0, 2 * b.ox - 1, iy}, -1, b.ox - 0.5, double(iy)});
  for (int iy = b.oy; iy < b.oy + b.ny; ++iy) s.push_back({Edge::right, {0, 2 * (b.ox + b.nx) - 1, iy}, 1, b.ox + b.nx - 0.5, double(iy)});
  for (int ix = b.ox; ix < b.ox + b.nx; ++ix) s.push_back({Edge::bottom, {1, 2 * b.oy - 1, ix}, -1, double(ix), b.oy - 0.5});
  for (int ix = b.ox; ix < b.ox + b.nx; ++ix) s.push_back({Edge::top, {1, 2 * (b.oy + b.ny) - 1, ix}, 1, double(ix), b.oy + b.ny - 0.5});
  return s;
}

// The assembled linear operator pieces over the unknowns z = (u~_x, u~_y, theta~) of the real
// nodes. Keeping theta as unknowns, as seed 000's static LPS does, keeps every row within one
// horizon: eliminating it couples nodes 2 delta apart and makes the LU several times denser.
//   forces  F = G z      (2N x 3N; rows x then y)
//   theta   theta~ = T u~ (N x 2N)
//   flux    of every boundary side, 2 N_b x 3N (rows: side-major, component-minor)
struct Operators {
  SpMat G, T, flux, P, Q;
};

Operators assemble(const Body& body, const Osb& model, const Box& b, const OsbStaticProblem& prob, const std::vector<Side>& sides) {
  const auto& bl = body.bonds;
  const long n_all = long(body.size()), N = long(b.real.size());
  const int order = prob.corrected ? prob.taylor_order : 0;
  Operators op;
  op.P = extrapolation_matrix(body, b, order);
  op.Q = extrapolation_matrix(body, b, std::max(order - 1, 0));
  // theta_real = D_x U_x + D_y U_y over every point (45); forces S_theta,c theta_all +
  // sum_d S_e,cd U_d (46, 47); the flux rows the same over crossing bonds (60).
  std::array<std::vector<Trip>, 2> td, ts, fe;
  std::array<std::array<std::vector<Trip>, 2>, 2> te;
  std::vector<Trip> fs;
  for (std::size_t r = 0; r < b.real.size(); ++r) {
    const auto i = b.real[r];
    for (auto k = bl.begin(i); k < bl.end(i); ++k) {
      // A broken bond enters with weight 0, not left out: the matrix keeps the pattern of the
      // first solve, so every re-solve reuses its fill-reducing ordering (OsbStaticOptions).
      const auto j = std::size_t(bl.neighbor[k]);
      const double len = bl.length[k], w = bl.intact[k] ? bl.weight[k] : 0.0;
      const double m[2] = {bl.xi[0][k] / len, bl.xi[1][k] / len};
      const double tw = model.theta_weight(i, len, w);
      const auto c = model.force_coefficients(i, j, len);
      for (int a = 0; a < 2; ++a) {
        td[a].emplace_back(long(r), long(j), tw * m[a]);
        td[a].emplace_back(long(r), long(i), -tw * m[a]);
        ts[a].emplace_back(long(r), long(i), w * c.A * m[a] / model.m[i]);
        ts[a].emplace_back(long(r), long(j), w * c.A * m[a] / model.m[j]);
        for (int d = 0; d < 2; ++d) {
          te[a][d].emplace_back(long(r), long(j), w * c.B * m[a] * m[d]);
          te[a][d].emplace_back(long(r), long(i), -w * c.B * m[a] * m[d]);
        }
      }
    }
  }
  const double h = b.grid.h;
  for (std::size_t s = 0; s < sides.size(); ++s)
    for_each_crossing(b.grid, bl, sides[s].segment, sides[s].normal_sign, false, [&](std::size_t k, double alpha) {
      // The start point j of bond k: the CSR row holding k.
      const auto j = std::size_t(std::upper_bound(bl.offset.begin(), bl.offset.end(), std::int64_t(k)) - bl.offset.begin() - 1);
      const auto q = std::size_t(bl.neighbor[k]);
      const double len = bl.length[k], w = bl.intact[k] ? bl.weight[k] : 0.0;
      const double m[2] = {bl.xi[0][k] / len, bl.xi[1][k] / len};
      const auto c = model.force_coefficients(j, q, len);
      const double scale = alpha * body.points.volume[j] / h * w;
      for (int a = 0; a < 2; ++a) {
        const long row = long(2 * s + std::size_t(a));
        fs.emplace_back(row, long(j), scale * m[a] * c.A / model.m[j]);
        fs.emplace_back(row, long(q), scale * m[a] * c.A / model.m[q]);
        for (int d = 0; d < 2; ++d) {
          fe[d].emplace_back(row, long(q), scale * m[a] * c.B * m[d]);
          fe[d].emplace_back(row, long(j), -scale * m[a] * c.B * m[d]);
        }
      }
    });
  const auto build = [](long rows, long cols, std::vector<Trip>& t) {
    SpMat M(rows, cols);
    M.setFromTriplets(t.begin(), t.end());
    std::vector<Trip>().swap(t);
    return M;
  };
  // Blocks [c][d] of a matrix with block columns (u_x, u_y, theta) into one matrix.
  const auto stack = [N](long rows_per_block, int row_blocks, const std::vector<std::array<const SpMat*, 3>>& blocks) {
    std::vector<Trip> t;
    for (int a = 0; a < row_blocks; ++a)
      for (int d = 0; d < 3; ++d) {
        const SpMat* B = blocks[std::size_t(a)][std::size_t(d)];
        if (!B) continue;
        for (long col = 0; col < B->outerSize(); ++col)
          for (SpMat::InnerIterator it(*B, col); it; ++it)
            t.emplace_back(it.row() + a * rows_per_block, it.col() + d * N, it.value());
      }
    SpMat M(rows_per_block * row_blocks, 3 * N);
    M.setFromTriplets(t.begin(), t.end());
    return M;
  };
  const SpMat T0 = build(N, n_all, td[0]) * op.P, T1 = build(N, n_all, td[1]) * op.P;
  {
    std::vector<Trip> t;
    for (int d = 0; d < 2; ++d) {
      const SpMat& B = d == 0 ? T0 : T1;
      for (long col = 0; col < B.outerSize(); ++col)
        for (SpMat::InnerIterator it(B, col); it; ++it) t.emplace_back(it.row(), it.col() + d * N, it.value());
    }
    op.T = build(N, 2 * N, t);
  }
  const SpMat G00 = build(N, n_all, te[0][0]) * op.P, G01 = build(N, n_all, te[0][1]) * op.P;
  const SpMat G10 = build(N, n_all, te[1][0]) * op.P, G11 = build(N, n_all, te[1][1]) * op.P;
  const SpMat G02 = build(N, n_all, ts[0]) * op.Q, G12 = build(N, n_all, ts[1]) * op.Q;
  op.G = stack(N, 2, {{&G00, &G01, &G02}, {&G10, &G11, &G12}});
  const long rows = long(2 * sides.size());
  const SpMat F0 = build(rows, n_all, fe[0]) * op.P, F1 = build(rows, n_all, fe[1]) * op.P, F2 = build(rows, n_all, fs) * op.Q;
  op.flux = stack(rows, 1, {{&F0, &F1, &F2}});
  return op;
}

// UMFPACK's factorisation of the re-solves. Its symbolic phase (the COLAMD ordering and the
// frontal structure) reads the pattern only, and the assembly keeps the first solve's pattern
// (broken bonds enter as zeros), so a re-solve redoes the numeric phase alone: about a third of a
// solve on the 40 x 40 crack plate. A pattern that differs is analysed again.
class UmfpackSolves {
 public:
  bool factorise(const SpMat& A, bool reuse) {
    const bool same = reuse && lu_ && A.rows() == rows_ && same_pattern(A);
    if (same) {
      lu_->factorize(A);
      if (lu_->info() == Eigen::Success) return true;
      // The old ordering's pivots may not suit the new values: a fresh analysis decides whether
      // the matrix is singular.
    }
    lu_ = std::make_unique<Eigen::UmfPackLU<SpMat>>();
    // Measured on the 40 x 40 crack deck: the unsymmetric strategy with AMD/COLAMD (no METIS)
    // factorises in half the time of UMFPACK's automatic choice.
    lu_->umfpackControl()(UMFPACK_STRATEGY) = UMFPACK_STRATEGY_UNSYMMETRIC;
    lu_->umfpackControl()(UMFPACK_ORDERING) = UMFPACK_ORDERING_AMD;
    lu_->analyzePattern(A);
    if (lu_->info() != Eigen::Success) return false;
    rows_ = A.rows();
    outer_.assign(A.outerIndexPtr(), A.outerIndexPtr() + A.outerSize() + 1);
    inner_.assign(A.innerIndexPtr(), A.innerIndexPtr() + A.nonZeros());
    ++analyses_;
    lu_->factorize(A);
    return lu_->info() == Eigen::Success;
  }
  Eigen::VectorXd solve(const Eigen::VectorXd& rhs) const {
    Eigen::VectorXd x = lu_->solve(rhs);
    if (lu_->info() != Eigen::Success) return {};
    return x;
  }
  std::size_t analyses() const { return analyses_; }

 private:
  bool same_pattern(const SpMat& A) const {
    return std::equal(outer_.begin(), outer_.end(), A.outerIndexPtr(), A.outerIndexPtr() + A.outerSize() + 1) &&
           std::equal(inner_.begin(), inner_.end(), A.innerIndexPtr(), A.innerIndexPtr() + A.nonZeros());
  }
  std::unique_ptr<Eigen::UmfPackLU<SpMat>> lu_;
  long rows_ = 0;
  std::vector<long> outer_, inner_;
  std::size_t analyses_ = 0;
};

Eigen::VectorXd factor_and_solve(const SpMat& A, const Eigen::VectorXd& rhs, const OsbStaticOptions& opt, UmfpackSolves& umfpack) {
  const LinearSolver which = opt.solver;
  Eigen::VectorXd x;
  if (which == LinearSolver::petsc) {
    std::vector<double> all;
    try {
      all = solve_on_ranks(A, rhs, opt.petsc);
    } catch (const std::runtime_error&) {
      return {};  // every rank holds the same system and fails alike
    }
    x = Eigen::Map<const Eigen::VectorXd>(all.data(), Eigen::Index(all.size()));
  } else if (which == LinearSolver::sparse_lu) {
    Eigen::SparseLU<SpMat> lu;
    lu.compute(A);
    if (lu.info() != Eigen::Success) return {};
    x = lu.solve(rhs);
  } else {
    if (!umfpack.factorise(A, opt.reuse_ordering)) return {};
    x = umfpack.solve(rhs);
  }
  if (!x.allFinite()) return {};
  return x;
}

}  // namespace

std::vector<double> taylor_weights(int order, const std::vector<std::array<int, 2>>& stencil, std::array<double, 2> target) {
  // Monomials x^a y^b with a + b <= order, restricted to the directions the stencil spans.
  const bool along_x = std::all_of(stencil.begin(), stencil.end(), [](auto s) { return s[1] == 0; });
  const bool along_y = std::all_of(stencil.begin(), stencil.end(), [](auto s) { return s[0] == 0; });
  std::vector<std::array<int, 2>> powers;
  for (int s = 0; s <= order; ++s)
    for (int q = 0; q <= s; ++q) {
      if ((along_x && q > 0) || (along_y && !along_x && s - q > 0)) continue;
      powers.push_back({s - q, q});
    }
  if (powers.size() != stencil.size()) throw std::invalid_argument("taylor weights: the stencil does not match the order");
  const auto n = long(stencil.size());
  Eigen::MatrixXd V(n, n);
  Eigen::VectorXd rhs(n);
  for (long a = 0; a < n; ++a) {
    const auto [px, py] = powers[std::size_t(a)];
    for (long k = 0; k < n; ++k) V(a, k) = std::pow(double(stencil[std::size_t(k)][0]), px) * std::pow(double(stencil[std::size_t(k)][1]), py);
    rhs[a] = std::pow(target[0], px) * std::pow(target[1], py);
  }
  const Eigen::VectorXd w = V.fullPivLu().solve(rhs);
  return {w.data(), w.data() + n};
}

struct OsbStaticSolver::Impl {
  Impl(Body& body_, const Osb& model_, const OsbStaticProblem& prob_, const OsbStaticOptions& opt_)
      : body(body_), model(model_), prob(prob_), opt(opt_) {
    if (body.dim() != 2) throw std::invalid_argument("osb static: only 2D");
    if (model.m.size() != body.size()) throw std::invalid_argument("osb static: the model's weighted volumes are not set");
    if (prob.corrected && (prob.taylor_order < 1 || prob.taylor_order > 3)) throw std::invalid_argument("osb static: taylor_order must be 1, 2 or 3");
    b = make_box(body);
    sides = boundary_sides(b);
    N = long(b.real.size());
    const double h = b.grid.h;
    const auto position = [&](double gx, double gy) { return Vec3{b.grid.x0 + gx * h, b.grid.y0 + gy * h, 0}; };
    res.real_points = std::size_t(N);
    for (const auto& s : sides) {
      res.boundary_position.push_back(position(s.gx, s.gy));
      res.boundary_normal.push_back(s.segment.axis == 0 ? std::array<double, 2>{double(s.normal_sign), 0} : std::array<double, 2>{0, double(s.normal_sign)});
    }

    // Right-hand side of equilibrium, -F(u~) = b (47): body force, plus tractions on the
    // outermost nodes when uncorrected.
    f = Eigen::VectorXd::Zero(2 * N);
    for (long r = 0; r < N; ++r)
      if (prob.body_force) {
        const auto bf = prob.body_force(body.points.position(b.real[std::size_t(r)]));
        f[r] = bf[0], f[N + r] = bf[1];
      }
    // Uncorrected Dirichlet rows: (real index, component, value).
    if (!prob.corrected)
      for (const auto& s : sides) {
        const int ix = int(std::lround(s.segment.axis == 0 ? s.gx - 0.5 * s.normal_sign : s.gx));
        const int iy = int(std::lround(s.segment.axis == 1 ? s.gy - 0.5 * s.normal_sign : s.gy));
        const long r = long(b.real_at(ix, iy));
        for (int c = 0; c < 2; ++c) {
          const auto& cond = prob.conditions.edge[std::size_t(s.edge)][std::size_t(c)];
          if (cond.displacement) pinned.emplace_back(r, c, cond.value);
          else f[c * N + r] += cond.value / h;
        }
      }
  }

  void advance() {
    remove_pending();
    auto& intact = body.bonds.intact;
    const auto t0 = std::chrono::steady_clock::now();
    const Operators op = assemble(body, model, b, prob, sides);
    // Rows: equilibrium -G z = f (2N), dilatation theta~ - T u~ = 0 (N), conditions B z = c (M).
    // Dilatation and condition rows are scaled to the largest |G_ij| (spec 004 Sec. 4 pitfall:
    // unscaled rows cost SparseLU 5 digits).
    double kmax = 0, tmax = 0;
    for (long col = 0; col < op.G.outerSize(); ++col)
      for (SpMat::InnerIterator it(op.G, col); it; ++it) kmax = std::max(kmax, std::abs(it.value()));
    for (long col = 0; col < op.T.outerSize(); ++col)
      for (SpMat::InnerIterator it(op.T, col); it; ++it) tmax = std::max(tmax, std::abs(it.value()));
    const double ts = kmax / std::max(tmax, 1.0);
    std::vector<Trip> t;
    t.reserve(std::size_t(op.G.nonZeros() + op.T.nonZeros() + 3 * N));
    std::vector<std::uint8_t> pinned_row(std::size_t(2 * N), 0);
    std::vector<double> pinned_value(std::size_t(2 * N), 0);
    for (auto [r, c, v] : pinned) pinned_row[std::size_t(c * N + r)] = 1, pinned_value[std::size_t(c * N + r)] = v;
    for (long col = 0; col < op.G.outerSize(); ++col)
      for (SpMat::InnerIterator it(op.G, col); it; ++it)
        if (!pinned_row[std::size_t(it.row())]) t.emplace_back(it.row(), it.col(), -it.value());
    Eigen::VectorXd rhs_u = Eigen::VectorXd::Zero(3 * N);
    rhs_u.head(2 * N) = f;
    for (long k = 0; k < 2 * N; ++k)
      if (pinned_row[std::size_t(k)]) t.emplace_back(k, k, kmax), rhs_u[k] = kmax * pinned_value[std::size_t(k)];
    for (long col = 0; col < op.T.outerSize(); ++col)
      for (SpMat::InnerIterator it(op.T, col); it; ++it) t.emplace_back(2 * N + it.row(), it.col(), -ts * it.value());
    for (long r = 0; r < N; ++r) t.emplace_back(2 * N + r, 2 * N + r, ts);
    std::vector<double> row_scale, c_bar;
    if (prob.corrected) {
      // Per side and component: a displacement row (P at the side centroid) or a flux row.
      const Eigen::SparseMatrix<double, Eigen::RowMajor, long> FR = op.flux;
      std::vector<std::pair<std::int64_t, double>> ext;
      std::vector<std::pair<long, double>> entries;
      long row = 3 * N;
      for (std::size_t s = 0; s < sides.size(); ++s)
        for (int c = 0; c < 2; ++c) {
          const auto& cond = prob.conditions.edge[std::size_t(sides[s].edge)][std::size_t(c)];
          entries.clear();
          if (cond.displacement) {
            extrapolation_row(b, sides[s].gx, sides[s].gy, prob.taylor_order, ext);
            for (auto [r, w] : ext) entries.emplace_back(long(r) + c * N, w);
          } else {
            for (Eigen::SparseMatrix<double, Eigen::RowMajor, long>::InnerIterator it(FR, long(2 * s) + c); it; ++it)
              entries.emplace_back(it.col(), it.value());
          }
          double bmax = 0;
          for (auto [col, v] : entries) bmax = std::max(bmax, std::abs(v));
          if (!(bmax > 0)) throw std::runtime_error("osb static: a boundary condition row is empty (every bond across a loaded side is broken)");
          const double sc = kmax / bmax;
          for (auto [col, v] : entries) {
            t.emplace_back(row, col, sc * v);
            t.emplace_back(col, row, sc * v);
          }
          row_scale.push_back(sc);
          c_bar.push_back(sc * cond.value);
          ++row;
        }
    }
    const long M = long(c_bar.size());
    SpMat A(3 * N + M, 3 * N + M);
    A.setFromTriplets(t.begin(), t.end());
    A.makeCompressed();
    Eigen::VectorXd rhs(3 * N + M);
    rhs << rhs_u, Eigen::Map<const Eigen::VectorXd>(c_bar.data(), M);
    res.assembly_seconds += since(t0);
    res.constraints = std::size_t(M);
    res.nonzeros = std::size_t(A.nonZeros());
    const auto t1 = std::chrono::steady_clock::now();
    const Eigen::VectorXd x = factor_and_solve(A, rhs, opt, umfpack);
    res.orderings = umfpack.analyses();
    res.factor_seconds += since(t1);
    ++res.solves;
    if (x.size() == 0) {
      if (res.solves == 1) throw std::runtime_error("osb static: the linear system is singular (are rigid motions constrained?)");
      res.stopped_singular = true;
      finished = true;
      return;
    }
    res.residual = (A * x - rhs).norm() / std::max(rhs.norm(), 1e-300);
    // Every point's displacement and dilatation (fictitious: extrapolated, Sec. 3.3).
    const Eigen::VectorXd ux = op.P * x.head(N), uy = op.P * x.segment(N, N), th = op.Q * x.segment(2 * N, N);
    res.u = zero_field(body.size());
    res.theta.assign(body.size(), 0);
    for (std::size_t p = 0; p < body.size(); ++p) res.u[0][p] = ux[long(p)], res.u[1][p] = uy[long(p)], res.theta[p] = th[long(p)];
    res.multipliers.assign(std::size_t(M), 0);
    for (long k = 0; k < M; ++k) res.multipliers[std::size_t(k)] = x[3 * N + k] * row_scale[std::size_t(k)];
    const Eigen::VectorXd tau = op.flux * x.head(3 * N);
    res.boundary_traction.assign(sides.size(), {0, 0});
    for (std::size_t s = 0; s < sides.size(); ++s) res.boundary_traction[s] = {tau[long(2 * s)], tau[long(2 * s + 1)]};
    model.pair_forces_with(body, res.u, res.theta, res.pair_force);
    if (!(opt.critical_stretch > 0)) {
      finished = true;
      return;
    }
    // Sequentially linear step: the most stretched bonds with a real end go.
    const auto& bl = body.bonds;
    std::vector<std::pair<double, std::int64_t>> over;
    for (std::size_t i = 0; i < body.size(); ++i)
      for (auto k = bl.begin(i); k < bl.end(i); ++k) {
        const auto j = std::size_t(bl.neighbor[k]);
        if (!intact[k] || j < i || (b.dof[i] < 0 && b.dof[j] < 0)) continue;
        const double s = linear_extension(bl, res.u, i, k) / bl.length[k];
        if (s >= opt.critical_stretch) over.emplace_back(s, k);
      }
    if (over.empty() || res.solves >= opt.max_solves) {
      finished = true;
      return;
    }
    const auto take = std::min<std::size_t>(over.size(), std::size_t(opt.bonds_per_solve));
    std::partial_sort(over.begin(), over.begin() + long(take), over.end(), [](auto& a, auto& c) { return a.first > c.first || (a.first == c.first && a.second < c.second); });
    // They go at the start of the next advance, so that after each advance the body's bonds are
    // the ones this solution was solved on (an observer's strain energy and damage match it).
    for (std::size_t q = 0; q < take; ++q) pending.push_back(over[q].second);
  }

  // The bonds chosen after the previous solve, both directions.
  void remove_pending() {
    if (pending.empty()) return;
    auto& intact = body.bonds.intact;
    const auto& bl = body.bonds;
    for (const auto k : pending) {
      const auto i = std::size_t(std::upper_bound(bl.offset.begin(), bl.offset.end(), k) - bl.offset.begin() - 1);
      const auto j = std::size_t(bl.neighbor[k]);
      intact[k] = 0;
      for (auto kk = bl.begin(j); kk < bl.end(j); ++kk)
        if (std::size_t(bl.neighbor[kk]) == i) intact[kk] = 0;
      ++res.broken;
    }
    pending.clear();
    if (opt.progress) opt.progress(res.solves, res.broken);
  }

  Body& body;
  const Osb& model;
  OsbStaticProblem prob;
  OsbStaticOptions opt;
  Box b;
  std::vector<Side> sides;
  long N = 0;
  Eigen::VectorXd f;                                  // right-hand side of equilibrium (47)
  std::vector<std::tuple<long, int, double>> pinned;  // uncorrected Dirichlet rows: (real index, component, value)
  OsbStaticResult res;
  std::vector<std::int64_t> pending;  // bonds to remove before the next solve
  UmfpackSolves umfpack;
  bool finished = false;
};

OsbStaticSolver::OsbStaticSolver(Body& body, const Osb& model, const OsbStaticProblem& problem, const OsbStaticOptions& options)
    : impl_(std::make_unique<Impl>(body, model, problem, options)) {}
OsbStaticSolver::OsbStaticSolver(OsbStaticSolver&&) noexcept = default;
OsbStaticSolver& OsbStaticSolver::operator=(OsbStaticSolver&&) noexcept = default;
OsbStaticSolver::~OsbStaticSolver() = default;
bool OsbStaticSolver::done() const { return impl_->finished; }
void OsbStaticSolver::advance() {
  if (!impl_->finished) impl_->advance();
}
const OsbStaticResult& OsbStaticSolver::result() const { return impl_->res; }

OsbStaticResult solve_osb_static(Body& body, const Osb& model, const OsbStaticProblem& prob, const OsbStaticOptions& opt) {
  OsbStaticSolver solver(body, model, prob, opt);
  while (!solver.done()) solver.advance();
  return solver.result();
}

}  // namespace peridot
