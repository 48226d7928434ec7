// peridot.problem: a validated Problem (peridot.deck) built into a runnable one: bodies,
// models, boundaries and time steps for every flavour, the one composition switch
// (compose), the distributed set-up of explicit runs, and refinement studies.
export module peridot.problem;
import peridot.std;
export import peridot.deck;
export import :setup;
export import :static_setup;
export import :osb_setup;
export import :lps_dynamics_setup;
export import :slab_setup;
export import :compose;
export import :study;
