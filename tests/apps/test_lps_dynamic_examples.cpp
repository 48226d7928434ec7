// Seed 000 Sec. 6 from the shipped decks (data/decks/lps_dynamic), run in-process:
// the glass plate against Table 2 (implicit Newmark, and velocity Verlet on the same deck)
// and the coarsest expanding cylinder against Table 5.
#include <catch2/catch.hpp>
#include <omp.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <variant>
#include <vector>
#include "../support/deck_text.hpp"
#include "../support/same.hpp"
import peridot.problem;
import peridot.analysis;

using namespace peridot;

namespace {

Problem deck(const std::string& name) { return read_deck(std::string(PERIDOT_SOURCE_DIR) + "/data/decks/lps_dynamic/" + name + ".yaml"); }

// The default suite's glass plate: h = 1 mm and delta = 4h = 4 mm (the paper's delta / h), dt
// doubled to 1.25e-7 s with it (the explicit deck's stable estimate doubles too, to 4.0e-7 s):
// a quarter of the points, half the steps. The tracker samples every 8 steps, 1 us, as the
// deck's every 16.
Problem coarse_glass(const std::string& name) {
  const std::filesystem::path file = std::string(PERIDOT_SOURCE_DIR) + "/data/decks/lps_dynamic/" + name + ".yaml";
  auto text = deck_text::replaced(deck_text::file_text(file), "spacing: 5.0e-4 ", "spacing: 1.0e-3 ");
  text = deck_text::replaced(text, "dt: 6.25e-8 ", "dt: 1.25e-7 ");
  return parse_deck(text, file.string(), file.parent_path());
}

struct GlassRun {
  TipSummary tip;
  std::vector<double> damage, uy;
  Body body;
};

// Every `every` steps (the decks' 16: 1 us), as the deck's crack_tip observer.
template <class Solver>
GlassRun track(Solver& solver, Body& body, std::size_t steps, std::size_t every = 16) {
  State state(body.size());
  solver.initialize(state);
  CrackTipTracker tracker({.damage_threshold = 0.35, .origin = {0.05, 0, 0}, .direction = Vec3{1, 0, 0}});
  std::vector<double> phi;
  for (std::size_t k = 0; k < steps; ++k) {
    solver.step(state);
    if (state.step % every == 0) {
      damage(body, phi);
      tracker.update(body.points, phi, state.time);
    }
  }
  return {tracker.summary(), damage(body), state.u[1], body};
}

GlassRun glass_newmark(const Problem& p, std::size_t every = 16) {
  auto c = compose(p);
  auto& s = std::get<NewmarkSetup>(c);
  NewmarkSolver<Lps> solver(s.body, s.model, s.boundaries, s.options);
  return track(solver, s.body, solver.steps(), every);
}

GlassRun glass_explicit(const Problem& p, int threads, std::size_t every = 16) {
  omp_set_num_threads(threads);
  auto c = compose(p);
  auto& s = std::get<Setup>(c);
  ExplicitSolver<Lps> solver(s.body, std::get<Lps>(s.model), s.boundaries, s.time_step);
  auto r = track(solver, s.body, s.time_step.steps, every);
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

// [paper]: about a minute of simulation on 2 cores, more when ctest runs another test beside it;
// the default suite runs it at h = 1 mm below.
TEST_CASE("glass plate, Newmark and GMLS: one branch within Table 2 tolerances", "[paper]") {
  check_table2(glass_newmark(deck("glass_plate")));
}

// Table 2's quantities move little with the horizon (SB: x 0.070 -> 0.068 m, t 21.8 -> 22.5 us,
// speed 2250 -> 2000 m/s from delta = 2 to 1 mm), well inside the windows; so the coarse plate
// at delta = 4 mm is held to the same windows around the delta = 2 mm column. Measured at
// delta = 4 mm: Newmark branches at x = 0.0709 m, t = 21.2 us, max speed about 2020 m/s;
// Verlet at 0.0703 m, 20.9 us.
TEST_CASE("glass plate at h = 1 mm, Newmark and GMLS: one branch within Table 2 tolerances", "[slow]") {
  check_table2(glass_newmark(coarse_glass("glass_plate"), 8));
}

// [paper]: about 40 s on 2 cores; the default suite runs it at h = 1 mm below.
TEST_CASE("glass plate, Verlet: same branch, same bits on 1 and 2 threads", "[paper]") {
  const auto one = glass_explicit(deck("glass_plate_explicit"), 1);
  check_table2(one);
  const auto two = glass_explicit(deck("glass_plate_explicit"), 2);
  CHECK(same::difference(one.damage, two.damage, "one.damage") == "");
  CHECK(same::difference(one.uy, two.uy, "one.uy") == "");
}

TEST_CASE("glass plate at h = 1 mm, Verlet to 36 us: same branch, same bits on 1 and 2 threads", "[slow]") {
  // From 39 us on at h = 1 mm, damage near the right edge (the reflected waves) appears ahead of
  // the arms and the tracker's tip jumps there, at up to 5900 m/s: that is no crack's speed, so
  // this run stops at 36 us, 15 us after the branch (up to 38 us the tip's speed stays below
  // 2050 m/s).
  Problem p = coarse_glass("glass_plate_explicit");
  p.solver.end_time = 36e-6;
  const auto one = glass_explicit(p, 1, 8);
  check_table2(one);
  const auto two = glass_explicit(p, 2, 8);
  CHECK(same::difference(one.damage, two.damage, "one.damage") == "");
  CHECK(same::difference(one.uy, two.uy, "one.uy") == "");
}

namespace {

// Table 5 at 3124 particles: 12 large fragments (15 or 14 on finer grids; [71]: 15 to 16), by the
// deck's rule that a large fragment holds at least 1 % of the ring's mass. And the ring moved
// outwards, by less than free flight under the whole pressure impulse would carry it: p0 t0 2 pi
// r_i / mass x t_end (hoop stress only slows it).
void check_cylinder(const Body& body, const State& state) {
  const auto f = count_fragments(body, {.large_mass_fraction = 0.01});
  INFO(f.large << " large fragments of " << f.count);
  CHECK(f.large >= 10);
  CHECK(f.large <= 17);
  const double impulse = 2.5e9 * 1e-5 * 2 * 3.141592653589793 * 0.08;
  double mass = 0;
  for (std::size_t i = 0; i < body.size(); ++i) mass += body.density * body.points.volume[i];
  const double free_flight = impulse / mass * 2e-4;
  double mean_radial = 0;
  for (std::size_t i = 0; i < body.size(); ++i) {
    const double x = body.points.x[0][i], y = body.points.x[1][i], r = std::hypot(x, y);
    mean_radial += (state.u[0][i] * x + state.u[1][i] * y) / r / double(body.size());
  }
  INFO("mean radial displacement " << mean_radial << " m; free flight " << free_flight << " m");
  CHECK(mean_radial > 0.25 * free_flight);
  CHECK(mean_radial < free_flight);
}

}  // namespace

// [paper]: about a minute of simulation on 2 cores, more when ctest runs another test beside it;
// the default suite runs the same deck with velocity Verlet below.
TEST_CASE("the coarsest cylinder breaks into 10 to 17 large fragments", "[paper]") {
  auto c = compose(deck("cylinder"));
  auto& s = std::get<NewmarkSetup>(c);
  NewmarkSolver<Lps> solver(s.body, s.model, s.boundaries, s.options);
  State state(s.body.size());
  solver.initialize(state);
  for (std::size_t k = 0; k < solver.steps(); ++k) solver.step(state);
  check_cylinder(s.body, state);
}

TEST_CASE("the coarsest cylinder under velocity Verlet also breaks into 10 to 17 large fragments", "[slow]") {
  // The same deck, integrated explicitly (about a tenth of the implicit run's time) at dt = 1e-7 s,
  // a seventeenth of the stable estimate (1.76e-6 s). Measured large fragments: 13 with Verlet at
  // dt = 2.5e-8, 5e-8 and 1e-7 s gives 12, 13 and 13 (11 at 2e-7 s); Newmark at 5e-8, 1e-7 and
  // 2e-7 s gives 12, 10 and 12.
  const std::filesystem::path file = std::string(PERIDOT_SOURCE_DIR) + "/data/decks/lps_dynamic/cylinder.yaml";
  auto text = deck_text::replaced(deck_text::file_text(file), "type: newmark", "type: explicit");
  text = deck_text::replaced(text, "  tolerance: 1.0e-8\n", "");
  text = deck_text::replaced(text, "dt: 5.0e-8 ", "dt: 1.0e-7 ");
  auto c = compose(parse_deck(text, file.string(), file.parent_path()));
  auto& s = std::get<Setup>(c);
  ExplicitSolver<Lps> solver(s.body, std::get<Lps>(s.model), s.boundaries, s.time_step);
  State state(s.body.size());
  solver.initialize(state);
  for (std::size_t k = 0; k < s.time_step.steps; ++k) solver.step(state);
  REQUIRE(state.time == Approx(2e-4));
  check_cylinder(s.body, state);
}
