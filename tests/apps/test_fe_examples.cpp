#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <functional>
#include <string>
#include <utility>
#include <variant>
#include <vector>
#include "../support/fe_study.hpp"
import peridot.problem;

using namespace peridot;

// Seed 003 Sec. 4.3-4.5 from the reduced decks (eps = 2 mm, h = 0.5 mm; the geometry the
// paper shows only in figures is assumed in the .geo files). The paper describes these
// qualitatively; the tests check the descriptions: where cracks start and where they go.

namespace {

struct Watch {
  double first_time = -1;
  std::vector<Vec3> first_points;  // Z >= 1 points at the first sample that has any
  std::vector<double> z;           // Z at the end
  PointCloud points;
};

// Runs a deck's problem, sampling Z every `every` steps; `ignore` masks points whose Z does not
// count (supports).
Watch run(const Problem& problem, std::size_t every, const std::function<bool(const Vec3&)>& ignore = {}) {
  Watch w;
  fe_study::run_deck(problem, every, [&](const Body& body, const Rnp& model, const State& state) {
    model.damage(body, state.u, w.z);
    w.points = body.points;
    if (w.first_time >= 0) return;
    for (std::size_t i = 0; i < body.size(); ++i)
      if (w.z[i] >= 1 && !(ignore && ignore(w.points.position(i)))) w.first_points.push_back(w.points.position(i));
    if (!w.first_points.empty()) w.first_time = state.time;
  });
  return w;
}

// A reduced deck as shipped, to end_time.
Watch run(const std::string& deck, double end_time, std::size_t every, const std::function<bool(const Vec3&)>& ignore = {}) {
  return run(fe_study::fe_deck(deck, end_time), every, ignore);
}

constexpr double eps = 2e-3, h = 0.5e-3;

// The default suite's versions: the same decks at h = eps / 2 (a quarter of the nodes, fewer
// than half the bonds per node).
constexpr double h2 = 1e-3;
std::pair<std::string, std::string> mesh_size_h2(const std::string& geo) {
  return {"file: " + geo + ", size: 0.5e-3}", "file: " + geo + ", size: 1.0e-3}"};
}

// Sec. 4.3 on a mesh of size `mesh_h`: the first Z >= 1 points lie on the rim where the hoop
// stress of the elastic (Kirsch) solution is at least 2/3 of its peak 3 sigma, sigma (1 - 2 cos
// 2 theta) >= 2 sigma, i.e. within 30 degrees of the vertical, above and below the hole; by the
// end Z >= 1 reaches the top and bottom edges above and below it.
void check_hole_cracks(const Watch& w, double mesh_h) {
  REQUIRE(w.first_time > 0);
  WARN("first Z >= 1 at " << w.first_time * 1e6 << " us, " << w.first_points.size() << " points");
  bool above = false, below = false;
  for (const auto& x : w.first_points) {
    const double dx = x[0] - 0.05, dy = x[1] - 0.05;
    CHECK(std::atan2(std::abs(dx), std::abs(dy)) <= M_PI / 6);
    CHECK(std::hypot(dx, dy) <= 0.01 + 2 * eps);
    (dy > 0 ? above : below) = true;
  }
  CHECK(above);
  CHECK(below);
  double top = 0, bottom = 1;
  for (std::size_t i = 0; i < w.points.size(); ++i)
    if (w.z[i] >= 1 && std::abs(w.points.x[0][i] - 0.05) < 0.01) top = std::max(top, w.points.x[1][i]), bottom = std::min(bottom, w.points.x[1][i]);
  CHECK(top >= 0.1 - mesh_h);
  CHECK(bottom <= mesh_h);
}

// Sec. 4.4 on a mesh of size `mesh_h`: the first Z >= 1 points (supports ignored) lie within 2
// eps of the notch tip at (50, 10) mm, and by the end Z >= 1 runs up the ligament to the top.
void check_v_notch(const Watch& w, double mesh_h) {
  REQUIRE(w.first_time > 0);
  WARN("first Z >= 1 at " << w.first_time * 1e6 << " us, " << w.first_points.size() << " points");
  for (const auto& x : w.first_points) CHECK(std::hypot(x[0] - 0.05, x[1] - 0.01) <= 2 * eps);
  double top = 0;
  for (std::size_t i = 0; i < w.points.size(); ++i)
    if (w.z[i] >= 1 && std::abs(w.points.x[0][i] - 0.05) < 0.005) top = std::max(top, w.points.x[1][i]);
  CHECK(top >= 0.03 - mesh_h);
}

// Supports of the V-notch beam, whose own Z >= 1 patches are not the crack.
bool v_notch_support(const Vec3& x) { return x[1] < 0.003 && (x[0] < 0.01 || x[0] > 0.09); }

// The pre-cracked plate: the pre-crack's mouth and the corners of the moving top and bottom
// layers reach Z >= 1 on their own; they are not the crack.
bool not_the_crack(const Vec3& x) { return x[0] < 0.005 || x[1] < 2 * eps || x[1] > 0.04 - 2 * eps; }

}  // namespace

// [paper]: one to two minutes of simulation on 2 cores; the default suite runs it at h = eps / 2 below.
TEST_CASE("Plate with a hole under pull: cracks start at the top and bottom of the hole and reach both edges (Sec. 4.3)", "[paper]") {
  // Hole of radius 10 mm at the centre of the 100 mm square; layers pulled at -1 and +1 m/s in x.
  check_hole_cracks(run("circular_hole_coarse.yaml", 46e-6, 40), h);
}

TEST_CASE("At h = eps / 2 the plate with a hole still cracks from the top and bottom of the hole to both edges by 46 us (Sec. 4.3)", "[slow]") {
  // Measured at h = eps / 2: first Z >= 1 at 19 us at the top and bottom of the rim, the top
  // edge reached at about 43 us, as at h = eps / 4 (19 and 44 us).
  check_hole_cracks(run(fe_study::fe_deck("circular_hole_coarse.yaml", 46e-6, {mesh_size_h2("circular_hole.geo")}), 40), h2);
}

// [paper]: one to two minutes of simulation on 2 cores; the default suite runs it at h = eps / 2 below.
TEST_CASE("V-notch beam in bending: the crack starts at the notch tip and runs through the ligament (Sec. 4.4)", "[paper]") {
  check_v_notch(run("v_notch_coarse.yaml", 125e-6, 40, v_notch_support), h);
}

TEST_CASE("At h = eps / 2 the V-notch beam still cracks from the notch tip through the ligament by 110 us (Sec. 4.4)", "[slow]") {
  // Measured at h = eps / 2: first Z >= 1 at the notch tip at 36 us, the top edge reached at
  // about 98 us.
  check_v_notch(run(fe_study::fe_deck("v_notch_coarse.yaml", 110e-6, {mesh_size_h2("v_notch.geo")}), 40, v_notch_support), h2);
}

// [paper]: one to two minutes of simulation on 2 cores; the default suite runs it at h = eps / 2 below.
TEST_CASE("Hole with a pre-crack: the crack starts at the pre-crack tip, passes the hole and reaches the far edge (Sec. 4.5)", "[paper]") {
  // Pre-crack along y = 20 mm from x = 0 to 10 mm; hole of radius 2.5 mm at (25, 29) mm.
  const auto w = run("hole_precrack_coarse.yaml", 540e-6, 200, not_the_crack);
  REQUIRE(w.first_time > 0);
  WARN("first Z >= 1 at " << w.first_time * 1e6 << " us, " << w.first_points.size() << " points");
  for (const auto& x : w.first_points) CHECK(std::hypot(x[0] - 0.01, x[1] - 0.02) <= 2 * eps);
  double right = 0;
  for (std::size_t i = 0; i < w.points.size(); ++i) {
    if (w.z[i] < 1 || not_the_crack(w.points.position(i))) continue;
    right = std::max(right, w.points.x[0][i]);
    // The crack passes beneath the hole: no Z >= 1 node on its rim.
    CHECK(std::hypot(w.points.x[0][i] - 0.025, w.points.x[1][i] - 0.029) > 0.0025 + h);
  }
  CHECK(right >= 0.05 - h);
}

// [paper], about an hour on 2 cores (Zen 5 VM, `ci`: 63 min): the shipped paper-resolution deck
// fe/hole_precrack.yaml (eps = 0.4 mm, h = 0.1 mm, 230,629 nodes, 160,000 steps of 5 ns, RNP in
// single precision), sampled every 600 steps (3 us) as the deck's crack tip is. Table 2 gives an
// average crack speed of 0.04 c_R for this example (c_R = 3244.2 m/s, README); measured here
// 0.046 from the first Z >= 1 node at the pre-crack tip (252 us) to the right edge (519 us), so
// the average is asserted within half of Table 2's either way. The crack runs below the hole,
// not deflected into it (README: the geometry and load are our reading of the paper's).
TEST_CASE("Hole with a pre-crack at the paper's resolution: the crack runs from the pre-crack tip past the hole to the far edge at Table 2's "
          "average speed within a factor 1.5 (Sec. 4.5)",
          "[paper]") {
  constexpr double eps_paper = 0.4e-3, h_paper = 0.1e-3, c_R = 3244.2, table2_average = 0.04;
  Problem p = read_deck(std::string(PERIDOT_SOURCE_DIR) + "/data/decks/fe/hole_precrack.yaml");
  const auto outside = [&](const Vec3& x) { return x[0] < 0.005 || x[1] < 2 * eps_paper || x[1] > 0.04 - 2 * eps_paper; };
  double t_start = -1, t_edge = -1;
  std::vector<Vec3> first;
  std::vector<double> z;
  PointCloud points;
  fe_study::run_deck(p, 600, [&](const Body& body, const Rnp& model, const State& state) {
    model.damage(body, state.u, z);
    double right = 0;
    for (std::size_t i = 0; i < body.size(); ++i) {
      if (z[i] < 1 || outside(body.points.position(i))) continue;
      right = std::max(right, body.points.x[0][i]);
      if (t_start < 0) first.push_back(body.points.position(i));
    }
    if (t_start < 0 && !first.empty()) t_start = state.time;
    if (t_edge < 0 && right >= 0.05 - h_paper) t_edge = state.time;
    if (points.size() == 0) points = body.points;
  });
  REQUIRE(t_start > 0);
  REQUIRE(t_edge > t_start);
  for (const auto& x : first) CHECK(std::hypot(x[0] - 0.01, x[1] - 0.02) <= 2 * eps_paper);
  REQUIRE(points.size() == z.size());
  for (std::size_t i = 0; i < z.size(); ++i)
    if (z[i] >= 1 && !outside(points.position(i))) CHECK(std::hypot(points.x[0][i] - 0.025, points.x[1][i] - 0.029) > 0.0025 + h_paper);
  const double average = (0.05 - 0.01) / (t_edge - t_start) / c_R;
  WARN("crack from t = " << t_start * 1e6 << " us to the edge at " << t_edge * 1e6 << " us: average " << average << " c_R (Table 2: 0.04)");
  CHECK(average >= table2_average / 1.5);
  CHECK(average <= table2_average * 1.5);
}

TEST_CASE("At h = eps / 2 the crack starts at the pre-crack tip and is deflected up towards the hole (Sec. 4.5)", "[slow]") {
  // Sec. 4.5 (paper Sec. 7.7): "initially, crack propagation is influenced by the hole nearby,
  // and instead of growing horizontally, it is deflected". At h = eps / 2 the hole's rim has
  // about 16 nodes and the crack runs into the hole instead of past it (so that is not
  // asserted); the start and the deflection are. dt = 6e-8 s is 0.8 of the stable estimate at
  // this mesh (7.5e-8 s), half the steps of the deck's 3e-8 s. Measured: first Z >= 1 at the pre-crack tip at 294 us; the tip at
  // x = 12 mm until 414 us, then a run to the hole's rim (x = 23 mm) by 441 us; the crack's
  // centre line at x = 20 mm is at y = 26 to 27 mm. The end time leaves 40 us after that run.
  const auto w = run(fe_study::fe_deck("hole_precrack_coarse.yaml", 480e-6, {mesh_size_h2("hole_precrack.geo"), {"dt: 3.0e-8", "dt: 6.0e-8"}}),
                     50, not_the_crack);
  REQUIRE(w.first_time > 0);
  WARN("first Z >= 1 at " << w.first_time * 1e6 << " us, " << w.first_points.size() << " points");
  for (const auto& x : w.first_points) CHECK(std::hypot(x[0] - 0.01, x[1] - 0.02) <= 2 * eps);
  // The crack band (2 eps wide) across x = 20 mm, halfway from the pre-crack tip to the hole's
  // centre: it must be there, and its middle above the pre-crack's line by more than a horizon
  // (a straight crack would keep it at y = 20 mm).
  double right = 0, lo = 1, hi = 0;
  for (std::size_t i = 0; i < w.points.size(); ++i) {
    if (w.z[i] < 1 || not_the_crack(w.points.position(i))) continue;
    right = std::max(right, w.points.x[0][i]);
    if (std::abs(w.points.x[0][i] - 0.02) <= h2 / 2) lo = std::min(lo, w.points.x[1][i]), hi = std::max(hi, w.points.x[1][i]);
  }
  WARN("Z >= 1 reaches x = " << right * 1e3 << " mm; across x = 20 mm from y = " << lo * 1e3 << " to " << hi * 1e3 << " mm");
  REQUIRE(right >= 0.02);
  REQUIRE(hi >= lo);
  CHECK((lo + hi) / 2 > 0.02 + eps);
}
