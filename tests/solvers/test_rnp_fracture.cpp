#include <catch2/catch.hpp>
#include <cmath>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>
#include "../support/rnp_path.hpp"
import peridot.problem;

using namespace peridot;

namespace {

// Seed 002's pre-cracked plate at a reduced resolution: h = 0.5, delta = 4h (900-1100 nodes).
rnp_path::Path run_reduced(const std::string& deck) {
  const auto path = rnp_path::run(deck, 0.5, 4);
  for (const auto& r : path.steps)
    WARN(deck << ": load " << r.load << ", Newton " << r.iterations << " (" << r.linear_solver << "), max damage " << r.max_damage
              << ", softening bonds " << r.softening_bonds << ", cuts " << r.cuts);
  return path;
}

using rnp_path::first_softening;

}  // namespace

TEST_CASE("under soft loading the pre-cracked plate softens at the tip and then Newton cannot follow: unstable growth", "[slow]") {
  const auto path = run_reduced("precracked_soft.yaml");
  REQUIRE(path.failed);
  INFO(path.message);
  CHECK(path.message.find("did not converge") != std::string::npos);
  const double soft = first_softening(path);
  REQUIRE(soft > 0);
  // The elastic steps converge in a few Newton iterations each.
  for (const auto& r : path.steps)
    if (r.softening_bonds == 0) CHECK(r.iterations <= 4);
  const double last = path.steps.back().load;
  WARN("first softening at load " << soft << ", last converged load " << last);
  CHECK(last < soft + 0.3);
}

TEST_CASE("under hard loading on extension layers the same crack grows stably: every step converges as softening spreads", "[slow]") {
  const auto path = run_reduced("precracked_hard.yaml");
  INFO(path.message);
  REQUIRE_FALSE(path.failed);
  const double soft = first_softening(path);
  REQUIRE(soft > 0);
  // Stable growth: after softening starts, several further converged steps, with the softening
  // zone growing.
  std::size_t after = 0, grew = 0, previous = 0;
  for (const auto& r : path.steps) {
    if (r.load < soft) continue;
    ++after;
    grew += r.softening_bonds > previous;
    previous = r.softening_bonds;
  }
  CHECK(after >= 5);
  CHECK(grew >= 4);
}

TEST_CASE("the soft-loaded tension specimen starts to soften at a gauge-to-grip corner, then fails unstably", "[slow]") {
  Problem p = read_deck(std::string(PERIDOT_SOURCE_DIR) + "/data/decks/rnp/tension_specimen_soft.yaml");
  p.lattice.spacing = 2.0;  // the deck's h = 1 softens first at (15.5, 145.5), load 0.4
  p.horizon = 4 * p.lattice.spacing;
  auto s = setup_quasi_static(p);
  QuasiStaticSolver solver(s.body, s.model, s.boundaries, s.solver.options);
  VectorField u = zero_field(s.body.size());
  Vec3 first{};
  double first_load = -1;
  bool failed = false;
  try {
    solver.run(u, [&](const LoadStepReport& r, const VectorField& v) {
      if (first_load > 0 || r.softening_bonds == 0) return;
      std::vector<double> d;
      s.model.damage(s.body, v, d);
      std::size_t worst = 0;
      for (std::size_t i = 0; i < d.size(); ++i)
        if (d[i] > d[worst]) worst = i;
      first = s.body.points.position(worst), first_load = r.load;
    });
  } catch (const std::runtime_error&) {
    failed = true;
  }
  REQUIRE(first_load > 0);
  WARN("first softening at load " << first_load << " at (" << first[0] << ", " << first[1] << ")");
  CHECK(failed);
  // The paper: the crack initiates near the upper (loaded) grip. Here: on the gauge section's
  // edge, within two horizons below the upper junction y = 150.
  CHECK(first[1] > 150 - 2 * p.horizon);
  CHECK(first[1] < 150);
  CHECK(std::min(std::abs(first[0] - 3.5), std::abs(first[0] - 15.5)) < p.lattice.spacing);
}

namespace {

// The condition number the deck plate_2d_crack_condition.yaml reports, with its crack tip moved:
// cond_2 of the reduced -K at the converged state of the plate's load.
double condition_with_crack(double tip) {
  Problem p = read_deck(std::string(PERIDOT_SOURCE_DIR) + "/data/decks/rnp/plate_2d_crack_condition.yaml");
  std::get<CrackSegment>(p.cracks[0]).b[0] = tip;
  auto s = setup_quasi_static(p);
  QuasiStaticSolver solver(s.body, s.model, s.boundaries, s.solver.options);
  VectorField u = zero_field(s.body.size());
  return solver.run(u).back().condition;
}

}  // namespace

TEST_CASE("as a crack advances by 0.5h, 1h or 1.5h per step, cond(K) of the reduced tangent grows about linearly (Sec. 6.2.1)", "[slow]") {
  const double h = 0.1;
  for (double advance : {0.5 * h, 1.0 * h, 1.5 * h}) {
    std::vector<double> k, c;
    for (int step = 0; 0.8 + step * advance <= 1.4 + 1e-9; ++step) {
      k.push_back(step);
      c.push_back(condition_with_crack(0.8 + step * advance));
    }
    // Least-squares line through (step, cond) and how much of the variation it explains.
    const double n = double(k.size());
    double mk = 0, mc = 0;
    for (std::size_t i = 0; i < k.size(); ++i) mk += k[i] / n, mc += c[i] / n;
    double skk = 0, skc = 0, scc = 0;
    for (std::size_t i = 0; i < k.size(); ++i) skk += (k[i] - mk) * (k[i] - mk), skc += (k[i] - mk) * (c[i] - mc), scc += (c[i] - mc) * (c[i] - mc);
    const double slope = skc / skk, r2 = skc * skc / (skk * scc);
    WARN("advance " << advance / h << " h per step: cond " << c.front() << " -> " << c.back() << " over " << k.size() - 1
                    << " steps, slope " << slope << " per step, R^2 " << r2);
    CHECK(slope > 0);
    CHECK(r2 > 0.9);
  }
}
