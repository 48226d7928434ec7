// peridot.solvers: boundary conditions, load histories, explicit dynamics (velocity Verlet,
// central differences) and implicit Newmark (matrix-free). The solvers with assembled systems
// and their back ends are peridot.implicit.
export module peridot.solvers;
import peridot.std;
export import peridot.models;
export import :time_function;
export import :boundary;
export import :explicit_dynamics;
export import :newmark;
