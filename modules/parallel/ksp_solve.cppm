module;
#include <petscksp.h>

export module peridot.parallel:ksp_solve;
import peridot.std;
import :runtime;
import :row_block;

export namespace peridot::parallel {

// A linear solve on PETSc's KSP. Peridot's defaults come first; a deck's `options` and then the
// command line's (`-ksp_type cg -pc_type gamg`, anything PETSc knows) override them.
struct KspOptions {
  std::string options;                  // e.g. "-ksp_type gmres -pc_type hypre"
  std::int64_t direct_below = 20000;    // fewer unknowns: LU (MUMPS); more: GMRES + BoomerAMG
  double rtol = 1e-12;                  // relative residual of the iterative default
  int max_iterations = 10000;
  int gmres_restart = 200;
  // When the iterative default fails (diverges, breaks down, or leaves a true residual above
  // 10 rtol) and no option was given, the same matrix is solved again by LU if it has at most
  // this many nonzeros: BoomerAMG fails on nearly incompressible solids (nu = 0.49), where a
  // 49,152-unknown 2D system (4.8 M nonzeros) factorises in seconds.
  std::int64_t fallback_nonzeros = 8'000'000;
  // Steps of iterative refinement after a direct solve (Richardson on the LU factors; 0: none).
  // Saddle-point systems need it: MUMPS alone left a relative residual of 3e-10 on static OSB's
  // (4,800 unknowns + 320 constraint rows), which UMFPACK solves to 3e-14; three steps reach 2e-14.
  int refinement = 0;
};

struct KspReport {
  std::string ksp, pc, factor_package;  // what ran, after the options were applied
  int iterations = 0;
  double residual = 0;                  // true |b - A x| / |b|, computed after the solve
  double setup_seconds = 0;  // matrix, vectors and preconditioner set-up [s]
  double solve_seconds = 0;  // Krylov iterations [s]
  int ranks = 1;
  std::vector<std::string> unused_options;  // options PETSc never read (typos, usually)
  std::string fallback;  // why the iterative default gave way to LU; empty when it did not
};

// What ksp_solve returns on each rank: the whole x, or the rows the rank handed over.
enum class SolutionRows { all, own };

// Solves A x = b where each rank holds its block of rows; collective. Returns the whole x on
// every rank (SolutionRows::all), or this rank's rows of it. The block is taken by value: its
// arrays go as soon as PETSc holds its own copy. Throws std::invalid_argument when an option is
// refused and std::runtime_error when the solve fails (diverged, singular, out of memory).
std::vector<double> ksp_solve(RowBlock A, const KspOptions& options, KspReport* report = nullptr, SolutionRows rows = SolutionRows::all);

// Applies the deck's and the command line's options to a KSP without a matrix, so that unknown
// solver or preconditioner types are refused (std::invalid_argument) before a run writes a file.
// Starts PETSc. Options that only a factorisation reads are checked at the solve.
void check_ksp_options(const KspOptions& options);

}  // namespace peridot::parallel

namespace peridot::parallel {

namespace {

double since(std::chrono::steady_clock::time_point t) { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count(); }

// Owns the PETSc objects of one solve; destroys them on every path, exceptions included.
struct Objects {
  Mat A = nullptr;
  Vec b = nullptr, x = nullptr, r = nullptr, all = nullptr;
  VecScatter to_all = nullptr;
  KSP ksp = nullptr;
  PetscOptions opts = nullptr;
  bool pushed = false;
  ~Objects() {
    if (pushed) PetscOptionsPop();
    KSPDestroy(&ksp);
    VecScatterDestroy(&to_all);
    VecDestroy(&all);
    VecDestroy(&r);
    VecDestroy(&x);
    VecDestroy(&b);
    MatDestroy(&A);
    if (opts) PetscOptionsDestroy(&opts);
  }
};

void refuse_options(PetscErrorCode code, std::string_view what) {
  try {
    check(code, what);
  } catch (const std::runtime_error& e) {
    throw std::invalid_argument(e.what());
  }
}

// BoomerAMG settings measured on the static LPS systems (3 unknowns per point, about 90
// nonzeros per row), sine deck, one process: HMIS coarsening, extended+i interpolation,
// strength 0.5 and two levels of aggressive coarsening hold GMRES at 16-17 iterations from
// 49,152 to 393,132 unknowns; hypre's defaults took 45 at 49,152 and 3.8x the time. One
// aggressive level took 44 at 196,608, and PETSc's GAMG 346. Jacobi smoothing on every level
// takes two iterations more than hypre's hybrid Gauss-Seidel but each costs about half, since
// the smoother was half of the solve: 196,608 unknowns 5.3 -> 3.6 s, 786,432 23.1 -> 16.6 s
// (Zen 4, one process; Chebyshev 4.7 s, l1-scaled Jacobi 59 iterations). They go in first, so
// any deck or command-line option wins.
constexpr const char* amg_defaults[][2] = {
    {"-pc_hypre_boomeramg_coarsen_type", "HMIS"},
    {"-pc_hypre_boomeramg_interp_type", "ext+i"},
    {"-pc_hypre_boomeramg_strong_threshold", "0.5"},
    {"-pc_hypre_boomeramg_agg_nl", "2"},
    {"-pc_hypre_boomeramg_relax_type_all", "Jacobi"},
};

// A private options database: Peridot's defaults, then the deck's, then the command line's.
void fill_options(PetscOptions opts, const KspOptions& o, bool iterative) {
  if (iterative)
    for (const auto& kv : amg_defaults) check(PetscOptionsSetValue(opts, kv[0], kv[1]), "default options");
  refuse_options(PetscOptionsInsertString(opts, o.options.c_str()), fmt::format("solver.petsc_options '{}'", o.options));
  refuse_options(PetscOptionsInsertString(opts, command_line_options().c_str()), fmt::format("command-line options '{}'", command_line_options()));
}

// Unknown -ksp_type and -pc_type values are refused here, by name, before PETSc's own error
// path (which leaves a few bytes allocated after the error) is reached.
void require_registered(PetscOptions opts, const char* option, PetscFunctionList list, const char* what) {
  char value[256] = {0};
  PetscBool set = PETSC_FALSE;
  check(PetscOptionsGetString(opts, nullptr, option, value, sizeof value, &set), "options");
  if (!set) return;
  PetscVoidFunction fn = nullptr;
  check(PetscFunctionListFind(list, value, &fn), "options");
  if (!fn) throw std::invalid_argument(fmt::format("PETSc: {} {}: not a {} this PETSc knows", option, value, what));
}

void require_known_types(PetscOptions opts) {
  check(KSPInitializePackage(), "KSP package");
  check(PCInitializePackage(), "PC package");
  require_registered(opts, "-ksp_type", KSPList, "Krylov method (e.g. gmres, cg, bcgs, preonly)");
  require_registered(opts, "-pc_type", PCList, "preconditioner (e.g. hypre, gamg, lu, jacobi, none)");
}

bool is_default(std::string_view name) {
  for (const auto& kv : amg_defaults)
    if (name == std::string_view(kv[0]).substr(1)) return true;
  return false;
}

// A private options database for one solve: Peridot's defaults, then the deck's options, then
// the command line's; unknown KSP and PC types are refused before PETSc sees them.
void push_options(Objects& ob, const KspOptions& o, bool iterative) {
  check(PetscOptionsCreate(&ob.opts), "options");
  fill_options(ob.opts, o, iterative);
  require_known_types(ob.opts);
  check(PetscOptionsPush(ob.opts), "options");
  ob.pushed = true;
}

// The direct solve: LU by MUMPS, or UMFPACK on one rank where PETSc has no MUMPS.
void use_lu(KSP ksp, PC pc, int refinement) {
  check(KSPSetType(ksp, refinement > 0 ? KSPRICHARDSON : KSPPREONLY), "KSP type");
  check(PCSetType(pc, PCLU), "PC type");
#if defined(PETSC_HAVE_MUMPS)
  check(PCFactorSetMatSolverType(pc, MATSOLVERMUMPS), "MUMPS");
#else
  if (ranks() == 1) check(PCFactorSetMatSolverType(pc, MATSOLVERUMFPACK), "UMFPACK");
#endif
}

}  // namespace

std::vector<double> ksp_solve(RowBlock blk, const KspOptions& o, KspReport* report, SolutionRows rows) {
  start();
  constexpr auto max_index = std::int64_t(std::numeric_limits<PetscInt>::max());
  if (blk.global_rows > max_index || std::int64_t(blk.column.size()) > max_index)
    throw std::invalid_argument(fmt::format("PETSc: {} unknowns and {} local nonzeros exceed this PETSc's {}-bit indices", blk.global_rows,
                                            blk.column.size(), 8 * sizeof(PetscInt)));
  const auto m = PetscInt(blk.rows());
  const auto M = PetscInt(blk.global_rows);
  Objects ob;

  const bool iterative = M >= o.direct_below;
  push_options(ob, o, iterative);
  const double nonzeros = sum_over_ranks(double(blk.column.size()));

  const auto t0 = std::chrono::steady_clock::now();
  {
    // PETSc copies the CSR arrays, so 32-bit copies can go once the matrix exists.
    std::vector<PetscInt> ia(blk.offset.size()), ja(blk.column.size());
    for (std::size_t k = 0; k < ia.size(); ++k) ia[k] = PetscInt(blk.offset[k]);
    for (std::size_t k = 0; k < ja.size(); ++k) ja[k] = PetscInt(blk.column[k]);
    check(MatCreateMPIAIJWithArrays(PETSC_COMM_WORLD, m, m, M, M, ia.data(), ja.data(), blk.value.data(), &ob.A), "matrix");
    std::vector<std::int64_t>().swap(blk.column);
    std::vector<double>().swap(blk.value);
  }
  check(MatCreateVecs(ob.A, &ob.x, &ob.b), "vectors");
  {
    PetscScalar* bb = nullptr;
    check(VecGetArray(ob.b, &bb), "right-hand side");
    for (PetscInt k = 0; k < m; ++k) bb[k] = blk.rhs[std::size_t(k)];
    check(VecRestoreArray(ob.b, &bb), "right-hand side");
  }

  check(KSPCreate(PETSC_COMM_WORLD, &ob.ksp), "KSP");
  check(KSPSetOperators(ob.ksp, ob.A, ob.A), "KSP operators");
  PC pc = nullptr;
  check(KSPGetPC(ob.ksp, &pc), "PC");
  if (!iterative) {
    use_lu(ob.ksp, pc, o.refinement);
  } else {
    check(KSPSetType(ob.ksp, KSPGMRES), "KSP type");
    check(KSPGMRESSetRestart(ob.ksp, o.gmres_restart), "GMRES restart");
    check(PCSetType(pc, PCHYPRE), "PC type");
    check(PCHYPRESetType(pc, "boomeramg"), "BoomerAMG");
    // Right preconditioning, so GMRES stops on the true residual: with PETSc's left default it
    // stopped on the preconditioned one, and on a nearly incompressible 3D inclusion (nu = 0.49,
    // 6,912 unknowns) it returned a true relative residual of 1.3e-9 for the 1e-12 asked.
    check(KSPSetPCSide(ob.ksp, PC_RIGHT), "preconditioner side");
  }
  const bool refining = !iterative && o.refinement > 0;
  check(KSPSetTolerances(ob.ksp, o.rtol, 0.0, PETSC_DEFAULT, refining ? o.refinement : o.max_iterations), "tolerances");
  refuse_options(KSPSetFromOptions(ob.ksp), "options");
  check(KSPSetUp(ob.ksp), "set-up (factorisation or preconditioner)");
  const double setup = since(t0);

  auto t1 = std::chrono::steady_clock::now();
  check(KSPSolve(ob.ksp, ob.b, ob.x), "solve");
  KSPConvergedReason reason;
  PetscInt its = 0;
  check(KSPGetConvergedReason(ob.ksp, &reason), "converged reason");
  check(KSPGetIterationNumber(ob.ksp, &its), "iterations");
  double solve = since(t1);

  // The true residual, whatever norm the KSP monitored.
  check(VecDuplicate(ob.b, &ob.r), "residual");
  const auto true_residual = [&] {
    PetscReal rn = 0, bn = 0;
    check(MatMult(ob.A, ob.x, ob.r), "residual");
    check(VecAYPX(ob.r, -1.0, ob.b), "residual");
    check(VecNorm(ob.r, NORM_2, &rn), "residual");
    check(VecNorm(ob.b, NORM_2, &bn), "residual");
    return rn / (bn > 0 ? bn : 1.0);
  };
  double residual = true_residual();
  const bool chosen = !o.options.empty() || !command_line_options().empty();
  std::string fallback;
  if (iterative && !chosen && (reason < 0 || !(residual <= 10 * o.rtol)) && nonzeros <= double(o.fallback_nonzeros)) {
    fallback = fmt::format("GMRES + BoomerAMG {} after {} iterations with relative residual {:.3e}",
                           reason < 0 ? std::string(KSPConvergedReasons[reason]) : "stopped", its, residual);
    check(KSPSetPCSide(ob.ksp, PC_LEFT), "preconditioner side");  // preonly takes no other
    use_lu(ob.ksp, pc, 0);
    check(VecSet(ob.x, 0.0), "initial guess");
    t1 = std::chrono::steady_clock::now();
    check(KSPSetUp(ob.ksp), "set-up (factorisation)");
    check(KSPSolve(ob.ksp, ob.b, ob.x), "solve");
    check(KSPGetConvergedReason(ob.ksp, &reason), "converged reason");
    check(KSPGetIterationNumber(ob.ksp, &its), "iterations");
    solve += since(t1);
    residual = true_residual();
  }
  // Refinement that used all its steps still leaves the direct solve's answer, or better.
  const bool refined = refining && reason == KSP_DIVERGED_ITS && std::isfinite(residual);
  if (reason < 0 && !refined)
    throw std::runtime_error(fmt::format("PETSc: the solve did not converge ({}) after {} iterations, relative residual {:.3e}; try other "
                                         "options, e.g. -ksp_type preonly -pc_type lu -pc_factor_mat_solver_type mumps",
                                         KSPConvergedReasons[reason], its, residual));

  std::vector<double> out;
  if (rows == SolutionRows::own) {
    out.resize(std::size_t(m));
    const PetscScalar* a = nullptr;
    check(VecGetArrayRead(ob.x, &a), "solution");
    for (PetscInt k = 0; k < m; ++k) out[std::size_t(k)] = a[k];
    check(VecRestoreArrayRead(ob.x, &a), "solution");
  } else {
    check(VecScatterCreateToAll(ob.x, &ob.to_all, &ob.all), "gather");
    check(VecScatterBegin(ob.to_all, ob.x, ob.all, INSERT_VALUES, SCATTER_FORWARD), "gather");
    check(VecScatterEnd(ob.to_all, ob.x, ob.all, INSERT_VALUES, SCATTER_FORWARD), "gather");
    out.resize(static_cast<std::size_t>(M));
    const PetscScalar* a = nullptr;
    check(VecGetArrayRead(ob.all, &a), "gather");
    for (PetscInt k = 0; k < M; ++k) out[std::size_t(k)] = a[k];
    check(VecRestoreArrayRead(ob.all, &a), "gather");
  }

  if (report) {
    KSPType kt;
    PCType pt;
    check(KSPGetType(ob.ksp, &kt), "report");
    check(PCGetType(pc, &pt), "report");
    report->ksp = kt ? kt : "";
    report->pc = pt ? pt : "";
    report->factor_package.clear();
    if (report->pc == PCLU || report->pc == PCCHOLESKY) {
      MatSolverType st = nullptr;
      check(PCFactorGetMatSolverType(pc, &st), "report");
      if (st) report->factor_package = st;
    }
    report->iterations = int(its);
    report->residual = residual;
    report->setup_seconds = setup;
    report->solve_seconds = solve;
    report->ranks = ranks();
    report->fallback = fallback;
    report->unused_options.clear();
    PetscInt left = 0;
    char** names = nullptr;
    char** values = nullptr;
    if (PetscOptionsLeftGet(ob.opts, &left, &names, &values) == 0) {
      for (PetscInt k = 0; k < left; ++k)
        if (!is_default(names[k])) report->unused_options.push_back(fmt::format("-{}", names[k]));
      PetscOptionsLeftRestore(ob.opts, &left, &names, &values);
    }
  }
  return out;
}

void check_ksp_options(const KspOptions& o) {
  start();
  Objects ob;
  push_options(ob, o, true);
  check(KSPCreate(PETSC_COMM_WORLD, &ob.ksp), "KSP");
  refuse_options(KSPSetFromOptions(ob.ksp), "options");
}

}  // namespace peridot::parallel
