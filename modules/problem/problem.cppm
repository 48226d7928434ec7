// peridot.problem: a validated deck turned into a runnable problem. The deck schema, the table
// of supported seam combinations, memory checks before allocation, the set-up of explicit
// and static runs, and refinement studies. File formats live in peridot.io.
export module peridot.problem;
export import peridot.io;
export import peridot.quadrature;
export import peridot.solvers;
export import :spec;
export import :combinations;
export import :resources;
export import :deck;
export import :setup;
export import :static_setup;
export import :osb_setup;
export import :lps_dynamics_setup;
export import :slab_setup;
export import :compose;
export import :study;
