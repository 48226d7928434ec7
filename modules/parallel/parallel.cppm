// peridot.parallel: MPI and PETSc under Peridot's solvers. One process is one rank; the same
// code runs on 1 rank (no mpirun) and on N.
export module peridot.parallel;
import peridot.std;
export import :runtime;
export import :bytes;
export import :row_block;
export import :ksp_solve;
export import :halo;
