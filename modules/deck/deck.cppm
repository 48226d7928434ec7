// peridot.deck: deck text into a validated Problem (the schema), the table of supported seam
// combinations, and the memory checks a deck can fail before anything is allocated. Building
// a run from a Problem is peridot.problem's job; file formats live in peridot.io.
export module peridot.deck;
import peridot.std;
export import peridot.io;
export import peridot.quadrature;
export import peridot.implicit;
export import :spec;
export import :combinations;
export import :resources;
export import :parse;
export import :mesh_part;
export import :structured_part;
