// The PETSc and MPI side of peridot.parallel (parallel_backend.h): a shared library the module
// opens at the first call that needs MPI or PETSc, so serial runs load neither. The functions
// here are the module's former bodies, taking plain C arguments; failures come back as a
// PeridotError that the module throws again.
#include "parallel_backend.h"

#include <petscksp.h>
#include <petscsf.h>
#include <stdlib.h>  // setenv

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <fmt/core.h>

#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#include <sanitizer/lsan_interface.h>
#define PERIDOT_LSAN_IGNORE 1
#endif
#endif

namespace {

std::string& last_message() {
  static std::string m;
  return m;
}

// PETSc's default handler prints a traceback and the caller aborts; Peridot turns every failure
// into an exception carrying PETSc's first message, so bad options exit 2 like any bad input.
PetscErrorCode keep_message(MPI_Comm, int, const char*, const char*, PetscErrorCode n, PetscErrorType p, const char* mess, void*) {
  if (p == PETSC_ERROR_INITIAL && mess) last_message() = mess;
  return n;
}

// Throws std::runtime_error naming `what` and PETSc's own message when a PETSc call fails.
void check(PetscErrorCode code, std::string_view what) {
  if (code == 0) return;
  std::string m = last_message();
  last_message().clear();
  if (m.empty()) {
    const char* text = nullptr;
    PetscErrorMessage(code, &text, nullptr);
    m = text ? text : "unknown error";
  }
  throw std::runtime_error(fmt::format("PETSc: {}: {}", what, m));
}

// OpenMPI keeps what MPI_Init allocates (topology, plugins, PMIx state) until exit, partly in
// plugins it has unloaded by then, so LeakSanitizer cannot name them for a suppression. Under
// the sanitizer, allocations made while starting and stopping MPI are not counted as leaks.
struct IgnoreLeaks {
#ifdef PERIDOT_LSAN_IGNORE
  IgnoreLeaks() { __lsan_disable(); }
  ~IgnoreLeaks() { __lsan_enable(); }
#endif
};

struct Runtime {
  bool owns = false;
  ~Runtime() {
    if (!owns) return;
    IgnoreLeaks quiet;
    PetscFinalize();
  }
};

Runtime& runtime() {
  static Runtime r;
  return r;
}

// Runs f, turning an exception into the error the module throws again.
template <class F>
int guarded(PeridotError* error, F&& f) {
  try {
    f();
    return 0;
  } catch (const std::invalid_argument& e) {
    error->kind = 2;
    std::snprintf(error->message, sizeof error->message, "%s", e.what());
  } catch (const std::length_error& e) {
    error->kind = 3;
    std::snprintf(error->message, sizeof error->message, "%s", e.what());
  } catch (const std::exception& e) {
    error->kind = 1;
    std::snprintf(error->message, sizeof error->message, "%s", e.what());
  }
  return 1;
}

MPI_Datatype mpi_type(int type) {
  switch (type) {
    case peridot_u8: return MPI_UINT8_T;
    case peridot_i16: return MPI_INT16_T;
    case peridot_i32: return MPI_INT;
    case peridot_i64: return MPI_INT64_T;
    case peridot_u64: return MPI_UINT64_T;
    default: return MPI_DOUBLE;
  }
}

MPI_Op mpi_op(int op) { return op == peridot_min ? MPI_MIN : op == peridot_max ? MPI_MAX : MPI_SUM; }

int started() {
  PetscBool s = PETSC_FALSE;
  PetscInitialized(&s);
  return s == PETSC_TRUE;
}

int size() {
  if (!started()) return 1;
  int s = 1;
  MPI_Comm_size(PETSC_COMM_WORLD, &s);
  return s;
}

int start(int isolated, PeridotError* error) {
  static std::once_flag once;
  return guarded(error, [&] {
    std::call_once(once, [&] {
      PetscBool already = PETSC_FALSE;
      PetscInitialized(&already);
      if (already) return;
      // Outside mpirun, OpenMPI's singleton start forks and execs an `orted` daemon that binds
      // TCP sockets, only so that the process could spawn others later (MPI_Comm_spawn, which
      // Peridot never calls). Isolated, the process is its own one-rank world: no second process
      // to start, time out or reap, and about 0.2 s less per start. A user's own setting wins.
      if (isolated) setenv("OMPI_MCA_ess_singleton_isolated", "1", 0);
      // No argv: Peridot hands PETSc its options itself (the module's set_command_line_options).
      {
        IgnoreLeaks quiet;
        if (PetscInitializeNoArguments() != 0) throw std::runtime_error("PETSc: initialisation failed (is MPI usable here?)");
      }
      runtime().owns = true;
      PetscPushErrorHandler(keep_message, nullptr);
    });
  });
}

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
void fill_options(PetscOptions opts, const PeridotKspIn& o, bool iterative) {
  if (iterative)
    for (const auto& kv : amg_defaults) check(PetscOptionsSetValue(opts, kv[0], kv[1]), "default options");
  refuse_options(PetscOptionsInsertString(opts, o.options), fmt::format("solver.petsc_options '{}'", o.options));
  refuse_options(PetscOptionsInsertString(opts, o.command_line), fmt::format("command-line options '{}'", o.command_line));
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
void push_options(Objects& ob, const PeridotKspIn& o, bool iterative) {
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
  if (size() == 1) check(PCFactorSetMatSolverType(pc, MATSOLVERUMFPACK), "UMFPACK");
#endif
}

void solve(const PeridotKspIn& o, PeridotKspOut& out) {
  constexpr auto max_index = std::int64_t(std::numeric_limits<PetscInt>::max());
  if (o.global_rows > max_index || o.nonzeros > max_index)
    throw std::invalid_argument(fmt::format("PETSc: {} unknowns and {} local nonzeros exceed this PETSc's {}-bit indices", o.global_rows,
                                            o.nonzeros, 8 * sizeof(PetscInt)));
  const auto m = PetscInt(o.rows);
  const auto M = PetscInt(o.global_rows);
  Objects ob;

  const bool iterative = M >= o.direct_below;
  push_options(ob, o, iterative);
  double nonzeros = double(o.nonzeros);
  MPI_Allreduce(MPI_IN_PLACE, &nonzeros, 1, MPI_DOUBLE, MPI_SUM, PETSC_COMM_WORLD);

  const auto t0 = std::chrono::steady_clock::now();
  {
    // PETSc copies the CSR arrays, so 32-bit copies can go once the matrix exists.
    std::vector<PetscInt> ia(std::size_t(o.rows) + 1), ja(std::size_t(o.nonzeros));
    for (std::size_t k = 0; k < ia.size(); ++k) ia[k] = PetscInt(o.offset[k]);
    for (std::size_t k = 0; k < ja.size(); ++k) ja[k] = PetscInt(o.column[k]);
    check(MatCreateMPIAIJWithArrays(PETSC_COMM_WORLD, m, m, M, M, ia.data(), ja.data(), o.value, &ob.A), "matrix");
    if (o.release_matrix) o.release_matrix(o.context);
  }
  check(MatCreateVecs(ob.A, &ob.x, &ob.b), "vectors");
  {
    PetscScalar* bb = nullptr;
    check(VecGetArray(ob.b, &bb), "right-hand side");
    for (PetscInt k = 0; k < m; ++k) bb[k] = o.rhs[k];
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
  double solve_time = since(t1);

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
  const bool chosen = *o.options != 0 || *o.command_line != 0;
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
    solve_time += since(t1);
    residual = true_residual();
  }
  // Refinement that used all its steps still leaves the direct solve's answer, or better.
  const bool refined = refining && reason == KSP_DIVERGED_ITS && std::isfinite(residual);
  if (reason < 0 && !refined)
    throw std::runtime_error(fmt::format("PETSc: the solve did not converge ({}) after {} iterations, relative residual {:.3e}; try other "
                                         "options, e.g. -ksp_type preonly -pc_type lu -pc_factor_mat_solver_type mumps",
                                         KSPConvergedReasons[reason], its, residual));

  if (o.own_rows) {
    const PetscScalar* a = nullptr;
    check(VecGetArrayRead(ob.x, &a), "solution");
    for (PetscInt k = 0; k < m; ++k) out.x[k] = a[k];
    check(VecRestoreArrayRead(ob.x, &a), "solution");
  } else {
    check(VecScatterCreateToAll(ob.x, &ob.to_all, &ob.all), "gather");
    check(VecScatterBegin(ob.to_all, ob.x, ob.all, INSERT_VALUES, SCATTER_FORWARD), "gather");
    check(VecScatterEnd(ob.to_all, ob.x, ob.all, INSERT_VALUES, SCATTER_FORWARD), "gather");
    const PetscScalar* a = nullptr;
    check(VecGetArrayRead(ob.all, &a), "gather");
    for (PetscInt k = 0; k < M; ++k) out.x[k] = a[k];
    check(VecRestoreArrayRead(ob.all, &a), "gather");
  }

  KSPType kt;
  PCType pt;
  check(KSPGetType(ob.ksp, &kt), "report");
  check(PCGetType(pc, &pt), "report");
  out.set_text(out.context, peridot_ksp_type, kt ? kt : "");
  out.set_text(out.context, peridot_pc_type, pt ? pt : "");
  if (pt && (std::string_view(pt) == PCLU || std::string_view(pt) == PCCHOLESKY)) {
    MatSolverType st = nullptr;
    check(PCFactorGetMatSolverType(pc, &st), "report");
    if (st) out.set_text(out.context, peridot_factor_package, st);
  }
  out.iterations = int(its);
  out.residual = residual;
  out.setup_seconds = setup;
  out.solve_seconds = solve_time;
  out.ranks = size();
  out.set_text(out.context, peridot_fallback, fallback.c_str());
  PetscInt left = 0;
  char** names = nullptr;
  char** values = nullptr;
  if (PetscOptionsLeftGet(ob.opts, &left, &names, &values) == 0) {
    for (PetscInt k = 0; k < left; ++k)
      if (!is_default(names[k])) out.set_text(out.context, peridot_unused_option, fmt::format("-{}", names[k]).c_str());
    PetscOptionsLeftRestore(ob.opts, &left, &names, &values);
  }
}



}  // namespace

extern "C" const PeridotParallelBackend* peridot_parallel_backend(void) {
  static const PeridotParallelBackend table{
      start,
      started,
      [] {
        int r = 0;
        if (started()) MPI_Comm_rank(PETSC_COMM_WORLD, &r);
        return r;
      },
      size,
      [](void* data, int count, int type, int op) { MPI_Allreduce(MPI_IN_PLACE, data, count, mpi_type(type), mpi_op(op), PETSC_COMM_WORLD); },
      [](void* data, int count, int type, int op) {
        int r = 0;
        MPI_Comm_rank(PETSC_COMM_WORLD, &r);
        if (r == 0) MPI_Reduce(MPI_IN_PLACE, data, count, mpi_type(type), mpi_op(op), 0, PETSC_COMM_WORLD);
        else MPI_Reduce(data, nullptr, count, mpi_type(type), mpi_op(op), 0, PETSC_COMM_WORLD);
      },
      [](const void* mine, void* all, int count, int type) { MPI_Allgather(mine, count, mpi_type(type), all, count, mpi_type(type), PETSC_COMM_WORLD); },
      [](const void* data, int count, int type, int to) { MPI_Send(data, count, mpi_type(type), to, 0, PETSC_COMM_WORLD); },
      [](void* data, int count, int type, int from) { MPI_Recv(data, count, mpi_type(type), from, 0, PETSC_COMM_WORLD, MPI_STATUS_IGNORE); },
      [](void* data, int count, int type) { MPI_Bcast(data, count, mpi_type(type), 0, PETSC_COMM_WORLD); },
      [](const int* send, int* recv) { MPI_Alltoall(send, 1, MPI_INT, recv, 1, MPI_INT, PETSC_COMM_WORLD); },
      [](const void* send, const int* send_count, const int* send_at, void* recv, const int* recv_count, const int* recv_at, int type) {
        MPI_Alltoallv(send, send_count, send_at, mpi_type(type), recv, recv_count, recv_at, mpi_type(type), PETSC_COMM_WORLD);
      },
      [](const uint64_t* in, uint64_t* out) { MPI_Exscan(in, out, 1, MPI_UINT64_T, MPI_SUM, PETSC_COMM_WORLD); },
      [] { MPI_Barrier(PETSC_COMM_WORLD); },
      [](int code) { MPI_Abort(PETSC_COMM_WORLD, code); },
      [](const void* piece, int mine, void* whole, const int* counts, const int* displs, int type, int scatter) -> int {
        return scatter ? MPI_Scatterv(whole, counts, displs, mpi_type(type), const_cast<void*>(piece), mine, mpi_type(type), 0, PETSC_COMM_WORLD)
                       : MPI_Gatherv(piece, mine, mpi_type(type), whole, counts, displs, mpi_type(type), 0, PETSC_COMM_WORLD);
      },
      [](int64_t local_size, const int64_t* ghost_local, const int* owner_rank, const int64_t* owner_index, int64_t ghosts,
         PeridotError* error) -> void* {
        PetscSF sf = nullptr;
        const int failed = guarded(error, [&] {
          std::vector<PetscInt> leaves(static_cast<std::size_t>(ghosts));
          std::vector<PetscSFNode> remote(static_cast<std::size_t>(ghosts));
          for (std::size_t g = 0; g < leaves.size(); ++g) {
            leaves[g] = PetscInt(ghost_local[g]);
            remote[g].rank = owner_rank[g];
            remote[g].index = PetscInt(owner_index[g]);
          }
          check(PetscSFCreate(PETSC_COMM_WORLD, &sf), "PetscSFCreate");
          check(PetscSFSetGraph(sf, PetscInt(local_size), PetscInt(leaves.size()), leaves.data(), PETSC_COPY_VALUES, remote.data(),
                                PETSC_COPY_VALUES),
                "PetscSFSetGraph");
          check(PetscSFSetUp(sf), "PetscSFSetUp");
        });
        if (failed && sf) PetscSFDestroy(&sf);
        return failed ? nullptr : static_cast<void*>(sf);
      },
      [](void* halo) {
        PetscSF sf = static_cast<PetscSF>(halo);
        PetscSFDestroy(&sf);
      },
      [](void* halo, double* const* arrays, size_t count, PeridotError* error) {
        return guarded(error, [&] {
          const PetscSF sf = static_cast<PetscSF>(halo);
          // Owned entries (roots) and ghost entries (leaves) of one array never overlap.
          for (size_t k = 0; k < count; ++k) check(PetscSFBcastBegin(sf, MPI_DOUBLE, arrays[k], arrays[k], MPI_REPLACE), "PetscSFBcastBegin");
          for (size_t k = 0; k < count; ++k) check(PetscSFBcastEnd(sf, MPI_DOUBLE, arrays[k], arrays[k], MPI_REPLACE), "PetscSFBcastEnd");
        });
      },
      [](void* halo, uint8_t* rows, size_t width, PeridotError* error) {
        return guarded(error, [&] {
          const PetscSF sf = static_cast<PetscSF>(halo);
          MPI_Datatype record;
          if (MPI_Type_contiguous(int(width), MPI_BYTE, &record) != MPI_SUCCESS || MPI_Type_commit(&record) != MPI_SUCCESS)
            throw std::runtime_error("Halo: MPI_Type_contiguous failed");
          const PetscErrorCode begin = PetscSFBcastBegin(sf, record, rows, rows, MPI_REPLACE);
          const PetscErrorCode end = begin ? begin : PetscSFBcastEnd(sf, record, rows, rows, MPI_REPLACE);
          MPI_Type_free(&record);
          check(end, "PetscSFBcast of records");
        });
      },
      [](const PeridotKspIn* in, PeridotKspOut* out, PeridotError* error) { return guarded(error, [&] { solve(*in, *out); }); },
      [](const PeridotKspIn* in, PeridotError* error) {
        return guarded(error, [&] {
          Objects ob;
          push_options(ob, *in, true);
          check(KSPCreate(PETSC_COMM_WORLD, &ob.ksp), "KSP");
          refuse_options(KSPSetFromOptions(ob.ksp), "options");
        });
      },
  };
  return &table;
}
