module;
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>
#include <fmt/core.h>
export module peridot.problem:setup;
import peridot.io;
import peridot.solvers;
import :spec;
import :resources;

export namespace peridot {

// Every force model a deck can name; the app visits it once and runs a solver
// instantiated on the concrete type.
using AnyModel = std::variant<Pmb>;

struct Setup {
  Body body;
  AnyModel model;
  std::vector<Boundary> boundaries;
  TimeStep time_step;
};

// Builds the body (lattice, bonds, pre-cracks, no-fail flags), the model, the boundary
// point sets and the time step. Throws DeckError for problems only visible at this stage
// (an empty geometry or a boundary region that selects no point).
Setup setup(const Problem& problem);

}  // namespace peridot

namespace peridot {

Setup setup(const Problem& p) {
  Setup s{};
  require_lattice_fits(p.body.bounds(), p.lattice.spacing, p.dim, 0.0);
  try {
    s.body.points = lattice(p.body, p.lattice);
  } catch (const std::invalid_argument& e) {
    throw DeckError(fmt::format("geometry.body: {} (discretization.spacing = {:g} m)", e.what(), p.lattice.spacing));
  }
  require_bonds_fit(s.body.size(), p.dim, p.horizon, p.lattice.spacing, bytes_per_bond_explicit);
  if (p.precrack_damage) {
    // Bonds across a pre-crack exist and start broken, so damage shows the pre-crack.
    s.body.bonds = build_bonds(s.body.points, {.horizon = p.horizon, .partial_volume = p.partial_volume});
    cut_bonds(s.body.points, s.body.bonds, p.cracks);
  } else {
    s.body.bonds = build_bonds(s.body.points, {.horizon = p.horizon, .partial_volume = p.partial_volume, .cracks = p.cracks});
  }
  s.body.density = p.material.density;
  s.body.no_fail.assign(s.body.size(), 0);
  for (const auto& region : p.no_fail)
    for (auto i : select_points(s.body.points, region)) s.body.no_fail[i] = 1;

  const Pmb pmb = Pmb::from_elastic(p.material.youngs_modulus, p.material.fracture_energy, p.horizon, p.material.kinematics);
  s.model = pmb;
  for (std::size_t k = 0; k < p.boundaries.size(); ++k) {
    const auto& spec = p.boundaries[k];
    Boundary bc{spec.name, spec.kind, select_points(s.body.points, spec.region), spec.value, spec.components, spec.history};
    if (bc.points.empty())
      throw DeckError(fmt::format("boundaries[{}] ('{}'): region selects no point of the body", k, spec.name));
    s.boundaries.push_back(std::move(bc));
  }
  const double estimate = std::visit([&](const auto& m) { return m.stable_time_step(s.body); }, s.model);
  try {
    s.time_step = choose_time_step(estimate, p.solver);
  } catch (const std::invalid_argument& e) {
    throw DeckError(e.what());
  }
  return s;
}

}  // namespace peridot
