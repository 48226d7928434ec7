// peridot.solvers: boundary conditions, load histories and time/load loops.
export module peridot.solvers;
export import peridot.models;
export import peridot.parallel;
export import :time_function;
export import :boundary;
export import :explicit_dynamics;
export import :static_lps;
export import :quasi_static;
export import :p1_elasticity;
export import :osb_static;
export import :newmark;
