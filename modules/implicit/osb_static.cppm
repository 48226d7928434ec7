module;
#include <Eigen/Dense>
#include <Eigen/SparseCore>
#include <Eigen/SparseLU>
#include <Eigen/UmfPackSupport>
// LAPACK's banded LU with partial pivoting (OpenBLAS's, as bootstrap selects it).
extern "C" void dgbsv_(const int* n, const int* kl, const int* ku, const int* nrhs, double* ab, const int* ldab, int* ipiv, double* b,
                       const int* ldb, int* info);
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
  // A re-solve whose relative residual |A x - b| / |b| exceeds this found no equilibrium: the
  // body has come apart and its matrix is singular to round-off (no pivot exactly zero). It ends
  // the fracture as an exactly singular system does, and the last equilibrium stands. Seed 004's
  // crack decks leave 1e-10 to 3e-8 in their equilibria (2e-6 in crack_neumann's last, as it
  // nears the end) and 0.9 to 9 past them: the bound sits in the gap, far from both, so that
  // every solver (UMFPACK, banded LU, MUMPS on N ranks) stops at the same re-solve.
  double singular_residual = 1e-3;
  std::function<void(std::size_t solve, std::size_t broken)> progress;
  // UMFPACK: re-solves reuse the first solve's fill-reducing ordering and frontal structure (the
  // matrix keeps its pattern; only values change). false analyses every matrix afresh.
  bool reuse_ordering = true;
  // solver = umfpack: a banded LU (LAPACK's dgbsv, partial pivoting) with the unknowns ordered
  // column by column across the plate instead, where its cost is below UMFPACK's (small
  // systems: Ex. 1's 2,000 unknowns have a half-bandwidth of 200 and factor and solve in 10 ms
  // against UMFPACK's 33-36). A deck that names linear_solver: umfpack gets UMFPACK (never).
  enum class Banded { when_cheaper, never, always };
  Banded banded = Banded::when_cheaper;
};

// With OsbParts, u, theta and the pair forces are right on the owned points and their bonds'
// partners, multipliers and boundary fields are the owned sides' only, and the counts and the
// residual are the whole system's.
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
  int band = 0;                        // > 0: the last solve was a banded LU of this half-bandwidth
  bool stopped_singular = false;       // fracture ended because equilibrium became impossible
  double residual = 0;                 // |A x - b| / |b| of the last solve
  double assembly_seconds = 0, factor_seconds = 0;
};

// One rank's share of a static OSB solve on N ranks (PETSc). The body is the rank's part: the
// sites of its brick of the grown rectangle and those around it, in ascending one-rank index.
// The rank assembles the rows of the real points it owns and the condition rows of the sides it
// owns (a side belongs to the owner of its real node). Rows are numbered rank after rank: rank
// r's block holds the u_x, then the u_y, then the theta of its real points, then the two rows of
// each of its sides, so a rank's rows are contiguous and a column is known without asking.
struct OsbParts {
  int rank = 0, ranks = 1;
  std::vector<std::int64_t> global_id;  // per local point: its index on one rank (ascending)
  std::vector<int> owner;               // per local point
  std::vector<std::int64_t> index;      // per local real point: its place among its owner's real points
  std::vector<std::int64_t> reals;      // per rank: the real points it owns
  std::vector<std::int64_t> first;      // ranks + 1: where each rank's rows start
  std::vector<int> side_owner;          // per side of the whole rectangle, in OsbStaticResult's order
  std::vector<std::int64_t> side_row;   // per side: its first condition row (corrected only)
  std::array<int, 4> box{};             // the whole rectangle of real points (x, y, nx, ny) in lattice_grid(local points)
  std::vector<std::int64_t> ghost;      // local points other ranks own, their owners and their indices there
  std::vector<int> ghost_owner;
  std::vector<std::int64_t> ghost_owner_index;
  bool owns(std::size_t i) const { return owner[i] == rank; }
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
  // With `parts` (which must outlive it) every call is collective and solves on PETSc.
  OsbStaticSolver(Body& body, const Osb& model, const OsbStaticProblem& problem, const OsbStaticOptions& options = {},
                  const OsbParts* parts = nullptr);
  OsbStaticSolver(OsbStaticSolver&&) noexcept;
  OsbStaticSolver& operator=(OsbStaticSolver&&) noexcept;
  ~OsbStaticSolver();
  bool done() const;
  void advance();
  // u, theta, pair forces and tractions of the last solve; counts of solves and removed bonds.
  const OsbStaticResult& result() const;
  // With parts: the halo that brings the ghosts their owners' values (null on one process).
  const parallel::Halo* halo() const;

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

std::invalid_argument too_few_nodes(int order) {
  return std::invalid_argument(fmt::format("osb static: Taylor order {} needs at least {} real nodes across the body", order, order + 1));
}
constexpr const char* empty_condition_row = "osb static: a boundary condition row is empty (every bond across a loaded side is broken)";

// Sparse linear form over the real points: point p of the grid (possibly outside the box) as
// Taylor extrapolation from the nearest real node (Sec. 3.2), order n. A rank's part (`partial`)
// lacks the stencils of points at its outer edge, which no owned row reads: those rows stay
// empty (false).
bool extrapolation_row(const Box& b, double gx, double gy, int order, std::vector<std::pair<std::int64_t, double>>& row, bool partial = false) {
  row.clear();
  const int jx = std::clamp(int(std::lround(gx)), b.ox, b.ox + b.nx - 1), jy = std::clamp(int(std::lround(gy)), b.oy, b.oy + b.ny - 1);
  const double lx = gx - jx, ly = gy - jy;
  if (lx == 0 && ly == 0) {
    row.emplace_back(b.real_at(jx, jy), 1.0);
    return true;
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
    if (r < 0 && partial) {
      row.clear();
      return false;
    }
    if (r < 0) throw too_few_nodes(order);
    if (w[k] != 0) row.emplace_back(r, w[k]);
  }
  return true;
}

// Every point (real or fictitious) as a linear form over the real values, as a sparse matrix.
SpMat extrapolation_matrix(const Body& body, const Box& b, int order, bool partial) {
  std::vector<Trip> t;
  std::vector<std::pair<std::int64_t, double>> row;
  for (std::size_t p = 0; p < body.size(); ++p) {
    extrapolation_row(b, b.grid.gx[p], b.grid.gy[p], order, row, partial);
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

// On a rank's part (`partial`) only the rows in `kept` (per real index; the owned ones) are
// assembled; the others stay empty.
Operators assemble(const Body& body, const Osb& model, const Box& b, const OsbStaticProblem& prob, const std::vector<Side>& sides, bool partial,
                   std::span<const std::uint8_t> kept = {}) {
  const auto& bl = body.bonds;
  const long n_all = long(body.size()), N = long(b.real.size());
  const int order = prob.corrected ? prob.taylor_order : 0;
  Operators op;
  op.P = extrapolation_matrix(body, b, order, partial);
  op.Q = extrapolation_matrix(body, b, std::max(order - 1, 0), partial);
  // theta_real = D_x U_x + D_y U_y over every point (45); forces S_theta,c theta_all +
  // sum_d S_e,cd U_d (46, 47); the flux rows the same over crossing bonds (60).
  std::array<std::vector<Trip>, 2> td, ts, fe;
  std::array<std::array<std::vector<Trip>, 2>, 2> te;
  std::vector<Trip> fs;
  for (std::size_t r = 0; r < b.real.size(); ++r) {
    if (!kept.empty() && !kept[r]) continue;
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

// The banded LU of the re-solves: the order and the band from the first matrix, kept while
// every entry of a later one lies in the band (removed bonds only drop entries).
class BandedSolves {
 public:
  // Whether the banded LU is the cheaper one for A (its order and band are then kept). place:
  // each unknown's grid position along the body's longer axis, then the other.
  bool suits(const SpMat& A, OsbStaticOptions::Banded mode, std::span<const std::array<double, 2>> place) {
    if (mode == OsbStaticOptions::Banded::never) return false;
    // Re-solves keep the first matrix's pattern: once UMFPACK is the cheaper, it stays so.
    if (mode == OsbStaticOptions::Banded::when_cheaper && umfpack_rows_ == A.rows()) return false;
    if (!fits(A)) {
      // The unknowns swept across the body's longer axis, column by column: each column's
      // unknowns then reach the next few columns only. (A reverse Cuthill-McKee order's levels
      // start at a corner and run diagonally: Ex. 1's 30 x 20 plate had half-bandwidth 339
      // there, 200 here, and factored and solved in 26-30 ms against 9-10.)
      std::vector<int> order(std::size_t(A.rows()));
      std::iota(order.begin(), order.end(), 0);
      std::stable_sort(order.begin(), order.end(), [&](int x, int y) { return place[std::size_t(x)] < place[std::size_t(y)]; });
      position_.assign(order.size(), 0);
      for (std::size_t k = 0; k < order.size(); ++k) position_[std::size_t(order[k])] = int(k);
      kl_ = ku_ = 0;
      for (int c = 0; c < int(A.cols()); ++c)
        for (SpMat::InnerIterator it(A, c); it; ++it) {
          const int r = position_[std::size_t(it.row())], q = position_[std::size_t(c)];
          kl_ = std::max(kl_, r - q), ku_ = std::max(ku_, q - r);
        }
    }
    if (mode == OsbStaticOptions::Banded::always) return true;
    // dgbtrf's flops, 2 n kl (kl + ku), against UMFPACK's time, measured on this project's OSB
    // systems (Zen 5, OpenBLAS): equal near 9e9 flops (the 40 x 40 crack plate, 5,120 unknowns,
    // band 653), the banded LU 2.3x faster at 9e8 (Ex. 1). Below 3e9 it is chosen, and only where
    // the band's storage stays under 256 MB.
    const double n = double(A.rows()), flops = 2 * n * kl_ * double(kl_ + ku_), bytes = 8 * n * double(2 * kl_ + ku_ + 1);
    if (flops < 3e9 && bytes < 256e6) return true;
    umfpack_rows_ = A.rows();
    return false;
  }
  // Factorises and solves A x = rhs; empty when A is singular.
  Eigen::VectorXd solve(const SpMat& A, const Eigen::VectorXd& rhs) {
    const int n = int(A.rows()), ldab = 2 * kl_ + ku_ + 1, one = 1;
    band_.assign(std::size_t(ldab) * std::size_t(n), 0.0);
    for (int c = 0; c < n; ++c)
      for (SpMat::InnerIterator it(A, c); it; ++it) {
        const int r = position_[std::size_t(it.row())], q = position_[std::size_t(c)];
        band_[std::size_t(q) * std::size_t(ldab) + std::size_t(kl_ + ku_ + r - q)] = it.value();
      }
    std::vector<double> x(static_cast<std::size_t>(n));
    for (int k = 0; k < n; ++k) x[std::size_t(position_[std::size_t(k)])] = rhs[k];
    pivots_.resize(std::size_t(n));
    int info = 0;
    dgbsv_(&n, &kl_, &ku_, &one, band_.data(), &ldab, pivots_.data(), x.data(), &n, &info);
    if (info != 0) return {};
    Eigen::VectorXd out(n);
    for (int k = 0; k < n; ++k) out[k] = x[std::size_t(position_[std::size_t(k)])];
    return out;
  }
  int band() const { return std::max(kl_, ku_); }

 private:
  bool fits(const SpMat& A) const {
    if (position_.size() != std::size_t(A.rows())) return false;
    for (int c = 0; c < int(A.cols()); ++c)
      for (SpMat::InnerIterator it(A, c); it; ++it) {
        const int d = position_[std::size_t(it.row())] - position_[std::size_t(c)];
        if (d > kl_ || -d > ku_) return false;
      }
    return true;
  }
  std::vector<int> position_, pivots_;  // position_[unknown]: its place in the order
  int kl_ = 0, ku_ = 0;
  Eigen::Index umfpack_rows_ = -1;  // the size of the system UMFPACK was found cheaper for
  std::vector<double> band_;
};

Eigen::VectorXd factor_and_solve(const SpMat& A, const Eigen::VectorXd& rhs, const OsbStaticOptions& opt, UmfpackSolves& umfpack,
                                 BandedSolves& banded, int& band, std::span<const std::array<double, 2>> place) {
  band = 0;
  if (opt.solver == LinearSolver::umfpack && banded.suits(A, opt.banded, place)) {
    band = banded.band();
    Eigen::VectorXd x = banded.solve(A, rhs);
    if (x.size() == 0 || !x.allFinite()) return {};
    return x;
  }
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
  Impl(Body& body_, const Osb& model_, const OsbStaticProblem& prob_, const OsbStaticOptions& opt_, const OsbParts* parts_)
      : body(body_), model(model_), prob(prob_), opt(opt_), parts(parts_) {
    if (body.dim() != 2) throw std::invalid_argument("osb static: only 2D");
    if (model.m.size() != body.size()) throw std::invalid_argument("osb static: the model's weighted volumes are not set");
    if (prob.corrected && (prob.taylor_order < 1 || prob.taylor_order > 3)) throw std::invalid_argument("osb static: taylor_order must be 1, 2 or 3");
    if (parts && opt.solver != LinearSolver::petsc) throw std::invalid_argument("osb static: a distributed solve runs on PETSc");
    if (parts && (parts->global_id.size() != body.size() || parts->owner.size() != body.size() || parts->index.size() != body.size()))
      throw std::invalid_argument("osb static: the parts need an id, an owner and an index per local point");
    b = make_box(body);
    // On a part the conditions sit on the whole rectangle's sides, not on the part's edges.
    Box whole = b;
    if (parts) {
      whole.ox = parts->box[0], whole.oy = parts->box[1], whole.nx = parts->box[2], whole.ny = parts->box[3];
      if (prob.corrected && std::min(whole.nx, whole.ny) < prob.taylor_order + 1) throw too_few_nodes(prob.taylor_order);
    }
    const auto all_sides = boundary_sides(whole);
    all_side_count = all_sides.size();
    for (std::size_t s = 0; s < all_sides.size(); ++s) {
      const auto [ix, iy] = real_node_of(all_sides[s]);
      if (parts && b.real_at(ix, iy) < 0) continue;
      sides.push_back(all_sides[s]);
      side_id.push_back(s);
    }
    N = long(b.real.size());
    const double h = b.grid.h;
    const auto position = [&](double gx, double gy) { return Vec3{b.grid.x0 + gx * h, b.grid.y0 + gy * h, 0}; };
    res.real_points = parts ? std::size_t(whole.nx) * std::size_t(whole.ny) : std::size_t(N);
    for (std::size_t k = 0; k < sides.size(); ++k) {
      if (parts && parts->side_owner[side_id[k]] != parts->rank) continue;
      reported.push_back(k);
      const auto& s = sides[k];
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
        const auto [ix, iy] = real_node_of(s);
        const long r = long(b.real_at(ix, iy));
        for (int c = 0; c < 2; ++c) {
          const auto& cond = prob.conditions.edge[std::size_t(s.edge)][std::size_t(c)];
          if (cond.displacement) pinned.emplace_back(r, c, cond.value);
          else f[c * N + r] += cond.value / h;
        }
      }
    if (parts) {
      halo.emplace(body.size(), parts->ghost, parts->ghost_owner, parts->ghost_owner_index);
      for (long r = 0; r < N; ++r) owned_rows.push_back(owns_real(r) ? 1 : 0);
    }
  }

  // The real node next to a side (grid units).
  static std::array<int, 2> real_node_of(const Side& s) {
    return {int(std::lround(s.segment.axis == 0 ? s.gx - 0.5 * s.normal_sign : s.gx)), int(std::lround(s.segment.axis == 1 ? s.gy - 0.5 * s.normal_sign : s.gy))};
  }
  bool owns_real(long r) const { return !parts || parts->owns(b.real[std::size_t(r)]); }
  std::int64_t id_of(std::size_t p) const { return parts ? parts->global_id[p] : std::int64_t(p); }
  std::int64_t local_of(std::int64_t id) const {
    if (!parts) return id;
    const auto& g = parts->global_id;
    const auto it = std::lower_bound(g.begin(), g.end(), id);
    return it != g.end() && *it == id ? std::int64_t(it - g.begin()) : -1;
  }

  // Side k's condition row for component c over the columns (u_x, u_y, theta) of the real
  // nodes: a displacement (P at the side centroid) or the force flux (60). False where a part
  // lacks the stencil.
  bool condition_row(std::size_t k, int c, const Eigen::SparseMatrix<double, Eigen::RowMajor, long>& FR, std::vector<std::pair<long, double>>& entries) {
    const auto& cond = prob.conditions.edge[std::size_t(sides[k].edge)][std::size_t(c)];
    entries.clear();
    if (cond.displacement) {
      if (!extrapolation_row(b, sides[k].gx, sides[k].gy, prob.taylor_order, ext, parts != nullptr)) return false;
      for (auto [r, w] : ext) entries.emplace_back(long(r) + c * N, w);
    } else {
      for (Eigen::SparseMatrix<double, Eigen::RowMajor, long>::InnerIterator it(FR, long(2 * k) + c); it; ++it) entries.emplace_back(it.col(), it.value());
    }
    return true;
  }

  void advance() {
    remove_pending();
    auto& intact = body.bonds.intact;
    const auto t0 = std::chrono::steady_clock::now();
    const Operators op = assemble(body, model, b, prob, sides, parts != nullptr, owned_rows);
    // Rows: equilibrium -G z = f (2N), dilatation theta~ - T u~ = 0 (N), conditions B z = c (M).
    // Dilatation and condition rows are scaled to the largest |G_ij| (spec 004 Sec. 4 pitfall:
    // unscaled rows cost SparseLU 5 digits); on N ranks the largest over every rank's rows.
    double kmax = 0, tmax = 0;
    for (long col = 0; col < op.G.outerSize(); ++col)
      for (SpMat::InnerIterator it(op.G, col); it; ++it)
        if (owns_real(it.row() % N)) kmax = std::max(kmax, std::abs(it.value()));
    for (long col = 0; col < op.T.outerSize(); ++col)
      for (SpMat::InnerIterator it(op.T, col); it; ++it)
        if (owns_real(it.row())) tmax = std::max(tmax, std::abs(it.value()));
    if (parts) {
      std::array<double, 2> m{kmax, tmax};
      parallel::max_over_ranks(m);
      kmax = m[0], tmax = m[1];
    }
    const double ts = kmax / std::max(tmax, 1.0);
    const double last_residual = res.residual;
    const auto last_multipliers = res.multipliers;
    const Eigen::VectorXd x = parts ? solve_parts(op, kmax, ts, t0) : solve_whole(op, kmax, ts, t0);
    ++res.solves;
    // Past an equilibrium only a fracture run can get: its removed bonds cut the body loose.
    const bool no_equilibrium = x.size() == 0 || (res.solves > 1 && !(res.residual <= opt.singular_residual));
    if (no_equilibrium) {
      if (res.solves == 1) throw std::runtime_error("osb static: the linear system is singular (are rigid motions constrained?)");
      res.residual = last_residual;
      res.multipliers = last_multipliers;
      res.stopped_singular = true;
      finished = true;
      return;
    }
    // Every point's displacement and dilatation (fictitious: extrapolated, Sec. 3.3).
    const Eigen::VectorXd ux = op.P * x.head(N), uy = op.P * x.segment(N, N), th = op.Q * x.segment(2 * N, N);
    res.u = zero_field(body.size());
    res.theta.assign(body.size(), 0);
    for (std::size_t p = 0; p < body.size(); ++p) res.u[0][p] = ux[long(p)], res.u[1][p] = uy[long(p)], res.theta[p] = th[long(p)];
    const Eigen::VectorXd tau = op.flux * x.head(3 * N);
    res.boundary_traction.assign(reported.size(), {0, 0});
    for (std::size_t q = 0; q < reported.size(); ++q) res.boundary_traction[q] = {tau[long(2 * reported[q])], tau[long(2 * reported[q] + 1)]};
    model.pair_forces_with(body, res.u, res.theta, res.pair_force);
    if (!(opt.critical_stretch > 0)) {
      finished = true;
      return;
    }
    // Sequentially linear step: the most stretched bonds with a real end go; ties go to the
    // bond first in the one-rank list (its start, then its place in the start's row), so that N
    // ranks choose what one does.
    const auto& bl = body.bonds;
    struct Candidate {
      double s;
      std::int64_t i, place, j;  // one-rank ids of the ends, the place in i's row
    };
    std::vector<Candidate> over;
    for (std::size_t i = 0; i < body.size(); ++i) {
      if (parts && !parts->owns(i)) continue;
      for (auto k = bl.begin(i); k < bl.end(i); ++k) {
        const auto j = std::size_t(bl.neighbor[k]);
        if (!intact[k] || j < i || (b.dof[i] < 0 && b.dof[j] < 0)) continue;
        const double s = linear_extension(bl, res.u, i, k) / bl.length[k];
        if (s >= opt.critical_stretch) over.push_back({s, id_of(i), std::int64_t(k - bl.begin(i)), id_of(j)});
      }
    }
    const auto first = [](const Candidate& a, const Candidate& c) { return a.s > c.s || (a.s == c.s && (a.i < c.i || (a.i == c.i && a.place < c.place))); };
    const auto bps = std::size_t(opt.bonds_per_solve);
    std::uint64_t total = over.size();
    std::partial_sort(over.begin(), over.begin() + long(std::min(over.size(), bps)), over.end(), first);
    if (parts) {
      // Each rank's best few, summed into one table: every rank then picks the same bonds.
      over.resize(std::min(over.size(), bps));
      parallel::sum_over_ranks(total);
      const auto ranks = std::size_t(parts->ranks), me = std::size_t(parts->rank);
      std::vector<std::int64_t> table(ranks + 4 * ranks * bps, 0);
      table[me] = std::int64_t(over.size());
      for (std::size_t q = 0; q < over.size(); ++q) {
        auto* slot = &table[ranks + 4 * (me * bps + q)];
        slot[0] = std::bit_cast<std::int64_t>(over[q].s), slot[1] = over[q].i, slot[2] = over[q].place, slot[3] = over[q].j;
      }
      parallel::sum_over_ranks(table);
      over.clear();
      for (std::size_t r = 0; r < ranks; ++r)
        for (std::size_t q = 0; q < std::size_t(table[r]); ++q) {
          const auto* slot = &table[ranks + 4 * (r * bps + q)];
          over.push_back({std::bit_cast<double>(slot[0]), slot[1], slot[2], slot[3]});
        }
      std::partial_sort(over.begin(), over.begin() + long(std::min(over.size(), bps)), over.end(), first);
    }
    if (total == 0 || res.solves >= opt.max_solves) {
      finished = true;
      return;
    }
    // They go at the start of the next advance, so that after each advance the body's bonds are
    // the ones this solution was solved on (an observer's strain energy and damage match it).
    for (std::size_t q = 0; q < std::min(over.size(), bps); ++q) pending.emplace_back(over[q].i, over[q].j);
  }

  // Where each unknown of the whole system sits, in grid units along the box's longer axis, then
  // the other: a real point's u, v and dilatation at the point, a condition row at its side.
  std::vector<std::array<double, 2>> unknown_places(long M) const {
    const bool x_longer = b.nx >= b.ny;
    const auto at = [&](double gx, double gy) { return x_longer ? std::array{gx, gy} : std::array{gy, gx}; };
    std::vector<std::array<double, 2>> out(std::size_t(3 * N + M));
    for (long k = 0; k < 3 * N; ++k) {
      const auto p = b.real[std::size_t(k % N)];
      out[std::size_t(k)] = at(b.grid.gx[p], b.grid.gy[p]);
    }
    for (long m = 0; m < M; ++m) out[std::size_t(3 * N + m)] = at(sides[std::size_t(m / 2)].gx, sides[std::size_t(m / 2)].gy);
    return out;
  }

  // One process: the whole system, solved by UMFPACK, SparseLU, or PETSc on the replicated system.
  Eigen::VectorXd solve_whole(const Operators& op, double kmax, double ts, std::chrono::steady_clock::time_point t0) {
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
      const Eigen::SparseMatrix<double, Eigen::RowMajor, long> FR = op.flux;
      std::vector<std::pair<long, double>> entries;
      long row = 3 * N;
      for (std::size_t k = 0; k < sides.size(); ++k)
        for (int c = 0; c < 2; ++c) {
          condition_row(k, c, FR, entries);
          const double sc = condition_scale(kmax, entries);
          for (auto [col, v] : entries) {
            t.emplace_back(row, col, sc * v);
            t.emplace_back(col, row, sc * v);
          }
          row_scale.push_back(sc);
          c_bar.push_back(sc * prob.conditions.edge[std::size_t(sides[k].edge)][std::size_t(c)].value);
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
    if (place.size() != std::size_t(A.rows())) place = unknown_places(M);
    const Eigen::VectorXd x = factor_and_solve(A, rhs, opt, umfpack, banded, res.band, place);
    res.orderings = umfpack.analyses();
    res.factor_seconds += since(t1);
    if (x.size() == 0) return x;
    res.residual = (A * x - rhs).norm() / std::max(rhs.norm(), 1e-300);
    res.multipliers.assign(std::size_t(M), 0);
    for (long k = 0; k < M; ++k) res.multipliers[std::size_t(k)] = x[3 * N + k] * row_scale[std::size_t(k)];
    return x.head(3 * N);
  }

  // A condition row scaled to the largest |G_ij|.
  static double condition_scale(double kmax, const std::vector<std::pair<long, double>>& entries) {
    double bmax = 0;
    for (auto [col, v] : entries) bmax = std::max(bmax, std::abs(v));
    if (!(bmax > 0)) throw std::runtime_error(empty_condition_row);
    return kmax / bmax;
  }

  // N ranks: this rank's rows of the system solve_whole builds (the same rows, scaled alike,
  // numbered rank after rank), solved on PETSc. Returns z of every held real point, the ghosts'
  // from their owners through the halo, or nothing when the system is singular. Collective.
  Eigen::VectorXd solve_parts(const Operators& op, double kmax, double ts, std::chrono::steady_clock::time_point t0) {
    const auto& P = *parts;
    const auto me = std::size_t(P.rank);
    const std::int64_t mine = P.reals[me], first = P.first[me], rows = P.first[me + 1] - first;
    // Global rows and columns: component c of real node r (local), and the owned ones.
    const auto unknown = [&](long r, long c) {
      const auto p = b.real[std::size_t(r)];
      const auto o = std::size_t(P.owner[p]);
      return P.first[o] + c * P.reals[o] + P.index[p];
    };
    const auto column = [&](long col) { return unknown(col % N, col / N); };
    std::vector<parallel::Entry> e;
    std::vector<double> rhs(std::size_t(rows), 0.0);
    std::vector<std::uint8_t> pinned_row(std::size_t(2 * N), 0);
    std::vector<double> pinned_value(std::size_t(2 * N), 0);
    for (auto [r, c, v] : pinned) pinned_row[std::size_t(c * N + r)] = 1, pinned_value[std::size_t(c * N + r)] = v;
    for (long col = 0; col < op.G.outerSize(); ++col)
      for (SpMat::InnerIterator it(op.G, col); it; ++it)
        if (owns_real(it.row() % N) && !pinned_row[std::size_t(it.row())]) e.push_back({unknown(it.row() % N, it.row() / N), column(col), -it.value()});
    for (long col = 0; col < op.T.outerSize(); ++col)
      for (SpMat::InnerIterator it(op.T, col); it; ++it)
        if (owns_real(it.row())) e.push_back({unknown(it.row(), 2), column(col), -ts * it.value()});
    for (long r = 0; r < N; ++r) {
      if (!owns_real(r)) continue;
      for (long a = 0; a < 2; ++a) {
        const auto k = std::size_t(a * N + r);
        const auto row = unknown(r, a);
        if (pinned_row[k]) e.push_back({row, row, kmax});
        rhs[std::size_t(row - first)] = pinned_row[k] ? kmax * pinned_value[k] : f[long(k)];
      }
      e.push_back({unknown(r, 2), unknown(r, 2), ts});
    }
    // Condition rows: the owned sides' rows, and the transposed entries in the owned real
    // nodes' rows, of every side whose row reaches one (each computed here alike).
    std::vector<double> row_scale;
    int empty = 0;
    if (prob.corrected) {
      const Eigen::SparseMatrix<double, Eigen::RowMajor, long> FR = op.flux;
      std::vector<std::pair<long, double>> entries;
      for (std::size_t k = 0; k < sides.size(); ++k)
        for (int c = 0; c < 2; ++c) {
          const auto sg = side_id[k];
          const bool own = P.side_owner[sg] == P.rank;
          if (!condition_row(k, c, FR, entries) && own) throw std::logic_error("osb static: a part lacks an owned side's stencil");
          const bool reaches = std::ranges::any_of(entries, [&](const auto& en) { return owns_real(en.first % N); });
          if (!own && !reaches) continue;
          double sc = 0;
          try {
            sc = condition_scale(kmax, entries);
          } catch (const std::runtime_error&) {
            empty = 1;
            continue;
          }
          const auto row = P.side_row[sg] + c;
          for (auto [col, v] : entries) {
            if (own) e.push_back({row, column(col), sc * v});
            if (owns_real(col % N)) e.push_back({column(col), row, sc * v});
          }
          if (own) {
            rhs[std::size_t(row - first)] = sc * prob.conditions.edge[std::size_t(sides[k].edge)][std::size_t(c)].value;
            row_scale.push_back(sc);
          }
        }
    }
    if (parallel::max_over_ranks(empty)) throw std::runtime_error(empty_condition_row);
    std::sort(e.begin(), e.end(), [](const auto& a, const auto& c) { return a.row != c.row ? a.row < c.row : a.col < c.col; });
    parallel::RowBlock block;
    block.global_rows = P.first.back();
    block.first_row = first;
    block.offset.assign(std::size_t(rows) + 1, 0);
    for (std::size_t q = 0; q < e.size(); ++q) {
      if (q > 0 && e[q].row == e[q - 1].row && e[q].col == e[q - 1].col) {
        block.value.back() += e[q].value;
        continue;
      }
      block.column.push_back(e[q].col);
      block.value.push_back(e[q].value);
      ++block.offset[std::size_t(e[q].row - first) + 1];
    }
    std::partial_sum(block.offset.begin(), block.offset.end(), block.offset.begin());
    block.rhs = std::move(rhs);
    std::vector<parallel::Entry>().swap(e);
    std::uint64_t nonzeros = block.column.size();
    parallel::sum_over_ranks(nonzeros);
    res.nonzeros = std::size_t(nonzeros);
    res.constraints = prob.corrected ? 2 * all_side_count : 0;
    res.assembly_seconds += since(t0);
    const auto t1 = std::chrono::steady_clock::now();
    std::vector<double> own;
    int failed = 0;
    try {
      own = parallel::ksp_solve(std::move(block), opt.petsc, &report, parallel::SolutionRows::own);
    } catch (const std::runtime_error&) {
      failed = 1;
    }
    res.factor_seconds += since(t1);
    if (!failed && !std::ranges::all_of(own, [](double v) { return std::isfinite(v); })) failed = 1;
    if (parallel::max_over_ranks(failed)) return {};
    res.residual = report.residual;
    std::array<std::vector<double>, 3> z;
    for (auto& a : z) a.assign(body.size(), 0.0);
    for (long r = 0; r < N; ++r)
      if (owns_real(r))
        for (long c = 0; c < 3; ++c) z[std::size_t(c)][b.real[std::size_t(r)]] = own[std::size_t(unknown(r, c) - first)];
    const std::array<double*, 3> arrays{z[0].data(), z[1].data(), z[2].data()};
    halo->exchange(arrays);
    Eigen::VectorXd x(3 * N);
    for (long r = 0; r < N; ++r)
      for (long c = 0; c < 3; ++c) x[c * N + r] = z[std::size_t(c)][b.real[std::size_t(r)]];
    res.multipliers.assign(row_scale.size(), 0);
    for (std::size_t q = 0; q < row_scale.size(); ++q) res.multipliers[q] = own[std::size_t(3 * mine) + q] * row_scale[q];
    return x;
  }

  // The bonds chosen after the previous solve, both directions, wherever this body holds them.
  void remove_pending() {
    if (pending.empty()) return;
    auto& intact = body.bonds.intact;
    const auto& bl = body.bonds;
    for (const auto& [gi, gj] : pending) {
      for (const auto& [from, to] : {std::pair{gi, gj}, std::pair{gj, gi}}) {
        const auto a = local_of(from);
        if (a < 0) continue;
        for (auto k = bl.begin(std::size_t(a)); k < bl.end(std::size_t(a)); ++k)
          if (id_of(std::size_t(bl.neighbor[k])) == to) intact[k] = 0;
      }
      ++res.broken;
    }
    pending.clear();
    if (opt.progress) opt.progress(res.solves, res.broken);
  }

  Body& body;
  const Osb& model;
  OsbStaticProblem prob;
  OsbStaticOptions opt;
  const OsbParts* parts = nullptr;
  Box b;
  std::vector<Side> sides;            // the whole rectangle's (on a part: those next to a held real node)
  std::vector<std::size_t> side_id;   // per side: its index among the whole rectangle's
  std::vector<std::size_t> reported;  // the sides the result reports (on a part: the owned ones)
  std::size_t all_side_count = 0;
  std::vector<std::uint8_t> owned_rows;  // per real index, on a part: whether this rank assembles its rows
  long N = 0;
  Eigen::VectorXd f;                                  // right-hand side of equilibrium (47)
  std::vector<std::tuple<long, int, double>> pinned;  // uncorrected Dirichlet rows: (real index, component, value)
  OsbStaticResult res;
  std::vector<std::pair<std::int64_t, std::int64_t>> pending;  // bonds to remove before the next solve, by their ends' one-rank ids
  std::vector<std::pair<std::int64_t, double>> ext;
  UmfpackSolves umfpack;
  BandedSolves banded;
  std::vector<std::array<double, 2>> place;  // per unknown of the whole system: unknown_places
  std::optional<parallel::Halo> halo;
  parallel::KspReport report;
  bool finished = false;
};

OsbStaticSolver::OsbStaticSolver(Body& body, const Osb& model, const OsbStaticProblem& problem, const OsbStaticOptions& options, const OsbParts* parts)
    : impl_(std::make_unique<Impl>(body, model, problem, options, parts)) {}
OsbStaticSolver::OsbStaticSolver(OsbStaticSolver&&) noexcept = default;
OsbStaticSolver& OsbStaticSolver::operator=(OsbStaticSolver&&) noexcept = default;
OsbStaticSolver::~OsbStaticSolver() = default;
bool OsbStaticSolver::done() const { return impl_->finished; }
void OsbStaticSolver::advance() {
  if (!impl_->finished) impl_->advance();
}
const OsbStaticResult& OsbStaticSolver::result() const { return impl_->res; }
const parallel::Halo* OsbStaticSolver::halo() const { return impl_->halo ? &*impl_->halo : nullptr; }

OsbStaticResult solve_osb_static(Body& body, const Osb& model, const OsbStaticProblem& prob, const OsbStaticOptions& opt) {
  OsbStaticSolver solver(body, model, prob, opt);
  while (!solver.done()) solver.advance();
  return solver.result();
}

}  // namespace peridot
