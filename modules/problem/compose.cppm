export module peridot.problem:compose;
import peridot.std;
import peridot.io;
import peridot.deck;
import :setup;
import :static_setup;
import :osb_setup;
import :lps_dynamics_setup;

export namespace peridot {

// A problem ready to run: one alternative per solver row of the combination table.
using Composed = std::variant<Setup, StaticSetup, QuasiStaticSetup, OsbStaticSetup, NewmarkSetup>;

// The one place a validated problem becomes a runnable one; callers visit the result.
Composed compose(const Problem& problem);

}  // namespace peridot

namespace peridot {

Composed compose(const Problem& p) {
  const auto& row = combination_of(p);
  switch (row.solver) {
    case SolverKind::static_linear:
      if (row.model == ModelKind::osb) return setup_osb_static(p);
      return setup_static(p);
    case SolverKind::quasi_static: return setup_quasi_static(p);
    case SolverKind::newmark: return setup_newmark(p);
    case SolverKind::explicit_dynamics:
      if (row.model == ModelKind::lps) return setup_lps_explicit(p);
      break;
  }
  return setup(p);
}

}  // namespace peridot
