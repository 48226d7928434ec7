// Seed 000 Sec. 6 from the shipped decks (data/decks/lps_dynamic), run in-process:
// the glass plate against Table 2 (implicit Newmark, and velocity Verlet on the same deck)
// and the coarsest expanding cylinder against Table 5.
#include <catch2/catch.hpp>
#include <omp.h>

#include <cmath>
#include <string>
#include <variant>
#include <vector>
#include "../support/same.hpp"
import peridot.problem;
import peridot.analysis;

using namespace peridot;

namespace {

Problem deck(const std::string& name) { return read_deck(std::string(PERIDOT_SOURCE_DIR) + "/data/decks/lps_dynamic/" + name + ".yaml"); }

struct GlassRun {
  TipSummary tip;
  std::vector<double> damage, uy;
  Body body;
};

// Every 16 steps (1 us), as the deck's crack_tip observer.
template <class Solver>
GlassRun track(Solver& solver, Body& body, std::size_t steps) {
  State state(body.size());
  solver.initialize(state);
  CrackTipTracker tracker({.damage_threshold = 0.35, .origin = {0.05, 0, 0}, .direction = Vec3{1, 0, 0}});
  std::vector<double> phi;
  for (std::size_t k = 0; k < steps; ++k) {
    solver.step(state);
    if (state.step % 16 == 0) {
      damage(body, phi);
      tracker.update(body.points, phi, state.time);
    }
  }
  return {tracker.summary(), damage(body), state.u[1], body};
}

GlassRun glass_newmark() {
  auto c = compose(deck("glass_plate"));
  auto& s = std::get<NewmarkSetup>(c);
  NewmarkSolver<Lps> solver(s.body, s.model, s.boundaries, s.options);
  return track(solver, s.body, solver.steps());
}

GlassRun glass_explicit(int threads) {
  omp_set_num_threads(threads);
  auto c = compose(deck("glass_plate_explicit"));
  auto& s = std::get<Setup>(c);
  ExplicitSolver<Lps> solver(s.body, std::get<Lps>(s.model), s.boundaries, s.time_step);
  auto r = track(solver, s.body, s.time_step.steps);
  omp_set_num_threads(2);
  return r;
}

// Table 2, SB at delta = 2 mm: branch at x = 0.070 m, t = 21.8 us, max speed 2250 m/s; the
// issue's targets are +-10 %, +-15 % and +-20 %.
void check_table2(const GlassRun& r) {
  REQUIRE(r.tip.branch.has_value());
  const auto& b = *r.tip.branch;
  INFO("branch at x = " << b.position[0] << " m, t = " << b.time * 1e6 << " us; max speed " << r.tip.max_speed << " m/s");
  CHECK(std::abs(b.position[0] - 0.070) <= 0.10 * 0.070);
  CHECK(std::abs(b.time - 21.8e-6) <= 0.15 * 21.8e-6);
  CHECK(std::abs(r.tip.max_speed - 2250) <= 0.20 * 2250);
  // Below the Rayleigh speed, as any running crack.
  CHECK(r.tip.max_speed < 3102);
  // One branch, both arms: cracked points well above and below mid-height past the branch.
  std::size_t above = 0, below = 0;
  for (std::size_t i = 0; i < r.body.size(); ++i) {
    if (r.damage[i] <= 0.35 || r.body.points.x[0][i] < b.position[0] + 0.005) continue;
    above += r.body.points.x[1][i] > 0.003;
    below += r.body.points.x[1][i] < -0.003;
  }
  CHECK(above > 10);
  CHECK(below > 10);
  // Nothing cracks away from the path: the left half behind the notch tip stays intact.
  for (std::size_t i = 0; i < r.body.size(); ++i)
    if (r.body.points.x[0][i] < 0.045) REQUIRE((r.damage[i] <= 0.35 || std::abs(r.body.points.x[1][i]) < 0.002));
}

}  // namespace

// [long]: about a minute of simulation on 2 cores, more when ctest runs another test beside it.
TEST_CASE("glass plate, Newmark and GMLS: one branch within Table 2 tolerances", "[long]") {
  check_table2(glass_newmark());
}

// [long]: about a minute of simulation on 2 cores, more when ctest runs another test beside it.
TEST_CASE("glass plate, Verlet: same branch, same bits on 1 and 2 threads", "[long]") {
  const auto one = glass_explicit(1);
  check_table2(one);
  const auto two = glass_explicit(2);
  CHECK(same::difference(one.damage, two.damage, "one.damage") == "");
  CHECK(same::difference(one.uy, two.uy, "one.uy") == "");
}

// [long]: about a minute of simulation on 2 cores, more when ctest runs another test beside it.
TEST_CASE("the coarsest cylinder breaks into 10 to 17 large fragments", "[long]") {
  auto c = compose(deck("cylinder"));
  auto& s = std::get<NewmarkSetup>(c);
  NewmarkSolver<Lps> solver(s.body, s.model, s.boundaries, s.options);
  State state(s.body.size());
  solver.initialize(state);
  for (std::size_t k = 0; k < solver.steps(); ++k) solver.step(state);
  // The deck's rule: a large fragment holds at least 1 % of the ring's mass.
  const auto f = count_fragments(s.body, {.large_mass_fraction = 0.01});
  INFO(f.large << " large fragments of " << f.count);
  CHECK(f.large >= 10);
  CHECK(f.large <= 17);
  // The ring moved outwards, by less than free flight under the whole pressure impulse would
  // carry it: p0 t0 2 pi r_i / mass x t_end (hoop stress only slows it).
  const double impulse = 2.5e9 * 1e-5 * 2 * 3.141592653589793 * 0.08;
  double mass = 0;
  for (std::size_t i = 0; i < s.body.size(); ++i) mass += s.body.density * s.body.points.volume[i];
  const double free_flight = impulse / mass * 2e-4;
  double mean_radial = 0;
  for (std::size_t i = 0; i < s.body.size(); ++i) {
    const double x = s.body.points.x[0][i], y = s.body.points.x[1][i], r = std::hypot(x, y);
    mean_radial += (state.u[0][i] * x + state.u[1][i] * y) / r / double(s.body.size());
  }
  INFO("mean radial displacement " << mean_radial << " m; free flight " << free_flight << " m");
  CHECK(mean_radial > 0.25 * free_flight);
  CHECK(mean_radial < free_flight);
}
