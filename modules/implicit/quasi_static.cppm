module;
#include <Eigen/CholmodSupport>
#include <Eigen/SVD>
#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCore>
#include <Eigen/UmfPackSupport>
#include <ceres/ceres.h>
export module peridot.implicit:quasi_static;
import peridot.std;
import peridot.models;
import peridot.solvers;
import peridot.parallel;
import :replicated_solve;
import :newton_rows;

export namespace peridot {

// A force model that also gives its tangent dL/du on the bond pattern (Newton needs it).
template <class M>
concept TangentModel = ForceModel<M> && requires(const M& m, const Body& b, const VectorField& u, TangentBlocks& K) {
  { m.tangent(b, u, K) };
  { m.damage(b, u, std::declval<std::vector<double>&>()) };
  { m.softening_bonds(b, u) } -> std::convertible_to<std::size_t>;
};

// automatic: sparse Cholesky (CHOLMOD) on -K while it is symmetric positive definite, LU
// (UMFPACK) once softening makes it indefinite; cg: conjugate gradients with incomplete
// Cholesky, for -K SPD only; petsc: PETSc's KSP on every MPI rank (LU by MUMPS for small
// systems, GMRES with BoomerAMG and an LU fallback above; QuasiStaticOptions::petsc), each rank
// handing over its block of rows of the same replicated -K.
enum class QsLinearSolver { automatic, cholmod, umfpack, cg, petsc };

// newton: Algs. 1-4 with the explicit tangent; ceres: the same equilibrium R(u) = L(u) + b = 0
// posed as least squares min |R|^2 / 2 and solved by Ceres' Levenberg-Marquardt with the
// analytic Jacobian (the same tangent blocks) and a sparse Cholesky of the normal equations.
enum class QsNonlinear { newton, ceres };

// analytic: the model's explicit tangent; finite_difference: central differences of the force,
// eq. (36), two force passes per unknown (the comparison method of seed 002 Sec. 6.1).
enum class QsTangent { analytic, finite_difference };

// load: the load factor lambda steps from 0 to 1 (load control; Newton fails at a limit point of
// the load path). arc_length: lambda becomes an unknown beside u and each step moves a set
// distance along the equilibrium path (Crisfield's spherical arc length over the free
// displacements and lambda times the prescribed ones), so the path can pass a limit point and
// come back: lambda may fall while a crack grows, until it rises to 1 again.
enum class QsControl { load, arc_length };

struct QuasiStaticOptions {
  std::size_t steps = 10;          // load steps from 0 to the full load
  double tolerance = 1e-10;        // Newton stops at |R| <= tolerance * reference force
  int max_iterations = 15;         // per load increment (a failing increment costs this many solves before it is cut)
  bool line_search = true;         // backtracking on |R|; off reproduces plain Newton
  double min_increment = 1e-4;     // smallest load increment, as a fraction of the full load
  QsLinearSolver linear_solver = QsLinearSolver::automatic;
  parallel::KspOptions petsc;      // linear_solver = petsc: defaults, deck and command-line options
  QsNonlinear nonlinear = QsNonlinear::newton;
  QsTangent tangent = QsTangent::analytic;
  QsControl control = QsControl::load;
  bool condition_number = false;   // dense SVD of the reduced -K per converged step (small systems)
};

// Limits on the unknowns (free displacement components) of the two costly options.
// condition_number: a dense SVD, 8 n^2 bytes (128 MB) and O(n^3) flops (about a minute) at the limit.
constexpr std::size_t condition_number_max_unknowns = 4000;
// finite_difference: two force passes per unknown per tangent.
constexpr std::size_t finite_difference_max_unknowns = 20000;
// nonlinear = ceres: up to this many unknowns the normal equations are solved dense.
constexpr std::size_t ceres_dense_max_unknowns = 600;
// control = arc_length: a path that has not reached the full load after this many times `steps`
// converged arcs is reported as a load-path failure (it may circle a snap-back for ever).
constexpr std::size_t arc_length_max_steps_per_load_step = 100;

// The components fixed by displacement boundaries, fixed[d * i + k].
std::vector<std::uint8_t> fixed_components(const Body& body, const std::vector<Boundary>& bcs);
// The free components of the points `owned` (a rank's unknowns on N ranks).
std::uint64_t free_components(const std::vector<std::uint8_t>& fixed, std::span<const std::int64_t> owned, int dim);
// Throws std::invalid_argument naming the deck key when an option's unknown limit is exceeded:
// checked before a run writes anything, and again by the solver.
void check_quasi_static_size(std::size_t unknowns, const QuasiStaticOptions& o);

// The load path cannot go on: an increment did not converge down to the smallest increment. On
// N ranks every rank decides it from the same reduced residuals, so all throw it together.
struct LoadPathFailure : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// One converged load increment.
struct LoadStepReport {
  std::size_t step = 0;            // converged increments so far
  double load = 0;                 // load factor in (0, 1]
  int iterations = 0;              // Newton iterations (linear solves)
  double residual0 = 0, residual = 0;  // |R| at the start and at convergence [N/m^3 (x sqrt m^d)]
  double reference = 0;            // the force scale the tolerance is relative to
  double max_damage = 0;           // max_i d_i (> 1: softening)
  std::size_t softening_bonds = 0; // directed bonds past the inflection point
  std::size_t cuts = 0;            // increments halved before this one converged
  double condition = NAN;          // cond_2 of the reduced -K at the converged state, when asked
  std::string linear_solver;       // which factorisation or iteration ran last
  double seconds = 0;
};

// The Newton system on the free degrees of freedom: the sparsity pattern of the bond list,
// built once; each assembly refills the values only.
class NewtonSystem {
 public:
  NewtonSystem(const Body& body, const std::vector<std::uint8_t>& fixed);  // fixed[d * i + k]
  ~NewtonSystem();
  NewtonSystem(NewtonSystem&&) noexcept;
  std::size_t unknowns() const { return std::size_t(free_.size()); }
  // Writes -K (from the model's blocks) into the matrix.
  void assemble(const TangentBlocks& K);
  // Solves (-K) dx = rhs; nullopt when the factorisation fails. `used` names the solver.
  // petsc: collective, with these options.
  std::optional<Eigen::VectorXd> solve(const Eigen::VectorXd& rhs, QsLinearSolver choice, std::string& used,
                                       const parallel::KspOptions& petsc = {});
  // The same for each column of rhs, from one factorisation (one KSP solve per column on petsc).
  std::optional<Eigen::MatrixXd> solve_columns(const Eigen::MatrixXd& rhs, QsLinearSolver choice, std::string& used,
                                               const parallel::KspOptions& petsc = {});
  // Full DOF index of free unknown k, and the reverse (-1 for fixed).
  const std::vector<std::int64_t>& free_dofs() const { return free_; }
  const std::vector<std::int64_t>& unknown_of() const { return unknown_; }
  const Eigen::SparseMatrix<double, Eigen::ColMajor, long>& matrix() const { return A_; }
  // 2-norm condition number of the assembled -K by a dense SVD (small systems only: studies).
  double condition_number() const;

 private:
  int dim_;
  std::vector<std::int64_t> free_, unknown_;
  Eigen::SparseMatrix<double, Eigen::ColMajor, long> A_;
  std::vector<long> diag_slot_, bond_slot_;  // value index per block entry; -1: a fixed row or column
  bool symmetric_ = true;                    // w_ij = w_ji on every bond: -K is symmetric
  // Factorisations keep their symbolic analysis: the pattern never changes.
  struct Factorisations;
  std::unique_ptr<Factorisations> f_;
};

// Quasi-static load control (Diehl & Lipton, Algs. 1-4): the load factor lambda goes from 0
// to 1 in `steps` increments; body forces (soft loading) are value * lambda, prescribed
// displacements (hard loading, clamps with value 0) are value * lambda. Each increment is a
// Newton iteration on the free DOFs with the model's tangent; a failed increment (no
// convergence, singular factorisation, non-finite residual) is halved down to min_increment.
//
// With `parts` the body is one rank's part of a distributed body (bond-based: ghosts hold no
// row): the rank assembles the rows of its owned points' free components (NewtonRows) and
// PETSc solves for them (linear_solver petsc, Newton only). Ghost displacements are refreshed
// before each force pass. Norms are exact sums over the owned points, reduced over the ranks,
// so every rank takes the same line-search steps, stops and cuts; boundaries hold owned points.
// The caller checks the options' limits (check_quasi_static_size) on the whole body's unknowns.
template <TangentModel Model>
class QuasiStaticSolver {
 public:
  QuasiStaticSolver(Body& body, Model model, std::vector<Boundary> boundaries, QuasiStaticOptions options, BodyParts parts = {});
  // Runs the whole load path from u (updated in place); on_step sees each converged increment.
  // Throws std::runtime_error naming the load and step when an increment cannot converge.
  std::vector<LoadStepReport> run(VectorField& u, const std::function<void(const LoadStepReport&, const VectorField&)>& on_step = {});
  // The same, one converged increment at a time (a run loop drives it): advance() takes u from
  // the last converged load to the next, halving the increment as needed.
  bool done() const { return lambda_ >= 1 - 1e-12; }
  LoadStepReport advance(VectorField& u);
  const Model& model() const { return model_; }
  // The whole body's system (one process only).
  const NewtonSystem& system() const { return *system_; }

 private:
  std::vector<std::uint8_t> fixed_mask() const;
  // parts: the rows of this rank's owned free components, numbered over the ranks.
  NewtonRows owned_rows(const std::vector<std::uint8_t>& fixed);
  std::optional<Eigen::VectorXd> solve(const Eigen::VectorXd& rhs, std::string& used);
  std::optional<Eigen::MatrixXd> solve_columns(const Eigen::MatrixXd& rhs, std::string& used);
  // Sums over the owned points (or the whole body), over the ranks: the same on every rank.
  double total(ExactSum s) const;
  double norm_of(const Eigen::VectorXd& v) const;
  double dot(const Eigen::VectorXd& a, const Eigen::VectorXd& b) const;
  double reference_force() const;  // after residual(): the load's or the reactions' norm, whichever is larger
  LoadStepReport advance_load(VectorField& u);
  LoadStepReport advance_arc(VectorField& u);
  bool arc_iterations(VectorField& u, LoadStepReport& rep, Eigen::VectorXd& du, double& dlambda, double& r);
  // At u (R_ its residual): the tangent's solves for R_ and for dR/dlambda, one factorisation.
  std::optional<Eigen::MatrixXd> arc_solve(const VectorField& u, LoadStepReport& rep);
  // dR/dlambda on the free rows at the tangent in K_: K times the prescribed displacements of
  // the full load, plus the full load's body forces.
  Eigen::VectorXd load_direction();
  // u = base + scale du on the free components.
  void set_free(VectorField& u, const VectorField& base, const Eigen::VectorXd& du, double scale = 1) const;
  LoadStepReport converged_report(const VectorField& u, LoadStepReport rep, std::size_t cuts, double r, double reference,
                                  std::chrono::steady_clock::time_point t0);
  bool newton_increment(VectorField& u, LoadStepReport& rep, double reference, Eigen::VectorXd& R, double& r);
  bool ceres_increment(VectorField& u, LoadStepReport& rep, double reference, Eigen::VectorXd& R, double& r);
  void tangent(const VectorField& u);  // into K_, analytic or by finite differences
  void assemble_tangent(const VectorField& u);  // tangent(u), then -K into the system or this rank's rows
  std::vector<std::int64_t> reverse_;  // reverse_[b]: the bond j -> i of bond b = i -> j
  void apply_loads(double lambda, VectorField& u);
  double residual(VectorField& u, Eigen::VectorXd& R);  // R on free DOFs = L(u) + b; returns |R| (parts: refreshes u's ghosts)

  Body& body_;
  Model model_;
  std::vector<Boundary> bcs_;
  QuasiStaticOptions o_;
  VectorField b_, f_;
  BodyParts parts_;
  std::optional<NewtonSystem> system_;  // one process
  std::optional<NewtonRows> rows_;      // one part of N
  std::vector<std::int64_t> free_;      // the DOF d * i + k of each unknown (parts: of each owned row)
  TangentBlocks K_;
  // Where the load path stands between advances.
  double lambda_ = 0, increment_ = 0;
  std::size_t converged_ = 0;
  bool softening_ = false;  // the last converged increment had bonds past the inflection point
  Eigen::VectorXd R_;
  std::vector<double> dmg_;
  VectorField previous_;
  // Arc length: the full load's prescribed displacements (ghosts included) and body forces, the
  // squared norm of the former over the fixed components (the constraint's weight on lambda),
  // the arc's length and its first (largest) value, and the last converged arc.
  VectorField full_u_, full_b_;
  double full_u2_ = 0, arc_ = 0, arc_max_ = 0, last_dlambda_ = 0, peak_lambda_ = 0;
  Eigen::VectorXd last_du_;
};

}  // namespace peridot

namespace peridot {

namespace {
using SpMat = Eigen::SparseMatrix<double, Eigen::ColMajor, long>;
}

struct NewtonSystem::Factorisations {
  Eigen::CholmodSupernodalLLT<SpMat> llt;
  Eigen::UmfPackLU<SpMat> lu;
  bool llt_analysed = false, lu_analysed = false;
  // Factorisations left that go straight to LU: Cholesky found -K indefinite lately. Softening
  // seldom heals within a few iterations, and a failed Cholesky costs up to a whole one
  // (0.3-0.6 s of a 1.2 s iteration on the hard-loaded plate).
  int skip_llt = 0;
};

NewtonSystem::~NewtonSystem() = default;
NewtonSystem::NewtonSystem(NewtonSystem&&) noexcept = default;

NewtonSystem::NewtonSystem(const Body& body, const std::vector<std::uint8_t>& fixed) : dim_(body.dim()) {
  const std::size_t n = body.size(), d = std::size_t(dim_);
  unknown_.assign(n * d, -1);
  for (std::size_t q = 0; q < n * d; ++q)
    if (!fixed[q]) unknown_[q] = std::int64_t(free_.size()), free_.push_back(std::int64_t(q));
  const auto& bl = body.bonds;
  // Pattern: slot ids as values, so the value index of each block entry can be found once.
  std::vector<Eigen::Triplet<double, long>> t;
  t.reserve((n + bl.size()) * d * d);
  long slot = 0;
  const auto add = [&](std::size_t row_point, std::size_t col_point, std::vector<long>& slots) {
    for (std::size_t r = 0; r < d; ++r)
      for (std::size_t c = 0; c < d; ++c) {
        const auto ur = unknown_[row_point * d + r], uc = unknown_[col_point * d + c];
        if (ur >= 0 && uc >= 0) {
          t.emplace_back(ur, uc, double(++slot));
          slots.push_back(slot);
        } else slots.push_back(0);
      }
  };
  for (std::size_t i = 0; i < n; ++i) add(i, i, diag_slot_);
  for (std::size_t i = 0; i < n; ++i)
    for (auto b = bl.offset[i]; b < bl.offset[i + 1]; ++b) add(i, std::size_t(bl.neighbor[b]), bond_slot_);
  A_.resize(long(free_.size()), long(free_.size()));
  A_.setFromTriplets(t.begin(), t.end());
  A_.makeCompressed();
  std::vector<long> where(std::size_t(slot) + 1, -1);
  for (long k = 0; k < A_.nonZeros(); ++k) where[std::size_t(A_.valuePtr()[k])] = k;
  for (auto& s : diag_slot_) s = s ? where[std::size_t(s)] : -1;
  for (auto& s : bond_slot_) s = s ? where[std::size_t(s)] : -1;
  // The tangent blocks A_ij and A_ji differ only through the weights w_ij and w_ji.
  for (std::size_t i = 0; i < n && symmetric_; ++i)
    for (auto b = bl.offset[i]; b < bl.offset[i + 1]; ++b) {
      const auto j = std::size_t(bl.neighbor[b]);
      const auto first = bl.neighbor.begin() + bl.offset[j], last = bl.neighbor.begin() + bl.offset[j + 1];
      const auto it = std::lower_bound(first, last, std::int32_t(i));
      if (it == last || *it != std::int32_t(i) || bl.weight[std::size_t(it - bl.neighbor.begin())] != bl.weight[b]) {
        symmetric_ = false;
        break;
      }
    }
  f_ = std::make_unique<Factorisations>();
  f_->llt.cholmod().print = 0;  // an indefinite matrix is an expected outcome here, not a warning to print
}

void NewtonSystem::assemble(const TangentBlocks& K) {
  double* v = A_.valuePtr();
  const auto nnz = std::size_t(A_.nonZeros());
  std::fill(v, v + nnz, 0.0);
  for (std::size_t k = 0; k < diag_slot_.size(); ++k)
    if (diag_slot_[k] >= 0) v[diag_slot_[k]] = -K.diagonal[k];
  for (std::size_t k = 0; k < bond_slot_.size(); ++k)
    if (bond_slot_[k] >= 0) v[bond_slot_[k]] -= K.bond[k];
}

std::vector<std::uint8_t> fixed_components(const Body& body, const std::vector<Boundary>& bcs) {
  const int d = body.dim();
  std::vector<std::uint8_t> fixed(body.size() * std::size_t(d), 0);
  for (const auto& bc : bcs)
    if (bc.kind == BoundaryKind::displacement)
      for (auto i : bc.points)
        for (int k = 0; k < d; ++k)
          if (bc.components[k]) fixed[std::size_t(i) * std::size_t(d) + std::size_t(k)] = 1;
  return fixed;
}

std::uint64_t free_components(const std::vector<std::uint8_t>& fixed, std::span<const std::int64_t> owned, int dim) {
  std::uint64_t free = 0;
  for (auto p : owned)
    for (int k = 0; k < dim; ++k) free += !fixed[std::size_t(p) * std::size_t(dim) + std::size_t(k)];
  return free;
}

void check_quasi_static_size(std::size_t unknowns, const QuasiStaticOptions& o) {
  if (o.condition_number && unknowns > condition_number_max_unknowns)
    throw std::invalid_argument(fmt::format("output.condition_number = true needs a dense SVD of the tangent; {} unknowns is more "
                                            "than the {} allowed (a coarser deck, or drop the key)",
                                            unknowns, condition_number_max_unknowns));
  if (o.tangent == QsTangent::finite_difference && unknowns > finite_difference_max_unknowns)
    throw std::invalid_argument(fmt::format("solver.tangent = 'finite_difference' costs two force passes per unknown; {} unknowns "
                                            "is more than the {} allowed (use analytic)",
                                            unknowns, finite_difference_max_unknowns));
}

double NewtonSystem::condition_number() const {
  if (std::size_t(A_.rows()) > condition_number_max_unknowns)
    throw std::invalid_argument(fmt::format("condition_number: dense SVD refused above {} unknowns", condition_number_max_unknowns));
  return dense_condition_number(Eigen::MatrixXd(A_));
}

std::optional<Eigen::VectorXd> NewtonSystem::solve(const Eigen::VectorXd& rhs, QsLinearSolver choice, std::string& used,
                                                   const parallel::KspOptions& petsc) {
  auto x = solve_columns(rhs, choice, used, petsc);
  if (!x) return std::nullopt;
  return Eigen::VectorXd(x->col(0));
}

std::optional<Eigen::MatrixXd> NewtonSystem::solve_columns(const Eigen::MatrixXd& rhs, QsLinearSolver choice, std::string& used,
                                                           const parallel::KspOptions& petsc) {
  if (choice == QsLinearSolver::petsc) {
    Eigen::MatrixXd out(rhs.rows(), rhs.cols());
    for (Eigen::Index c = 0; c < rhs.cols(); ++c) {
      parallel::KspReport report;
      std::vector<double> x;
      try {
        x = solve_on_ranks(A_, rhs.col(c), petsc, &report);
      } catch (const std::runtime_error& e) {
        // Every rank holds the same system and fails alike: the increment is cut on all of them.
        used = fmt::format("petsc failed: {}", e.what());
        return std::nullopt;
      }
      used = describe_petsc_solve(report);
      out.col(c) = Eigen::Map<const Eigen::VectorXd>(x.data(), Eigen::Index(x.size()));
    }
    if (!out.allFinite()) return std::nullopt;
    return out;
  }
  bool try_llt = symmetric_ && (choice == QsLinearSolver::automatic || choice == QsLinearSolver::cholmod);
  if (try_llt && choice == QsLinearSolver::automatic && f_->skip_llt > 0) --f_->skip_llt, try_llt = false;
  if (try_llt) {
    auto& llt = f_->llt;
    if (!f_->llt_analysed) llt.analyzePattern(A_), f_->llt_analysed = true;
    llt.factorize(A_);
    if (llt.info() == Eigen::Success) {
      used = "cholmod";
      Eigen::MatrixXd x = llt.solve(rhs);
      if (x.allFinite()) return x;
    }
    if (choice == QsLinearSolver::cholmod) return std::nullopt;  // not SPD: the user asked for Cholesky only
    f_->skip_llt = 8;
  }
  if (choice == QsLinearSolver::cg) {
    if (!symmetric_) return std::nullopt;
    Eigen::ConjugateGradient<SpMat, Eigen::Lower | Eigen::Upper, Eigen::IncompleteCholesky<double, Eigen::Lower, Eigen::AMDOrdering<long>>> cg;
    cg.setTolerance(1e-12);
    cg.setMaxIterations(int(10 * rhs.rows() + 100));
    cg.compute(A_);
    Eigen::MatrixXd x(rhs.rows(), rhs.cols());
    for (Eigen::Index c = 0; c < rhs.cols(); ++c) {
      x.col(c) = cg.solve(rhs.col(c));
      used = fmt::format("cg ({} iterations)", cg.iterations());
      if (cg.info() != Eigen::Success) return std::nullopt;
    }
    if (!x.allFinite()) return std::nullopt;
    return x;
  }
  auto& lu = f_->lu;
  if (!f_->lu_analysed) lu.analyzePattern(A_), f_->lu_analysed = true;
  lu.factorize(A_);
  used = "umfpack";
  if (lu.info() != Eigen::Success) return std::nullopt;
  Eigen::MatrixXd x = lu.solve(rhs);
  if (!x.allFinite()) return std::nullopt;
  return x;
}

}  // namespace peridot

// Template members: in the interface, so each model instantiates them.
namespace peridot {

template <TangentModel Model>
QuasiStaticSolver<Model>::QuasiStaticSolver(Body& body, Model model, std::vector<Boundary> bcs, QuasiStaticOptions o, BodyParts parts)
    : body_(body), model_(std::move(model)), bcs_(std::move(bcs)), o_(o), b_(zero_field(body.size())), f_(zero_field(body.size())),
      parts_(std::move(parts)) {
  if (o_.steps == 0) throw std::invalid_argument("quasi-static: steps must be >= 1");
  if (parts_.parted()) {
    if (o_.linear_solver != QsLinearSolver::petsc || o_.nonlinear != QsNonlinear::newton || o_.tangent != QsTangent::analytic)
      throw std::invalid_argument("quasi-static on N ranks: Newton with the analytic tangent on PETSc only (no Ceres or finite-difference "
                                  "tangent)");
    rows_.emplace(owned_rows(fixed_mask()));
    free_ = rows_->row_dofs();
  } else {
    system_.emplace(body, fixed_mask());
    free_ = system_->free_dofs();
    check_quasi_static_size(system_->unknowns(), o_);
  }
  if (o_.tangent == QsTangent::finite_difference) {
    const auto& bl = body_.bonds;
    reverse_.resize(bl.size());
    for (std::size_t i = 0; i < body_.size(); ++i)
      for (auto b = bl.offset[i]; b < bl.offset[i + 1]; ++b) {
        const auto j = std::size_t(bl.neighbor[b]);
        const auto first = bl.neighbor.begin() + bl.offset[j], last = bl.neighbor.begin() + bl.offset[j + 1];
        reverse_[std::size_t(b)] = std::int64_t(std::lower_bound(first, last, std::int32_t(i)) - bl.neighbor.begin());
      }
  }
  for (const auto& bc : bcs_)
    if (bc.kind == BoundaryKind::velocity)
      throw std::invalid_argument(fmt::format("boundary '{}': a quasi-static run has no velocities (use displacement)", bc.name));
}

template <TangentModel Model>
std::vector<std::uint8_t> QuasiStaticSolver<Model>::fixed_mask() const {
  return fixed_components(body_, bcs_);
}

template <TangentModel Model>
NewtonRows QuasiStaticSolver<Model>::owned_rows(const std::vector<std::uint8_t>& fixed) {
  const int d = body_.dim();
  const auto counts = parallel::all_gather(free_components(fixed, parts_.owned, d));
  std::int64_t first = 0, global = 0;
  for (std::size_t r = 0; r < counts.size(); ++r) {
    if (int(r) < parallel::rank()) first += std::int64_t(counts[r]);
    global += std::int64_t(counts[r]);
  }
  // Owners number their free components; ghosts learn theirs (fixed: -1) through the halo.
  VectorField number = zero_field(body_.size());
  std::int64_t next = first;
  for (auto p : parts_.owned)
    for (int k = 0; k < d; ++k) {
      const auto q = std::size_t(p) * std::size_t(d) + std::size_t(k);
      number[std::size_t(k)][std::size_t(p)] = fixed[q] ? -1.0 : double(next++);
    }
  parts_.refresh(number);
  std::vector<std::int64_t> unknown(body_.size() * std::size_t(d));
  for (std::size_t i = 0; i < body_.size(); ++i)
    for (int k = 0; k < d; ++k) unknown[i * std::size_t(d) + std::size_t(k)] = std::int64_t(number[std::size_t(k)][i]);
  return NewtonRows(body_, parts_.owned, unknown, global, first);
}

template <TangentModel Model>
std::optional<Eigen::VectorXd> QuasiStaticSolver<Model>::solve(const Eigen::VectorXd& rhs, std::string& used) {
  if (rows_) return rows_->solve(rhs, o_.petsc, used);
  return system_->solve(rhs, o_.linear_solver, used, o_.petsc);
}

template <TangentModel Model>
std::optional<Eigen::MatrixXd> QuasiStaticSolver<Model>::solve_columns(const Eigen::MatrixXd& rhs, std::string& used) {
  if (!rows_) return system_->solve_columns(rhs, o_.linear_solver, used, o_.petsc);
  Eigen::MatrixXd out(rhs.rows(), rhs.cols());
  for (Eigen::Index c = 0; c < rhs.cols(); ++c) {
    auto x = rows_->solve(rhs.col(c), o_.petsc, used);
    if (!x) return std::nullopt;
    out.col(c) = *x;
  }
  return out;
}

template <TangentModel Model>
double QuasiStaticSolver<Model>::total(ExactSum s) const {
  if (parts_.reduce) parts_.reduce(s);
  return s.value();
}

template <TangentModel Model>
double QuasiStaticSolver<Model>::norm_of(const Eigen::VectorXd& v) const {
  if (!parts_.parted()) return v.allFinite() ? v.norm() : INFINITY;
  ExactSum s;
  for (double x : v) s += x * x;
  const double n = std::sqrt(total(s));
  return std::isfinite(n) ? n : INFINITY;
}

template <TangentModel Model>
double QuasiStaticSolver<Model>::dot(const Eigen::VectorXd& a, const Eigen::VectorXd& b) const {
  if (!parts_.parted()) return a.dot(b);
  ExactSum s;
  for (Eigen::Index k = 0; k < a.size(); ++k) s += a[k] * b[k];
  return total(s);
}

template <TangentModel Model>
double QuasiStaticSolver<Model>::reference_force() const {
  const auto d = std::size_t(body_.dim());
  if (parts_.parted()) {
    ExactSum load, all;
    for (auto p : parts_.owned)
      for (std::size_t k = 0; k < d; ++k) {
        load += b_[k][std::size_t(p)] * b_[k][std::size_t(p)];
        all += f_[k][std::size_t(p)] * f_[k][std::size_t(p)];
      }
    return std::max(std::sqrt(total(load)), std::sqrt(total(all)));
  }
  double load = 0, all = 0;
  for (const auto& c : b_)
    for (double v : c) load += v * v;
  for (std::size_t k = 0; k < d; ++k)
    for (double v : f_[k]) all += v * v;
  return std::max(std::sqrt(load), std::sqrt(all));
}

template <TangentModel Model>
void QuasiStaticSolver<Model>::set_free(VectorField& u, const VectorField& base, const Eigen::VectorXd& du, double scale) const {
  const auto d = std::size_t(body_.dim());
  for (std::size_t k = 0; k < free_.size(); ++k) {
    const auto q = std::size_t(free_[k]);
    u[q % d][q / d] = base[q % d][q / d] + scale * du[long(k)];
  }
}

template <TangentModel Model>
Eigen::VectorXd QuasiStaticSolver<Model>::load_direction() {
  const int d = body_.dim();
  const auto bs = std::size_t(d * d);
  const auto& bl = body_.bonds;
  Eigen::VectorXd q(long(free_.size()));
  for (std::size_t k = 0; k < free_.size(); ++k) {
    const auto i = std::size_t(free_[k]) / std::size_t(d);
    const auto r = int(std::size_t(free_[k]) % std::size_t(d));
    // Free components of full_u_ are zero: only the prescribed ones enter the product.
    double v = full_b_[std::size_t(r)][i];
    for (int c = 0; c < d; ++c) v += K_.diagonal[i * bs + std::size_t(r * d + c)] * full_u_[std::size_t(c)][i];
    for (auto b = bl.offset[i]; b < bl.offset[i + 1]; ++b) {
      const auto j = std::size_t(bl.neighbor[b]);
      for (int c = 0; c < d; ++c) v += K_.bond[std::size_t(b) * bs + std::size_t(r * d + c)] * full_u_[std::size_t(c)][j];
    }
    q[long(k)] = v;
  }
  return q;
}

template <TangentModel Model>
void QuasiStaticSolver<Model>::apply_loads(double lambda, VectorField& u) {
  for (auto& c : b_) std::fill(c.begin(), c.end(), 0.0);
  for (const auto& bc : bcs_)
    for (auto i : bc.points)
      for (int k = 0; k < body_.dim(); ++k) {
        if (bc.kind == BoundaryKind::body_force) b_[k][i] += lambda * bc.value[k];
        else if (bc.components[k]) u[k][i] = lambda * bc.value[k];
      }
}

template <TangentModel Model>
double QuasiStaticSolver<Model>::residual(VectorField& u, Eigen::VectorXd& R) {
  // The ghosts read by the owned rows' bonds take their owners' displacements.
  parts_.refresh(u);
  model_.forces(body_, u, f_);
  const auto& free = free_;
  const auto d = std::size_t(body_.dim());
  R.resize(long(free.size()));
  for (std::size_t k = 0; k < free.size(); ++k) {
    const auto q = std::size_t(free[k]);
    R[long(k)] = f_[q % d][q / d] + b_[q % d][q / d];
  }
  return norm_of(R);
}

template <TangentModel Model>
void QuasiStaticSolver<Model>::tangent(const VectorField& u) {
  if (o_.tangent == QsTangent::analytic) return model_.tangent(body_, u, K_);
  const int d = body_.dim();
  const auto n = body_.size(), bs = std::size_t(d * d);
  const auto& bl = body_.bonds;
  K_.dim = d;
  K_.diagonal.assign(n * bs, 0.0);
  K_.bond.assign(bl.size() * bs, 0.0);
  double scale = body_.points.spacing * 1e-3;
  for (int k = 0; k < d; ++k)
    for (double v : u[std::size_t(k)]) scale = std::max(scale, std::abs(v));
  const double tau = 1e-6 * scale;
  VectorField up = u, fp = zero_field(n), fm = zero_field(n);
  // Column (j, c): the force of j itself and of every partner i of j responds.
  for (std::size_t j = 0; j < n; ++j)
    for (int c = 0; c < d; ++c) {
      up[c][j] = u[c][j] + tau;
      model_.forces(body_, up, fp);
      up[c][j] = u[c][j] - tau;
      model_.forces(body_, up, fm);
      up[c][j] = u[c][j];
      for (int r = 0; r < d; ++r) K_.diagonal[j * bs + std::size_t(r * d + c)] = (fp[r][j] - fm[r][j]) / (2 * tau);
      for (auto b = bl.offset[j]; b < bl.offset[j + 1]; ++b) {
        const auto i = std::size_t(bl.neighbor[b]);
        for (int r = 0; r < d; ++r) K_.bond[std::size_t(reverse_[std::size_t(b)]) * bs + std::size_t(r * d + c)] = (fp[r][i] - fm[r][i]) / (2 * tau);
      }
    }
}

template <TangentModel Model>
void QuasiStaticSolver<Model>::assemble_tangent(const VectorField& u) {
  tangent(u);
  if (rows_) rows_->assemble(K_);
  else system_->assemble(K_);
}

template <TangentModel Model>
bool QuasiStaticSolver<Model>::newton_increment(VectorField& u, LoadStepReport& rep, double reference, Eigen::VectorXd& R, double& r) {
  const auto d = std::size_t(body_.dim());
  const auto& free = free_;
  Eigen::VectorXd trial_R;
  bool converged = false;
  while (!converged) {
    if (rep.iterations >= o_.max_iterations) return false;
    assemble_tangent(u);
    auto dx = solve(R, rep.linear_solver);
    ++rep.iterations;
    if (!dx) return false;
    // Backtracking: accept the first step length that lowers |R| enough, else the best.
    double alpha = 1, best_alpha = 1, best = INFINITY;
    const VectorField base = u;
    for (int tries = 0; tries < (o_.line_search ? 6 : 1); ++tries, alpha *= 0.5) {
      set_free(u, base, *dx, alpha);
      const double rt = residual(u, trial_R);
      if (rt < best) best = rt, best_alpha = alpha;
      if (rt <= (1 - 1e-4 * alpha) * r) break;
    }
    if (best_alpha != alpha || !o_.line_search) set_free(u, base, *dx, best_alpha);
    const double step_norm = best_alpha * norm_of(*dx);
    r = residual(u, R);
    if (!std::isfinite(r)) return false;
    double unorm = 0;
    if (parts_.parted()) {
      ExactSum sum;
      for (auto q : free) sum += std::pow(u[std::size_t(q) % d][std::size_t(q) / d], 2);
      unorm = total(sum);
    } else {
      for (std::size_t k = 0; k < free.size(); ++k) unorm += std::pow(u[free[k] % d][free[k] / d], 2);
    }
    // Converged, or stalled at round-off (the update no longer changes u).
    converged = r <= o_.tolerance * reference || step_norm <= 1e-15 * std::sqrt(unorm);
  }
  return true;
}

// Ceres sees one residual block per point with a free component: R_i (d values, zero on fixed
// components), depending on the point's own parameter block and its partners'. Before each
// evaluation an EvaluationCallback runs the model once over the whole body (forces and, when
// asked, tangent blocks), so the residual blocks only copy: no formula is restated here.
template <TangentModel Model>
bool QuasiStaticSolver<Model>::ceres_increment(VectorField& u, LoadStepReport& rep, double reference, Eigen::VectorXd& R, double& r) {
  const int d = body_.dim();
  const auto n = body_.size();
  const auto& bl = body_.bonds;
  const auto& unknown = system_->unknown_of();
  std::vector<double> params(n * std::size_t(d));
  for (std::size_t i = 0; i < n; ++i)
    for (int k = 0; k < d; ++k) params[i * std::size_t(d) + std::size_t(k)] = u[k][i];

  struct Callback final : ceres::EvaluationCallback {
    QuasiStaticSolver& s;
    VectorField& u;
    const std::vector<double>& params;
    Callback(QuasiStaticSolver& solver, VectorField& field, const std::vector<double>& p) : s(solver), u(field), params(p) {}
    void PrepareForEvaluation(bool jacobians, bool new_point) override {
      const int dd = s.body_.dim();
      if (new_point)
        for (std::size_t i = 0; i < s.body_.size(); ++i)
          for (int k = 0; k < dd; ++k) u[k][i] = params[i * std::size_t(dd) + std::size_t(k)];
      s.model_.forces(s.body_, u, s.f_);
      if (jacobians) s.model_.tangent(s.body_, u, s.K_);
    }
  } callback(*this, u, params);

  struct PointResidual final : ceres::CostFunction {
    QuasiStaticSolver& s;
    std::size_t i;
    std::vector<std::uint8_t> free_row;
    PointResidual(QuasiStaticSolver& solver, std::size_t point, std::vector<std::uint8_t> rows) : s(solver), i(point), free_row(std::move(rows)) {
      const int dd = s.body_.dim();
      set_num_residuals(dd);
      mutable_parameter_block_sizes()->assign(1 + s.body_.bonds.count(i), dd);
    }
    bool Evaluate(double const* const*, double* residuals, double** jacobians) const override {
      const int dd = s.body_.dim();
      const auto bs = std::size_t(dd * dd);
      for (int r = 0; r < dd; ++r) residuals[r] = free_row[r] ? s.f_[r][i] + s.b_[r][i] : 0.0;
      if (!jacobians) return true;
      const auto& b = s.body_.bonds;
      for (std::size_t blk = 0; blk <= b.count(i); ++blk) {
        if (!jacobians[blk]) continue;
        const double* src = blk == 0 ? s.K_.diagonal.data() + i * bs : s.K_.bond.data() + std::size_t(b.offset[i] + std::int64_t(blk) - 1) * bs;
        for (int r = 0; r < dd; ++r)
          for (int c = 0; c < dd; ++c) jacobians[blk][r * dd + c] = free_row[r] ? src[r * dd + c] : 0.0;
      }
      return true;
    }
  };

  ceres::Problem::Options po;
  po.evaluation_callback = &callback;
  po.cost_function_ownership = ceres::TAKE_OWNERSHIP;
  po.manifold_ownership = ceres::TAKE_OWNERSHIP;
  ceres::Problem problem(po);
  for (std::size_t i = 0; i < n; ++i) problem.AddParameterBlock(params.data() + i * std::size_t(d), d);
  for (std::size_t i = 0; i < n; ++i) {
    std::vector<std::uint8_t> rows(static_cast<std::size_t>(d), 0);
    std::vector<int> fixed;
    for (int k = 0; k < d; ++k) {
      rows[std::size_t(k)] = unknown[i * std::size_t(d) + std::size_t(k)] >= 0;
      if (!rows[std::size_t(k)]) fixed.push_back(k);
    }
    double* own = params.data() + i * std::size_t(d);
    if (int(fixed.size()) == d) problem.SetParameterBlockConstant(own);
    else if (!fixed.empty()) problem.SetManifold(own, new ceres::SubsetManifold(d, fixed));
    if (int(fixed.size()) == d) continue;
    std::vector<double*> blocks{own};
    for (auto b = bl.offset[i]; b < bl.offset[i + 1]; ++b) blocks.push_back(params.data() + std::size_t(bl.neighbor[b]) * std::size_t(d));
    problem.AddResidualBlock(new PointResidual(*this, i, std::move(rows)), nullptr, blocks);
  }
  ceres::Solver::Options so;
  so.minimizer_type = ceres::TRUST_REGION;
  so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  // LM solves the normal equations, whose pattern J^T J reaches 2 delta; each Solve builds and
  // sorts that product's structure anew (Ceres' InnerProductComputer). A small system is
  // cheaper dense, through LAPACK (Zen 4, 2D plate, per linear solve: 480 unknowns 10 ms dense
  // against 24 sparse; 966 unknowns 91 against 65; 1,920 595 against 159).
  const bool dense = system_->unknowns() <= ceres_dense_max_unknowns;
  so.linear_solver_type = dense ? ceres::DENSE_NORMAL_CHOLESKY : ceres::SPARSE_NORMAL_CHOLESKY;
  so.dense_linear_algebra_library_type = ceres::LAPACK;
  // Start as Gauss-Newton (a huge trust region): near a solution LM's damping only slows it.
  so.initial_trust_region_radius = 1e12;
  so.max_trust_region_radius = 1e32;
  so.max_num_iterations = o_.max_iterations;
  so.function_tolerance = 1e-30;
  so.gradient_tolerance = 1e-30;
  so.parameter_tolerance = 1e-15;
  so.num_threads = 1;
  so.logging_type = ceres::SILENT;
  // Stop as Newton does: once |R| reaches the tolerance.
  struct Stop final : ceres::IterationCallback {
    double target;
    explicit Stop(double t) : target(t) {}
    ceres::CallbackReturnType operator()(const ceres::IterationSummary& it) override {
      return std::sqrt(2 * it.cost) <= target ? ceres::SOLVER_TERMINATE_SUCCESSFULLY : ceres::SOLVER_CONTINUE;
    }
  } stop(o_.tolerance * reference);
  so.callbacks.push_back(&stop);
  so.update_state_every_iteration = true;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  rep.iterations += int(summary.iterations.size() > 0 ? summary.iterations.size() - 1 : 0);
  rep.linear_solver = dense ? "ceres LM (dense normal Cholesky)" : "ceres LM (sparse normal Cholesky)";
  for (std::size_t i = 0; i < n; ++i)
    for (int k = 0; k < d; ++k) u[k][i] = params[i * std::size_t(d) + std::size_t(k)];
  r = residual(u, R);
  return std::isfinite(r) && r <= o_.tolerance * reference * (1 + 1e-9);
}

template <TangentModel Model>
std::vector<LoadStepReport> QuasiStaticSolver<Model>::run(VectorField& u,
                                                          const std::function<void(const LoadStepReport&, const VectorField&)>& on_step) {
  std::vector<LoadStepReport> reports;
  while (!done()) {
    reports.push_back(advance(u));
    if (on_step) on_step(reports.back(), u);
  }
  return reports;
}

template <TangentModel Model>
LoadStepReport QuasiStaticSolver<Model>::advance(VectorField& u) {
  return o_.control == QsControl::arc_length ? advance_arc(u) : advance_load(u);
}

template <TangentModel Model>
LoadStepReport QuasiStaticSolver<Model>::advance_load(VectorField& u) {
  const double full = 1.0 / double(o_.steps);
  if (converged_ == 0 && lambda_ == 0 && increment_ == 0) increment_ = full;
  std::size_t cuts = 0;
  const auto d = std::size_t(body_.dim());
  const auto& free = free_;
  auto& R = R_;
  while (true) {
    const auto t0 = std::chrono::steady_clock::now();
    const double target = std::min(1.0, lambda_ + increment_);
    previous_ = u;
    // While the response is elastic, start from the last solution scaled along the load path:
    // after the first step this carries prescribed displacements into the body (the spec's
    // extension of w into D). Once bonds soften the path is no longer proportional, and the
    // last solution itself is the better guess.
    if (lambda_ > 0 && !softening_)
      for (auto q : free) u[std::size_t(q) % d][std::size_t(q) / d] *= target / lambda_;
    apply_loads(target, u);
    // The force scale the tolerance refers to: the load, or for hard loading the reactions.
    double r = residual(u, R);
    const double reference = reference_force();
    LoadStepReport rep;
    rep.residual0 = r;
    bool converged = r <= o_.tolerance * reference;
    bool failed = !std::isfinite(r);
    if (!converged && !failed)
      failed = !(o_.nonlinear == QsNonlinear::ceres ? ceres_increment(u, rep, reference, R, r) : newton_increment(u, rep, reference, R, r));
    if (failed) {
      u = previous_;
      apply_loads(lambda_, u);
      increment_ *= 0.5;
      ++cuts;
      if (increment_ < o_.min_increment * 1.0000001)
        throw LoadPathFailure(fmt::format(
            "quasi-static: the load increment from {:.6g} to {:.6g} of the full load (load step {}) did not converge after {} cuts "
            "(last: {} iterations, |R| = {:.3e} against tolerance {:.3e}); the increment fell below solver.min_increment = {:g}. "
            "The structure has likely lost stability (unstable crack growth under soft loading; under hard loading, a limit point "
            "that solver.control: arc_length can pass)",
            lambda_, target, converged_ + 1, cuts, rep.iterations, r, o_.tolerance * reference, o_.min_increment));
      continue;
    }
    lambda_ = target;
    rep = converged_report(u, rep, cuts, r, reference, t0);
    // After cuts, continue with the cut increment until the next full-step mark is reached.
    const double next_mark = std::ceil(lambda_ / full - 1e-9) * full;
    if (std::abs(lambda_ - next_mark) < 1e-12) increment_ = full;
    else increment_ = std::min(increment_, next_mark - lambda_);
    return rep;
  }
}

template <TangentModel Model>
LoadStepReport QuasiStaticSolver<Model>::converged_report(const VectorField& u, LoadStepReport rep, std::size_t cuts, double r, double reference,
                                                          std::chrono::steady_clock::time_point t0) {
  model_.damage(body_, u, dmg_);
  rep.step = ++converged_;
  rep.load = lambda_;
  rep.residual = r;
  rep.reference = reference;
  rep.max_damage = 0;
  if (parts_.parted()) {
    for (auto p : parts_.owned) rep.max_damage = std::max(rep.max_damage, dmg_[std::size_t(p)]);
    rep.max_damage = -parallel::min_over_ranks(-rep.max_damage);
    // Ghost rows hold no bond: each directed bond is counted by its owner.
    std::uint64_t softening = model_.softening_bonds(body_, u);
    parallel::sum_over_ranks(softening);
    rep.softening_bonds = std::size_t(softening);
  } else {
    for (double v : dmg_) rep.max_damage = std::max(rep.max_damage, v);
    rep.softening_bonds = model_.softening_bonds(body_, u);
  }
  softening_ = rep.softening_bonds != 0;
  rep.cuts = cuts;
  if (o_.condition_number) {
    assemble_tangent(u);
    rep.condition = rows_ ? rows_->condition_number() : system_->condition_number();
  }
  rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return rep;
}

// One arc: from the converged (u, lambda) a predictor along the tangent of the path, then
// Newton corrections of u and lambda together that keep the arc's length (Crisfield 1981):
// each iteration solves the tangent for the residual and for dR/dlambda from one
// factorisation and takes the root of the constraint's quadratic nearer the last direction.
template <TangentModel Model>
LoadStepReport QuasiStaticSolver<Model>::advance_arc(VectorField& u) {
  const int d = body_.dim();
  if (converged_ == 0 && arc_ == 0) {
    // The full load's prescribed displacements and body forces, on ghosts too.
    full_u_ = zero_field(body_.size());
    full_b_ = zero_field(body_.size());
    ExactSum u2;
    for (const auto& bc : bcs_)
      for (auto i : bc.points)
        for (int k = 0; k < d; ++k) {
          if (bc.kind == BoundaryKind::body_force) full_b_[std::size_t(k)][i] += bc.value[k];
          else if (bc.components[k]) full_u_[std::size_t(k)][i] = bc.value[k];
        }
    // Counted on each point's owner (boundaries hold owned points).
    for (std::size_t i = 0; i < body_.size(); ++i)
      for (int k = 0; k < d; ++k) u2 += full_u_[std::size_t(k)][i] * full_u_[std::size_t(k)][i];
    full_u2_ = total(u2);
    parts_.refresh(full_u_);
  }
  const std::size_t limit = arc_length_max_steps_per_load_step * o_.steps;
  if (converged_ >= limit)
    throw LoadPathFailure(fmt::format("quasi-static arc length: {} converged arcs without reaching the full load (the load factor is {:.6g}); "
                                      "the path may circle a snap-back. A larger solver.steps gives longer arcs",
                                      converged_, lambda_));
  // Past a peak the path may fall back to no load (a body that comes apart under a soft load),
  // where it would never reach the full load.
  peak_lambda_ = std::max(peak_lambda_, lambda_);
  if (converged_ > 0 && lambda_ < o_.min_increment && lambda_ < peak_lambda_)
    throw LoadPathFailure(fmt::format("quasi-static arc length: after a peak at load factor {:.6g} the path fell back to {:.3g}, below "
                                      "solver.min_increment = {:g}, at arc {}: the body cannot carry the full load",
                                      peak_lambda_, lambda_, o_.min_increment, converged_));
  std::size_t cuts = 0;
  auto& R = R_;
  while (true) {
    const auto t0 = std::chrono::steady_clock::now();
    previous_ = u;
    LoadStepReport rep;
    apply_loads(lambda_, u);
    double r = residual(u, R);
    auto x = arc_solve(u, rep);
    bool failed = !x;
    if (!failed) {
      const Eigen::VectorXd tangent_u = x->col(1);
      const double scale = std::sqrt(dot(tangent_u, tangent_u) + full_u2_);
      // The first arc is the first load step's length along the tangent; arcs never grow past it.
      if (arc_max_ == 0) arc_ = arc_max_ = scale / double(o_.steps);
      // Keep going the way the path went: the predictor's sign follows the last arc.
      const double sign = last_du_.size() && dot(last_du_, tangent_u) + full_u2_ * last_dlambda_ < 0 ? -1.0 : 1.0;
      double dlambda = sign * arc_ / scale;
      if (lambda_ + dlambda >= 1 - 1e-12) {
        // The full load is within this arc: end there by load control.
        u = previous_;
        increment_ = 1 - lambda_;
        return advance_load(u);
      }
      Eigen::VectorXd du = x->col(0) + dlambda * tangent_u;
      failed = !arc_iterations(u, rep, du, dlambda, r);
      if (!failed) {
        lambda_ += dlambda;
        last_du_ = du;
        last_dlambda_ = dlambda;
        rep = converged_report(u, rep, cuts, r, rep.reference, t0);
        // Few iterations: lengthen the next arc, up to the first one's length.
        if (rep.iterations <= 4) arc_ = std::min(arc_max_, 1.5 * arc_);
        return rep;
      }
    }
    u = previous_;
    apply_loads(lambda_, u);
    arc_ *= 0.5;
    ++cuts;
    if (arc_ < arc_max_ * o_.min_increment * double(o_.steps) * 1.0000001)
      throw LoadPathFailure(fmt::format(
          "quasi-static arc length: the arc from load factor {:.6g} (arc {}) did not converge after {} cuts (last: {} iterations, "
          "|R| = {:.3e}); the arc fell below {:g} of the first arc (solver.min_increment = {:g} of the full load, times solver.steps)",
          lambda_, converged_ + 1, cuts, rep.iterations, r, o_.min_increment * double(o_.steps), o_.min_increment));
  }
}

template <TangentModel Model>
std::optional<Eigen::MatrixXd> QuasiStaticSolver<Model>::arc_solve(const VectorField& u, LoadStepReport& rep) {
  assemble_tangent(u);
  Eigen::MatrixXd rhs(R_.size(), 2);
  rhs.col(0) = R_;
  rhs.col(1) = load_direction();
  ++rep.iterations;
  return solve_columns(rhs, rep.linear_solver);
}

template <TangentModel Model>
bool QuasiStaticSolver<Model>::arc_iterations(VectorField& u, LoadStepReport& rep, Eigen::VectorXd& du, double& dlambda, double& r) {
  const VectorField base = u;
  const double lambda0 = lambda_;
  auto& R = R_;
  const auto move = [&] {
    set_free(u, base, du);
    apply_loads(lambda0 + dlambda, u);
    r = residual(u, R);
  };
  move();
  rep.residual0 = r;
  rep.reference = reference_force();
  const double arc2 = arc_ * arc_;
  while (std::isfinite(r)) {
    if (r <= o_.tolerance * rep.reference) return true;
    if (rep.iterations >= o_.max_iterations) return false;
    auto x = arc_solve(u, rep);
    if (!x) return false;
    const Eigen::VectorXd tu = x->col(1), a = du + x->col(0);
    // |a + s tu|^2 + full_u2 (dlambda + s)^2 = arc^2
    const double c2 = dot(tu, tu) + full_u2_, c1 = 2 * (dot(a, tu) + full_u2_ * dlambda),
                 c0 = dot(a, a) + full_u2_ * dlambda * dlambda - arc2;
    const double disc = c1 * c1 - 4 * c2 * c0;
    if (!(disc >= 0) || !(c2 > 0)) return false;  // the sphere is missed: a shorter arc
    const double root = std::sqrt(disc), q = -0.5 * (c1 + std::copysign(root, c1));
    double s1 = q / c2, s2 = q != 0 ? c0 / q : s1;
    // The root whose new arc turns least from the current one.
    const auto turn = [&](double s) { return dot(du, a + s * tu) + full_u2_ * dlambda * (dlambda + s); };
    const double s = turn(s1) >= turn(s2) ? s1 : s2;
    du = a + s * tu;
    dlambda += s;
    move();
  }
  return false;
}
}  // namespace peridot
