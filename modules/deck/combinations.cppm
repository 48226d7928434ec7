export module peridot.deck:combinations;
import peridot.std;
import peridot.io;
import :spec;

export namespace peridot {

// The five seams a deck chooses an implementation for (see shared/design.md; observers and
// the sixth, bonds, have a single implementation per discretization today).
enum class Seam { discretization, quadrature, model, boundary_method, solver };

// One runnable composition: an implementation on each seam.
struct Combination {
  DiscretizationKind discretization;
  QuadratureKind quadrature;
  ModelKind model;
  BoundaryMethodKind boundary_method;
  SolverKind solver;
  const char* what;
};

// The table of supported combinations: the one place that says what runs with what. Adding a
// method adds its rows here; an unsupported combination is a deck error naming both keys.
inline constexpr std::array supported_combinations{
    Combination{DiscretizationKind::lattice, QuadratureKind::volume, ModelKind::pmb, BoundaryMethodKind::layers,
                SolverKind::explicit_dynamics, "PMB dynamics, nodal volumes"},
    Combination{DiscretizationKind::lattice, QuadratureKind::partial_volume, ModelKind::pmb, BoundaryMethodKind::layers,
                SolverKind::explicit_dynamics, "PMB dynamics, partial volumes at the horizon edge"},
    Combination{DiscretizationKind::lattice, QuadratureKind::gmls, ModelKind::lps, BoundaryMethodKind::collar_traction,
                SolverKind::static_linear, "static LPS, GMLS weights, Dirichlet collar and nonlocal traction (seed 000 Sec. 5)"},
    Combination{DiscretizationKind::lattice, QuadratureKind::volume, ModelKind::lps, BoundaryMethodKind::collar_traction,
                SolverKind::static_linear, "static LPS, nodal volumes (for comparison with GMLS)"},
    Combination{DiscretizationKind::lattice, QuadratureKind::gmls, ModelKind::lps, BoundaryMethodKind::collar_traction,
                SolverKind::newmark, "dynamic LPS fracture, implicit Newmark with break sub-iteration, GMLS weights, nonlocal traction (seed 000 Sec. 6)"},
    Combination{DiscretizationKind::lattice, QuadratureKind::volume, ModelKind::lps, BoundaryMethodKind::collar_traction,
                SolverKind::newmark, "dynamic LPS fracture, implicit Newmark, nodal volumes (the grid-imprinting comparison)"},
    Combination{DiscretizationKind::lattice, QuadratureKind::gmls, ModelKind::lps, BoundaryMethodKind::collar_traction,
                SolverKind::explicit_dynamics, "dynamic LPS fracture, velocity Verlet, GMLS weights, nonlocal traction"},
    Combination{DiscretizationKind::lattice, QuadratureKind::volume, ModelKind::lps, BoundaryMethodKind::collar_traction,
                SolverKind::explicit_dynamics, "dynamic LPS fracture, velocity Verlet, nodal volumes"},
    Combination{DiscretizationKind::lattice, QuadratureKind::volume, ModelKind::rnp, BoundaryMethodKind::layers,
                SolverKind::quasi_static, "quasi-static RNP, Newton on the explicit tangent (seed 002), nodal volumes"},
    Combination{DiscretizationKind::lattice, QuadratureKind::partial_volume, ModelKind::rnp, BoundaryMethodKind::layers,
                SolverKind::quasi_static, "quasi-static RNP, partial volumes"},
    Combination{DiscretizationKind::lattice, QuadratureKind::volume, ModelKind::rnp, BoundaryMethodKind::layers,
                SolverKind::explicit_dynamics, "RNP dynamics, nodal volumes"},
    Combination{DiscretizationKind::lattice, QuadratureKind::partial_volume, ModelKind::rnp, BoundaryMethodKind::layers,
                SolverKind::explicit_dynamics, "RNP dynamics, partial volumes"},
    Combination{DiscretizationKind::mesh, QuadratureKind::element, ModelKind::rnp, BoundaryMethodKind::layers,
                SolverKind::explicit_dynamics, "nodal finite-element RNP dynamics on a triangle or tetrahedral mesh, V_ij weights (seed 003)"},
    Combination{DiscretizationKind::mesh, QuadratureKind::element, ModelKind::rnp, BoundaryMethodKind::layers,
                SolverKind::quasi_static, "quasi-static RNP on a triangle or tetrahedral mesh, V_ij weights"},
    Combination{DiscretizationKind::mesh, QuadratureKind::element, ModelKind::pmb, BoundaryMethodKind::layers,
                SolverKind::explicit_dynamics, "PMB dynamics on a triangle or tetrahedral mesh, V_ij weights with J = 1"},
    Combination{DiscretizationKind::lattice, QuadratureKind::cell_area, ModelKind::osb, BoundaryMethodKind::fictitious_taylor,
                SolverKind::static_linear, "static OSB, exact cell-area weights, fictitious Taylor nodes and Lagrange rows (seed 004)"},
    Combination{DiscretizationKind::lattice, QuadratureKind::cell_area, ModelKind::osb, BoundaryMethodKind::outermost_nodes,
                SolverKind::static_linear, "static OSB without correction: conditions on the outermost nodes (seed 004's comparison)"},
    Combination{DiscretizationKind::lattice, QuadratureKind::cell_area, ModelKind::osb, BoundaryMethodKind::layers,
                SolverKind::explicit_dynamics, "OSB dynamics, exact cell-area weights"},
    Combination{DiscretizationKind::lattice, QuadratureKind::volume, ModelKind::osb, BoundaryMethodKind::layers,
                SolverKind::explicit_dynamics, "OSB dynamics, nodal volumes"},
};

// What a solver offers beyond a run on one process: restart from a checkpoint, and a set-up by
// parts on N MPI ranks (setup_slab). Newmark and quasi-static runs are distributed but do not
// restart. The static solvers do neither: they build their parts themselves (setup_static_part,
// setup_osb_static_part).
struct SolverCapabilities {
  bool restart = false;
  bool distributed = false;
};
constexpr SolverCapabilities capabilities(SolverKind s) {
  const bool explicit_run = s == SolverKind::explicit_dynamics;
  return {.restart = explicit_run, .distributed = explicit_run || s == SolverKind::newmark || s == SolverKind::quasi_static};
}

// Deck names of a seam's implementations, in the order of its enum.
const std::vector<std::string>& seam_names(Seam seam);
// The deck key that selects a seam's implementation.
const char* seam_key(Seam seam);
std::size_t index_of(const std::vector<std::string>& names, const std::string& name);

// Throws a DeckError naming both keys when no row of the table has both choices.
void require_supported_pair(Seam a, std::size_t a_value, Seam b, std::size_t b_value);
// The implementation on `wanted` of the first supported row with `given` = value: the default
// when the deck leaves `wanted` out.
std::size_t default_choice(Seam given, std::size_t value, Seam wanted);

// The row a whole problem runs as; throws a DeckError if there is none.
const Combination& combination_of(const Problem& problem);

}  // namespace peridot

namespace peridot {

namespace {

std::size_t value_on(const Combination& c, Seam s) {
  switch (s) {
    case Seam::discretization: return std::size_t(c.discretization);
    case Seam::quadrature: return std::size_t(c.quadrature);
    case Seam::model: return std::size_t(c.model);
    case Seam::boundary_method: return std::size_t(c.boundary_method);
    case Seam::solver: return std::size_t(c.solver);
  }
  return 0;
}

std::string row_names(const Combination& c) {
  return fmt::format("{} + {} + {} + {} + {}", seam_names(Seam::solver)[std::size_t(c.solver)], seam_names(Seam::model)[std::size_t(c.model)],
                     seam_names(Seam::quadrature)[std::size_t(c.quadrature)], seam_names(Seam::boundary_method)[std::size_t(c.boundary_method)],
                     seam_names(Seam::discretization)[std::size_t(c.discretization)]);
}

}  // namespace

const std::vector<std::string>& seam_names(Seam seam) {
  static const std::vector<std::string> discretization{"lattice", "mesh"}, quadrature{"volume", "partial_volume", "gmls", "element", "cell_area"},
      model{"pmb", "lps", "rnp", "osb"}, boundary{"layers", "collar_traction", "fictitious_taylor", "outermost_nodes"}, solver{"explicit", "static", "quasi_static", "newmark"};
  switch (seam) {
    case Seam::discretization: return discretization;
    case Seam::quadrature: return quadrature;
    case Seam::model: return model;
    case Seam::boundary_method: return boundary;
    case Seam::solver: return solver;
  }
  return solver;
}

const char* seam_key(Seam seam) {
  switch (seam) {
    case Seam::discretization: return "discretization.type";
    case Seam::quadrature: return "discretization.quadrature";
    case Seam::model: return "material.model";
    case Seam::boundary_method: return "boundary_method";
    case Seam::solver: return "solver.type";
  }
  return "";
}

std::size_t index_of(const std::vector<std::string>& names, const std::string& name) {
  for (std::size_t k = 0; k < names.size(); ++k)
    if (names[k] == name) return k;
  throw DeckError(fmt::format("'{}' is not an implementation name", name));
}

void require_supported_pair(Seam a, std::size_t av, Seam b, std::size_t bv) {
  for (const auto& c : supported_combinations)
    if (value_on(c, a) == av && value_on(c, b) == bv) return;
  std::string rows;
  for (const auto& c : supported_combinations) rows += fmt::format("\n  {} ({})", row_names(c), c.what);
  throw DeckError(fmt::format("{} = '{}' with {} = '{}' is not a supported combination; supported (solver + model + quadrature + "
                              "boundary method + discretization):{}",
                              seam_key(b), seam_names(b)[bv], seam_key(a), seam_names(a)[av], rows));
}

std::size_t default_choice(Seam given, std::size_t value, Seam wanted) {
  for (const auto& c : supported_combinations)
    if (value_on(c, given) == value) return value_on(c, wanted);
  return 0;
}

const Combination& combination_of(const Problem& p) {
  for (const auto& c : supported_combinations)
    if (c.discretization == p.discretization_kind && c.quadrature == p.quadrature_kind && c.model == p.material.model &&
        c.boundary_method == p.boundary_method && c.solver == p.solver_kind)
      return c;
  require_supported_pair(Seam::solver, std::size_t(p.solver_kind), Seam::model, std::size_t(p.material.model));
  require_supported_pair(Seam::model, std::size_t(p.material.model), Seam::quadrature, std::size_t(p.quadrature_kind));
  require_supported_pair(Seam::solver, std::size_t(p.solver_kind), Seam::boundary_method, std::size_t(p.boundary_method));
  require_supported_pair(Seam::discretization, std::size_t(p.discretization_kind), Seam::quadrature, std::size_t(p.quadrature_kind));
  require_supported_pair(Seam::discretization, std::size_t(p.discretization_kind), Seam::model, std::size_t(p.material.model));
  require_supported_pair(Seam::discretization, std::size_t(p.discretization_kind), Seam::solver, std::size_t(p.solver_kind));
  throw DeckError("this combination of solver, model, quadrature and boundary method is not supported");
}

}  // namespace peridot
