module;
#include <omp.h>

#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCore>
#include <Eigen/SparseLU>
#include <Eigen/UmfPackSupport>
export module peridot.implicit:static_lps;
import peridot.std;
import peridot.models;
import peridot.parallel;

export namespace peridot {

// petsc: PETSc's KSP on every MPI rank (direct MUMPS for small systems, GMRES with BoomerAMG
// for large ones, anything else through PETSc options); umfpack: SuiteSparse's multifrontal LU
// on one process; sparse_lu: Eigen's supernodal LU; bicgstab_ilut: Eigen's BiCGSTAB with ILUT.
enum class LinearSolver { petsc, umfpack, sparse_lu, bicgstab_ilut };

struct StaticOptions {
  LinearSolver solver = LinearSolver::petsc;
  parallel::KspOptions petsc;    // defaults, deck and command-line options of the PETSc solve
  double tolerance = 1e-12;      // BiCGSTAB relative residual
  int max_iterations = 20000;
  double ilut_drop = 1e-6;       // ILUT drop tolerance
  int ilut_fill = 40;            // ILUT fill factor
};

// Data of a static LPS problem (seed 000, eq. (3.4) discretised as (4.6)-(4.11)), 2D or 3D.
// Unknowns (u, v, theta) in 2D, (u, v, w, theta) in 3D, live on interior points; collar points carry u_D and a theta computed
// from u_D (moved to the right-hand side); ghost points carry nothing.
// Callbacks take positions or the body as arguments, so a problem never refers into the
// object that owns it.
struct NeumannLoad {
  std::array<double, 3> T{0, 0, 0};                 // traction vector [Pa]
  std::optional<std::array<double, 3>> normal;      // set: use this exact n in (4.6) instead of (4.9)
};

struct StaticLpsProblem {
  std::function<std::array<double, 3>(const Vec3&)> body_force;   // f(x) [N/m^3]
  std::function<std::array<double, 3>(const Vec3&)> dirichlet;    // u_D(x) [m]
  // The traction vector [Pa] for an interior point i with missing interactions, given its
  // frame; (4.6) applies its normal part T_n = T . n_i along n_i and the rest tangentially.
  // May be empty for a problem without Neumann boundaries.
  std::function<NeumannLoad(const Body&, std::size_t, const LpsFrame&)> traction;
};

struct StaticResult {
  VectorField u;                  // interior: solved; collar: u_D; ghost: 0
  std::vector<double> theta;      // interior: solved; collar: from u_D
  std::size_t unknowns = 0, nonzeros = 0;
  int iterations = 0;             // iterative solvers only
  double residual = 0;            // relative residual |K eta - F| / |F|
  parallel::KspReport petsc;      // what PETSc ran (solver = petsc)
  double assembly_seconds = 0, solve_seconds = 0;
};

// One rank's share of a static LPS solve on N ranks (PETSc): the body is the rank's part, and
// the rank assembles the rows of the interior points it owns. Interior points are numbered over
// the whole body rank after rank (each rank's owned ones in their order), so a rank's rows are
// contiguous.
struct StaticParts {
  std::vector<std::int64_t> unknown;  // per local point: its global interior number, or -1 (collar, ghost)
  std::int64_t first = 0;             // this rank's first interior number
  std::int64_t count = 0;             // the interior points it owns
  std::int64_t global = 0;            // interior points of the whole body
};

// Solves the static problem. With `parts` the solve is collective: the result holds u and theta
// of the owned interior points (and u_D, theta of collar points as on one rank); other interior
// points are zero until the caller refreshes them from their owners.
StaticResult solve_static_lps(const Body& body, const Lps& model, const StaticLpsProblem& problem, const StaticOptions& options = {},
                              const StaticParts* parts = nullptr);

}  // namespace peridot

namespace peridot {

namespace {

// 64-bit indices: UMFPACK's int interface runs out of address space near a million unknowns.
using SparseMatrix = Eigen::SparseMatrix<double, Eigen::ColMajor, long>;
using RowMatrix = Eigen::SparseMatrix<double, Eigen::RowMajor, long>;

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

}  // namespace

StaticResult solve_static_lps(const Body& body, const Lps& lps, const StaticLpsProblem& prob, const StaticOptions& opt, const StaticParts* parts) {
  const auto& pc = body.points;
  const auto& bl = body.bonds;
  const std::size_t n = body.size();
  const int d = pc.dim;
  if (d != 2 && d != 3) throw std::invalid_argument("static LPS: the body must be 2D or 3D");
  if (lps.dim != d) throw std::invalid_argument(fmt::format("static LPS: a {}D model on a {}D body", lps.dim, d));
  if (lps.lambda.size() != n) throw std::invalid_argument("static LPS: the model needs one (lambda, mu) per point");
  const auto t0 = std::chrono::steady_clock::now();

  // Unknown numbering: interior points only (on N ranks: over all ranks).
  if (parts && opt.solver != LinearSolver::petsc) throw std::invalid_argument("static LPS: a distributed solve runs on PETSc");
  if (parts && parts->unknown.size() != n) throw std::invalid_argument("static LPS: one unknown number per local point");
  std::vector<std::int64_t> numbered;
  std::int64_t N = 0;
  if (!parts) {
    numbered.assign(n, -1);
    for (std::size_t i = 0; i < n; ++i)
      if (pc.role[i] == Role::interior) numbered[i] = N++;
  } else {
    N = parts->global;
  }
  const std::vector<std::int64_t>& dof = parts ? parts->unknown : numbered;
  if (N == 0) throw std::invalid_argument("static LPS: the body has no interior points");

  StaticResult res;
  res.u = zero_field(n);
  res.theta.assign(n, 0.0);
  const double d_over_m = lps.dim / lps.m;

  // Collar data: u_D everywhere (partners of collar points reach further out), and theta from
  // u_D by the model's own (4.7) on collar partners of interior points.
  VectorField uD = zero_field(n);
  for (std::size_t i = 0; i < n; ++i) {
    const auto u = prob.dirichlet(pc.position(i));
    for (int c = 0; c < d; ++c) {
      uD[std::size_t(c)][i] = u[std::size_t(c)];
      if (pc.role[i] == Role::collar) res.u[std::size_t(c)][i] = u[std::size_t(c)];
    }
  }
  std::vector<std::uint8_t> needs_theta(n, 0);
  for (std::size_t i = 0; i < n; ++i)
    if (pc.role[i] == Role::interior)
      for (auto b = bl.offset[i]; b < bl.offset[i + 1]; ++b)
        if (pc.role[bl.neighbor[b]] == Role::collar && bl.intact[b]) needs_theta[bl.neighbor[b]] = 1;
#pragma omp parallel for schedule(dynamic, 64)
  for (std::int64_t i = 0; i < std::int64_t(n); ++i)
    if (needs_theta[i]) res.theta[i] = lps_dilatation(body, lps, lps_frame(body, lps, std::size_t(i)), std::size_t(i), uD);

  // Unknowns interleaved per point, (u, v[, w], theta) at s dof + (0 .. d), s = d + 1, so that
  // a rank owning a contiguous range of interior points owns a contiguous range of rows. Each
  // rank assembles its own rows (with PETSc on N ranks) or all of them (one process).
  const std::int64_t s = d + 1;
  const bool on_petsc = opt.solver == LinearSolver::petsc;
  if (on_petsc) parallel::start();
  const int nranks = on_petsc ? parallel::ranks() : 1;
  const auto own = parts ? parallel::Range{parts->first, parts->first + parts->count} : parallel::owned_range(N, nranks, on_petsc ? parallel::rank() : 0);
  const std::int64_t first_row = s * own.begin, local_rows = s * (own.end - own.begin);
  std::vector<double> F(std::size_t(local_rows), 0.0);
  const int threads = omp_get_max_threads();
  parallel::RowAssembly assembly(s * N, first_row, local_rows, threads);
#pragma omp parallel
  {
    const int thread = omp_get_thread_num();
    std::vector<parallel::Entry> T;
#pragma omp for schedule(dynamic, 64)
    for (std::int64_t ii = 0; ii < std::int64_t(n); ++ii) {
      const auto i = std::size_t(ii);
      if (dof[i] < own.begin || dof[i] >= own.end) continue;
      const std::int64_t r0 = s * dof[i], rt = r0 + d;  // first u row, theta row
      auto fr = lps_frame(body, lps, i);
      const auto f = prob.body_force ? prob.body_force(pc.position(i)) : std::array<double, 3>{0, 0, 0};
      double rhs[4] = {f[0], f[1], d == 3 ? f[2] : 0.0, 0.0};
      rhs[d] = 0.0;
      double diag_u[3][3] = {}, diag_theta[3] = {}, theta_row_self[3] = {};
      std::array<double, 3> traction{0, 0, 0};
      const bool traction_terms = fr.has_missing && fr.has_normal;
      if (traction_terms && prob.traction) {
        const auto load = prob.traction(body, i, fr);
        traction = load.T;
        if (load.normal) fr.n = *load.normal;
      }
      for (auto b = bl.offset[i]; b < bl.offset[i + 1]; ++b) {
        if (!bl.intact[b]) continue;
        const auto j = std::size_t(bl.neighbor[b]);
        double xi[3] = {bl.xi[0][b], bl.xi[1][b], d == 3 ? bl.xi[2][b] : 0.0};
        double r2 = 0;
        for (int c = 0; c < d; ++c) r2 += xi[c] * xi[c];
        const double K = lps.kernel(bl.length[b]), w = bl.weight[b];
        const std::int64_t rj = dof[j] >= 0 ? s * dof[j] : -1;
        // The left side of (4.6) is minus the model's force density.
        const double a = -lps.theta_coefficient(i, j, K * w);
        for (int c = 0; c < d; ++c) {
          diag_theta[c] += a * xi[c];
          if (rj >= 0) T.push_back({r0 + c, rj + d, a * xi[c]});
          else rhs[c] -= a * xi[c] * res.theta[j];
        }
        const double bcoef = -lps.shear_coefficient(i, j, K * w, r2);
        for (int c = 0; c < d; ++c)
          for (int e = 0; e < d; ++e) {
            const double v = bcoef * xi[c] * xi[e];
            diag_u[c][e] -= v;
            if (rj >= 0) T.push_back({r0 + c, rj + e, v});
            else rhs[c] -= v * res.u[std::size_t(e)][j];
          }
        // theta_i - d/m sum K xi . M (u_j - u_i) w~ = 0
        const double t = -d_over_m * K * w;
        for (int e = 0; e < d; ++e) {
          double me = 0;
          for (int c = 0; c < d; ++c) me += fr.M[std::size_t(3 * e + c)] * xi[c];
          theta_row_self[e] -= t * me;
          if (rj >= 0) T.push_back({rt, rj + e, t * me});
          else rhs[d] -= t * me * res.u[std::size_t(e)][j];
        }
      }
      // Missing interactions (4.6): theta_i terms and the traction load over all w^ bonds.
      if (traction_terms) {
        const auto a = lps.missing_theta(i, fr);
        const auto g = lps.traction_load(fr, fr.missing, traction);
        for (int c = 0; c < d; ++c) {
          diag_theta[c] += a[std::size_t(c)];
          rhs[c] += g[std::size_t(c)];
        }
      }
      for (int c = 0; c < d; ++c) {
        for (int e = 0; e < d; ++e) T.push_back({r0 + c, r0 + e, diag_u[c][e]});
        T.push_back({r0 + c, rt, diag_theta[c]});
        T.push_back({rt, r0 + c, theta_row_self[c]});
      }
      T.push_back({rt, rt, 1.0});
      for (int c = 0; c <= d; ++c) F[std::size_t(r0 + c - first_row)] = rhs[c];
      assembly.add_rows(thread, r0, int(s), T);
    }
  }
  auto block = assembly.finish(std::move(F));
  res.unknowns = std::size_t(s * N);
  res.nonzeros = block.column.size();
  res.assembly_seconds = seconds_since(t0);

  const auto t1 = std::chrono::steady_clock::now();
  std::vector<double> eta;
  if (on_petsc) {
    eta = parallel::ksp_solve(std::move(block), opt.petsc, &res.petsc, parts ? parallel::SolutionRows::own : parallel::SolutionRows::all);
    res.iterations = res.petsc.iterations;
    res.residual = res.petsc.residual;
    if (nranks > 1) {
      std::uint64_t nnz = res.nonzeros;
      parallel::sum_over_ranks(nnz);
      res.nonzeros = nnz;
    }
  } else {
    // One process: the CSR block is the whole matrix.
    const SparseMatrix Kmat = Eigen::Map<const RowMatrix>(s * N, s * N, std::int64_t(block.column.size()), block.offset.data(),
                                                         block.column.data(), block.value.data());
    const Eigen::Map<const Eigen::VectorXd> Fv(block.rhs.data(), s * N);
    Eigen::VectorXd x;
    if (opt.solver == LinearSolver::umfpack) {
      Eigen::UmfPackLU<SparseMatrix> lu;
      lu.compute(Kmat);
      if (lu.info() != Eigen::Success)
        throw std::runtime_error("static LPS: UMFPACK factorisation failed (singular system, or out of memory: try linear_solver: petsc)");
      x = lu.solve(Fv);
    } else if (opt.solver == LinearSolver::sparse_lu) {
      Eigen::SparseLU<SparseMatrix> lu;
      lu.compute(Kmat);
      if (lu.info() != Eigen::Success)
        throw std::runtime_error("static LPS: sparse LU factorisation failed (singular system: check that every interior point has enough neighbours)");
      x = lu.solve(Fv);
    } else {
      Eigen::BiCGSTAB<SparseMatrix, Eigen::IncompleteLUT<double, long>> it;
      it.preconditioner().setDroptol(opt.ilut_drop);
      it.preconditioner().setFillfactor(opt.ilut_fill);
      it.setTolerance(opt.tolerance);
      it.setMaxIterations(opt.max_iterations);
      it.compute(Kmat);
      x = it.solve(Fv);
      res.iterations = int(it.iterations());
      if (it.info() != Eigen::Success)
        throw std::runtime_error(fmt::format("static LPS: BiCGSTAB did not converge in {} iterations (error {:.3e})", it.iterations(), it.error()));
    }
    const double fn = Fv.norm();
    res.residual = (Kmat * x - Fv).norm() / (fn > 0 ? fn : 1.0);
    eta.assign(x.data(), x.data() + x.size());
  }
  res.solve_seconds = seconds_since(t1);
  // eta holds the rows from first_row on: all of them, or this rank's.
  const std::int64_t from = parts ? first_row : 0;
  for (std::size_t i = 0; i < n; ++i)
    if (dof[i] >= 0 && (!parts || (dof[i] >= own.begin && dof[i] < own.end))) {
      for (int c = 0; c < d; ++c) res.u[std::size_t(c)][i] = eta[std::size_t(s * dof[i] + c - from)];
      res.theta[i] = eta[std::size_t(s * dof[i] + d - from)];
    }
  return res;
}

}  // namespace peridot
