module;
#include <omp.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>
#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCore>
#include <Eigen/SparseLU>
#include <Eigen/UmfPackSupport>
#include <fmt/core.h>
export module peridot.implicit:static_lps;
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

// Data of a static LPS problem (seed 000, eq. (3.4) discretised as (4.6)-(4.11)). Unknowns
// (u, v, theta) live on interior points; collar points carry u_D and a theta computed
// from u_D (moved to the right-hand side); ghost points carry nothing.
// Callbacks take positions or the body as arguments, so a problem never refers into the
// object that owns it.
struct NeumannLoad {
  std::array<double, 2> T{0, 0};                    // (T_n, T_p) [Pa]
  std::optional<std::array<double, 2>> normal;      // set: use this exact n in (4.6) instead of (4.9)
};

struct StaticLpsProblem {
  std::function<std::array<double, 2>(const Vec3&)> body_force;   // f(x) [N/m^3]
  std::function<std::array<double, 2>(const Vec3&)> dirichlet;    // u_D(x) [m]
  // Normal and tangential traction (T_n, T_p) [Pa] at x-bar for an interior point i with missing
  // interactions, given its frame; (4.6) applies them along n_i and p_i = (-n_y, n_x).
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

StaticResult solve_static_lps(const Body& body, const Lps& model, const StaticLpsProblem& problem, const StaticOptions& options = {});

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

StaticResult solve_static_lps(const Body& body, const Lps& lps, const StaticLpsProblem& prob, const StaticOptions& opt) {
  const auto& pc = body.points;
  const auto& bl = body.bonds;
  const std::size_t n = body.size();
  if (pc.dim != 2) throw std::invalid_argument("static LPS: only 2D is implemented");
  if (lps.lambda.size() != n) throw std::invalid_argument("static LPS: the model needs one (lambda, mu) per point");
  const auto t0 = std::chrono::steady_clock::now();

  // Unknown numbering: interior points only.
  std::vector<std::int64_t> dof(n, -1);
  std::int64_t N = 0;
  for (std::size_t i = 0; i < n; ++i)
    if (pc.role[i] == Role::interior) dof[i] = N++;
  if (N == 0) throw std::invalid_argument("static LPS: the body has no interior points");

  StaticResult res;
  res.u = zero_field(n);
  res.theta.assign(n, 0.0);
  const double d_over_m = lps.dim / lps.m;

  // Collar data: u_D everywhere (partners of collar points reach further out), and theta from
  // u_D by the model's own (4.7) on collar partners of interior points.
  VectorField uD = zero_field(n);
  for (std::size_t i = 0; i < n; ++i) {
    const auto d = prob.dirichlet(pc.position(i));
    uD[0][i] = d[0];
    uD[1][i] = d[1];
    if (pc.role[i] == Role::collar) res.u[0][i] = d[0], res.u[1][i] = d[1];
  }
  std::vector<std::uint8_t> needs_theta(n, 0);
  for (std::size_t i = 0; i < n; ++i)
    if (pc.role[i] == Role::interior)
      for (auto b = bl.offset[i]; b < bl.offset[i + 1]; ++b)
        if (pc.role[bl.neighbor[b]] == Role::collar && bl.intact[b]) needs_theta[bl.neighbor[b]] = 1;
#pragma omp parallel for schedule(dynamic, 64)
  for (std::int64_t i = 0; i < std::int64_t(n); ++i)
    if (needs_theta[i]) res.theta[i] = lps_dilatation(body, lps, lps_frame(body, lps, std::size_t(i)), std::size_t(i), uD);

  // Unknowns interleaved per point, (u, v, theta) at 3 dof + (0, 1, 2), so that a rank owning a
  // contiguous range of interior points owns a contiguous range of rows. Each rank assembles its
  // own rows (with PETSc on N ranks) or all of them (one process).
  const bool on_petsc = opt.solver == LinearSolver::petsc;
  if (on_petsc) parallel::start();
  const int nranks = on_petsc ? parallel::ranks() : 1;
  const auto own = parallel::owned_range(N, nranks, on_petsc ? parallel::rank() : 0);
  const std::int64_t first_row = 3 * own.begin, local_rows = 3 * (own.end - own.begin);
  std::vector<double> F(std::size_t(local_rows), 0.0);
  const int threads = omp_get_max_threads();
  parallel::RowAssembly assembly(3 * N, first_row, local_rows, threads);
#pragma omp parallel
  {
    const int thread = omp_get_thread_num();
    std::vector<parallel::Entry> T;
#pragma omp for schedule(dynamic, 64)
    for (std::int64_t ii = 0; ii < std::int64_t(n); ++ii) {
      const auto i = std::size_t(ii);
      if (dof[i] < own.begin || dof[i] >= own.end) continue;
      const std::int64_t r[3] = {3 * dof[i], 3 * dof[i] + 1, 3 * dof[i] + 2};
      auto fr = lps_frame(body, lps, i);
      const auto f = prob.body_force ? prob.body_force(pc.position(i)) : std::array<double, 2>{0, 0};
      double rhs[3] = {f[0], f[1], 0.0};
      double diag_u[2][2] = {{0, 0}, {0, 0}}, diag_theta[2] = {0, 0}, theta_row_self[2] = {0, 0};
      std::array<double, 2> Tn_p{0, 0};
      const bool traction_terms = fr.has_missing && fr.has_normal;
      if (traction_terms && prob.traction) {
        const auto load = prob.traction(body, i, fr);
        Tn_p = load.T;
        if (load.normal) fr.n = *load.normal, fr.p = {-fr.n[1], fr.n[0]};
      }
      for (auto b = bl.offset[i]; b < bl.offset[i + 1]; ++b) {
        const auto j = std::size_t(bl.neighbor[b]);
        const double xi[2] = {bl.xi[0][b], bl.xi[1][b]};
        const double r2 = xi[0] * xi[0] + xi[1] * xi[1], K = lps.kernel(bl.length[b]), w = bl.weight[b];
        if (!bl.intact[b]) continue;
        // The left side of (4.6) is minus the model's force density.
        const double a = -lps.theta_coefficient(i, j, K * w);
        for (int c = 0; c < 2; ++c) {
          diag_theta[c] += a * xi[c];
          if (dof[j] >= 0) T.push_back({r[c], 3 * dof[j] + 2, a * xi[c]});
          else rhs[c] -= a * xi[c] * res.theta[j];
        }
        const double bcoef = -lps.shear_coefficient(i, j, K * w, r2);
        for (int c = 0; c < 2; ++c)
          for (int e = 0; e < 2; ++e) {
            const double v = bcoef * xi[c] * xi[e];
            diag_u[c][e] -= v;
            if (dof[j] >= 0) T.push_back({r[c], 3 * dof[j] + e, v});
            else rhs[c] -= v * res.u[e][j];
          }
        // theta_i - d/m sum K xi . M (u_j - u_i) w~ = 0
        const double mx = fr.M[0] * xi[0] + fr.M[1] * xi[1], my = fr.M[2] * xi[0] + fr.M[3] * xi[1];
        const double t = -d_over_m * K * w;
        const double m2[2] = {mx, my};
        for (int e = 0; e < 2; ++e) {
          theta_row_self[e] -= t * m2[e];
          if (dof[j] >= 0) T.push_back({r[2], 3 * dof[j] + e, t * m2[e]});
          else rhs[2] -= t * m2[e] * res.u[e][j];
        }
      }
      // Missing interactions (4.6): theta_i terms and the traction load over all w^ bonds.
      if (traction_terms) {
        const auto a = lps.missing_theta(i, fr);
        const auto g = lps.traction_load(fr, fr.missing, Tn_p[0], Tn_p[1]);
        for (int c = 0; c < 2; ++c) {
          diag_theta[c] += a[c];
          rhs[c] += g[c];
        }
      }
      for (int c = 0; c < 2; ++c) {
        for (int e = 0; e < 2; ++e) T.push_back({r[c], 3 * dof[i] + e, diag_u[c][e]});
        T.push_back({r[c], r[2], diag_theta[c]});
        T.push_back({r[2], 3 * dof[i] + c, theta_row_self[c]});
      }
      T.push_back({r[2], r[2], 1.0});
      for (int c = 0; c < 3; ++c) F[std::size_t(r[c] - first_row)] = rhs[c];
      assembly.add_rows(thread, r[0], 3, T);
    }
  }
  auto block = assembly.finish(std::move(F));
  res.unknowns = std::size_t(3 * N);
  res.nonzeros = block.column.size();
  res.assembly_seconds = seconds_since(t0);

  const auto t1 = std::chrono::steady_clock::now();
  std::vector<double> eta;
  if (on_petsc) {
    eta = parallel::ksp_solve(std::move(block), opt.petsc, &res.petsc);
    res.iterations = res.petsc.iterations;
    res.residual = res.petsc.residual;
    if (nranks > 1) {
      std::uint64_t nnz = res.nonzeros;
      parallel::sum_over_ranks(nnz);
      res.nonzeros = nnz;
    }
  } else {
    // One process: the CSR block is the whole matrix.
    const SparseMatrix Kmat = Eigen::Map<const RowMatrix>(3 * N, 3 * N, std::int64_t(block.column.size()), block.offset.data(),
                                                         block.column.data(), block.value.data());
    const Eigen::Map<const Eigen::VectorXd> Fv(block.rhs.data(), 3 * N);
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
  for (std::size_t i = 0; i < n; ++i)
    if (dof[i] >= 0) {
      res.u[0][i] = eta[std::size_t(3 * dof[i])];
      res.u[1][i] = eta[std::size_t(3 * dof[i] + 1)];
      res.theta[i] = eta[std::size_t(3 * dof[i] + 2)];
    }
  return res;
}

}  // namespace peridot
