// Where the build put the PETSc and MPI backend (parallel_backend.h): the module opens it from
// here unless PERIDOT_PETSC_BACKEND names another file.
#include "parallel_backend.h"

extern "C" const char* peridot_petsc_backend_path(void) { return PERIDOT_PETSC_BACKEND_PATH; }
