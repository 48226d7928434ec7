// peridot.implicit: the solvers that factorise or iterate on assembled systems -- static LPS
// (UMFPACK, PETSc), quasi-static Newton and Ceres, P1 elasticity, static OSB -- and so bring
// SuiteSparse, Ceres, MPI and PETSc with them. Explicit dynamics and Newmark (peridot.solvers)
// need none of these.
export module peridot.implicit;
import peridot.std;
export import peridot.solvers;
export import peridot.parallel;
export import :replicated_solve;
export import :static_lps;
export import :newton_rows;
export import :quasi_static;
export import :p1_elasticity;
export import :osb_static;
