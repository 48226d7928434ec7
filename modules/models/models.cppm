// peridot.models: material models (force, energy, later tangent) as small types
// constrained by a concept, plus model-independent bond measures (damage, stress).
export module peridot.models;
import peridot.std;
export import :body;
export import :elastic;
export import :pmb_bond;
export import :pmb_stencil;
export import :lean_records;
export import :pmb;
export import :lps;
export import :rnp;
export import :osb;
export import :bond_measures;
export import :elastic_solutions;
