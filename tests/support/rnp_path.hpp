#pragma once
// Test-side helper for seed 002 load paths: runs a quasi-static deck (optionally coarsened)
// and keeps every converged increment, and whether and why the path stopped.
#include <stdexcept>
#include <string>
#include <vector>
import peridot.problem;

namespace rnp_path {

struct Path {
  std::vector<peridot::LoadStepReport> steps;
  bool failed = false;
  std::string message;
};

// spacing > 0 coarsens the deck to that h at the same delta / h ratio of `factor` (0: the deck's).
inline Path run(const std::string& deck, double spacing = 0, double factor = 0) {
  peridot::Problem p = peridot::read_deck(std::string(PERIDOT_SOURCE_DIR) + "/data/decks/rnp/" + deck);
  if (spacing > 0) {
    const double m = factor > 0 ? factor : p.horizon / p.lattice.spacing;
    p.lattice.spacing = spacing;
    p.horizon = m * spacing;
  }
  auto s = peridot::setup_quasi_static(p);
  peridot::QuasiStaticSolver solver(s.body, s.model, s.boundaries, s.solver.options);
  auto u = peridot::zero_field(s.body.size());
  Path path;
  try {
    solver.run(u, [&](const peridot::LoadStepReport& r, const peridot::VectorField&) { path.steps.push_back(r); });
  } catch (const std::runtime_error& e) {
    path.failed = true;
    path.message = e.what();
  }
  return path;
}

// Load factor of the first converged increment with a softening bond; -1 if none.
inline double first_softening(const Path& p) {
  for (const auto& r : p.steps)
    if (r.softening_bonds > 0) return r.load;
  return -1;
}

}  // namespace rnp_path
