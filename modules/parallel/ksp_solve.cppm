module;
#include "parallel_backend.h"

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

// The backend's view of a solve: the block's arrays and the options, as parallel_backend.h has them.
PeridotKspIn ksp_in(const RowBlock& blk, const KspOptions& o, bool own_rows) {
  PeridotKspIn in{};
  in.global_rows = blk.global_rows;
  in.rows = blk.rows();
  in.nonzeros = std::int64_t(blk.column.size());
  in.offset = blk.offset.data();
  in.column = blk.column.data();
  in.value = blk.value.data();
  in.rhs = blk.rhs.data();
  in.options = o.options.c_str();
  in.command_line = command_line_options().c_str();
  in.direct_below = o.direct_below;
  in.fallback_nonzeros = o.fallback_nonzeros;
  in.rtol = o.rtol;
  in.max_iterations = o.max_iterations;
  in.gmres_restart = o.gmres_restart;
  in.refinement = o.refinement;
  in.own_rows = own_rows ? 1 : 0;
  return in;
}

}  // namespace

std::vector<double> ksp_solve(RowBlock blk, const KspOptions& o, KspReport* report, SolutionRows rows) {
  start();
  const bool own = rows == SolutionRows::own;
  std::vector<double> x(std::size_t(own ? blk.rows() : blk.global_rows));
  PeridotKspIn in = ksp_in(blk, o, own);
  // The block's arrays go as soon as PETSc holds its own copy.
  in.release_matrix = [](void* block) {
    auto* b = static_cast<RowBlock*>(block);
    std::vector<std::int64_t>().swap(b->column);
    std::vector<double>().swap(b->value);
  };
  in.context = &blk;
  KspReport got;
  PeridotKspOut out{};
  out.x = x.data();
  out.set_text = [](void* r, int which, const char* text) {
    auto& rep = *static_cast<KspReport*>(r);
    if (which == peridot_ksp_type) rep.ksp = text;
    else if (which == peridot_pc_type) rep.pc = text;
    else if (which == peridot_factor_package) rep.factor_package = text;
    else if (which == peridot_fallback) rep.fallback = text;
    else rep.unused_options.push_back(text);
  };
  out.context = &got;
  PeridotError error{};
  if (backend().ksp_solve(&in, &out, &error)) rethrow(error);
  if (report) {
    got.iterations = out.iterations;
    got.residual = out.residual;
    got.setup_seconds = out.setup_seconds;
    got.solve_seconds = out.solve_seconds;
    got.ranks = out.ranks;
    *report = std::move(got);
  }
  return x;
}

void check_ksp_options(const KspOptions& o) {
  start();
  const RowBlock none;
  const PeridotKspIn in = ksp_in(none, o, false);
  PeridotError error{};
  if (backend().check_ksp_options(&in, &error)) rethrow(error);
}

}  // namespace peridot::parallel
