// peridot.io: YAML problem decks (validated), set-up of bodies from decks, VTU/PVD and CSV output.
export module peridot.io;
export import peridot.quadrature;
export import peridot.solvers;
export import :deck_reader;
export import :problem;
export import :deck;
export import :setup;
export import :static_setup;
export import :vtu;
export import :history_csv;
