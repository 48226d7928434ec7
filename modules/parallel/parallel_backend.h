// The PETSc and MPI calls of peridot.parallel, behind one table of C functions. The module
// links neither library: the table lives in libperidot_petsc_backend.so (petsc_backend.cpp),
// which the module opens at the first call that needs MPI or PETSc (start, a distributed solve).
// A serial run that never solves on PETSc loads neither, and its start-up skips the ~100 shared
// libraries PETSc brings (MUMPS, hypre, ScaLAPACK, Trilinos, HDF5 over Open MPI).
//
// Plain C types only, so the module's global fragment includes no standard C++ header. Calls
// that can fail fill a PeridotError; the module throws it again as the exception the code
// inside threw (kind: 1 std::runtime_error, 2 std::invalid_argument, 3 std::length_error).
#pragma once
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

enum PeridotType { peridot_u8, peridot_i16, peridot_i32, peridot_i64, peridot_u64, peridot_f64 };
enum PeridotOp { peridot_sum, peridot_min, peridot_max };

struct PeridotError {
  int kind;  // 0: no error
  char message[4096];
};

// One solve's matrix block (this rank's CSR rows, global columns), options and answer.
struct PeridotKspIn {
  int64_t global_rows, rows, nonzeros;
  const int64_t* offset;  // rows + 1
  const int64_t* column;
  const double* value;
  const double* rhs;
  void (*release_matrix)(void* context);  // called once PETSc holds its own copy of column and value
  void* context;
  const char* options;       // the deck's
  const char* command_line;  // the command line's (they win)
  int64_t direct_below, fallback_nonzeros;
  double rtol;
  int max_iterations, gmres_restart, refinement;
  int own_rows;  // 1: x holds this rank's rows; 0: every row
};

enum PeridotKspText { peridot_ksp_type, peridot_pc_type, peridot_factor_package, peridot_fallback, peridot_unused_option };

struct PeridotKspOut {
  double* x;  // rows or global_rows values, the caller's
  int iterations, ranks;
  double residual, setup_seconds, solve_seconds;
  void (*set_text)(void* context, int which, const char* text);  // which: PeridotKspText (unused options: one call each)
  void* context;
};

struct PeridotParallelBackend {
  int (*start)(int isolated, struct PeridotError* error);  // PETSc and MPI, once per process
  int (*started)(void);
  int (*rank)(void);
  int (*size)(void);
  void (*allreduce)(void* data, int count, int type, int op);       // in place on every rank
  void (*reduce_to_root)(void* data, int count, int type, int op);  // in place on rank 0
  void (*allgather)(const void* mine, void* all, int count, int type);
  void (*send)(const void* data, int count, int type, int to);
  void (*recv)(void* data, int count, int type, int from);
  void (*bcast)(void* data, int count, int type);  // from rank 0
  void (*alltoall_int)(const int* send, int* recv);
  void (*alltoallv)(const void* send, const int* send_count, const int* send_at, void* recv, const int* recv_count, const int* recv_at, int type);
  void (*exscan_sum_u64)(const uint64_t* in, uint64_t* out);
  void (*barrier)(void);
  void (*abort)(int code);
  int (*gatherv)(const void* piece, int mine, void* whole, const int* counts, const int* displs, int type, int scatter);  // MPI's code
  void* (*halo_create)(int64_t local_size, const int64_t* ghost_local, const int* owner_rank, const int64_t* owner_index, int64_t ghosts,
                       struct PeridotError* error);
  void (*halo_destroy)(void* halo);
  int (*halo_exchange)(void* halo, double* const* arrays, size_t count, struct PeridotError* error);
  int (*halo_exchange_records)(void* halo, uint8_t* rows, size_t width, struct PeridotError* error);
  int (*ksp_solve)(const struct PeridotKspIn* in, struct PeridotKspOut* out, struct PeridotError* error);
  int (*check_ksp_options)(const struct PeridotKspIn* in, struct PeridotError* error);
};

const struct PeridotParallelBackend* peridot_parallel_backend(void);
// Where the build put the backend (backend_path.cpp); PERIDOT_PETSC_BACKEND overrides it.
const char* peridot_petsc_backend_path(void);

#ifdef __cplusplus
}
#endif
