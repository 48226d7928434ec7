// Seed 004 examples run from the shipped decks in data/decks/osb/, in-process: the deck is
// parsed and composed as `peridot run` does, then solved.
#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <variant>
#include <vector>
#include "../support/deck_text.hpp"
#include "../support/same.hpp"
import peridot.problem;
import peridot.analysis;

using namespace peridot;

namespace {

std::string deck_file(const std::string& name) { return std::string(PERIDOT_SOURCE_DIR) + "/data/decks/osb/" + name; }

std::string deck_text_of(const std::string& name) {
  std::ifstream in(deck_file(name));
  std::stringstream t;
  t << in.rdbuf();
  return t.str();
}

struct Run {
  Problem problem;
  OsbStaticSetup setup;
  OsbStaticResult result;
  OsbErrors errors;
};

Run run_text(const std::string& text, const std::string& source) {
  Run r;
  r.problem = parse_deck(text, source);
  auto composed = compose(r.problem);
  r.setup = std::move(std::get<OsbStaticSetup>(composed));
  r.result = solve_osb_static(r.setup.body, r.setup.model, r.setup.problem, r.setup.options);
  r.errors = osb_errors(r.problem, r.setup, r.result);
  return r;
}

Run run_deck(const std::string& name) { return run_text(deck_text_of(name), deck_file(name)); }

double round2(double x) { return std::round(x * 100) / 100; }

// The uncorrected variant of a deck: conditions on the outermost nodes, no layer.
std::string uncorrected(const std::string& name) {
  auto t = deck_text::replaced(deck_text_of(name), "boundary_method: fictitious_taylor", "boundary_method: outermost_nodes");
  const auto k = t.find("  taylor_order:");
  t.erase(k, t.find('\n', k) - k + 1);
  return t;
}

}  // namespace

TEST_CASE("The traction deck gives Table 2's uniform error at m = 3", "[osb]") {
  const auto r = run_deck("traction.yaml");
  CHECK(round2(r.errors.rel_u_max) == Approx(0.43).margin(1e-12));
  CHECK(round2(r.errors.rel_v_max) == Approx(2.15).margin(1e-12));
  CHECK(r.errors.rel_u_max - r.errors.rel_u_min < 1e-5 * r.errors.rel_u_max);
  CHECK(r.errors.rel_v_max - r.errors.rel_v_min < 1e-5 * r.errors.rel_v_max);
  // Spec 004 Sec. 7: the largest (64) errors of the corrected run are 0.43 % (u) and 0.28 % (v).
  CHECK(round2(r.errors.abs_u_max) == Approx(0.43).margin(1e-12));
  CHECK(round2(r.errors.abs_v_max) == Approx(0.28).margin(1e-12));
  double lambda = 0;
  for (double l : r.result.multipliers) lambda = std::max(lambda, std::abs(l));
  CHECK(lambda < 1e-9 * 1e6 / 0.01);
}

TEST_CASE("Without the layer the traction error is larger and varies over the plate", "[osb]") {
  const auto c = run_deck("traction.yaml");
  const auto u = run_text(uncorrected("traction.yaml"), "uncorrected traction");
  INFO("uncorrected (64): u " << u.errors.abs_u_max << " %, v " << u.errors.abs_v_max << " %");
  CHECK(u.errors.abs_u_max > 5 * c.errors.abs_u_max);
  CHECK(u.errors.rel_u_max - u.errors.rel_u_min > 10 * c.errors.rel_u_max);
}

TEST_CASE("The shear deck gives Table 3 with v zero everywhere", "[osb]") {
  const auto r = run_deck("shear.yaml");
  CHECK(round2(r.errors.rel_u_max) == Approx(0.73).margin(1e-12));
  CHECK(r.errors.rel_u_max - r.errors.rel_u_min < 1e-5 * r.errors.rel_u_max);
  CHECK(r.errors.max_v < 1e-12 * r.errors.max_u);
  // Without the layer v is not zero: the surface effect (Fig. 8).
  const auto u = run_text(uncorrected("shear.yaml"), "uncorrected shear");
  CHECK(u.errors.max_v > 1e-3 * u.errors.max_u);
}

TEST_CASE("With the layer the stress tensor equals the applied traction at every node", "[osb]") {
  // The corrected solution is linear and every real node has a full neighbourhood, so eq. (51)
  // must give tau = (p, 0, 0) exactly: the flux rows impose tau . n = p through the same bonds.
  const auto r = run_deck("traction.yaml");
  const auto& pc = r.setup.body.points;
  const auto tau = lattice_stress(lattice_grid(pc), r.setup.body, r.result.pair_force);
  double worst = 0;
  for (std::size_t i = 0; i < pc.size(); ++i)
    if (pc.role[i] == Role::interior)
      worst = std::max({worst, std::abs(tau.xx[i] - 1e6), std::abs(tau.yy[i]), std::abs(tau.xy[i])});
  CHECK(worst < 1e-6 * 1e6);
  // The boundary tractions reported after the solve are the imposed ones, corners included.
  for (std::size_t s = 0; s < r.result.boundary_traction.size(); ++s) {
    const auto n = r.result.boundary_normal[s];
    CHECK(r.result.boundary_traction[s][0] == Approx(1e6 * n[0]).margin(1e-6 * 1e6));
    CHECK(r.result.boundary_traction[s][1] == Approx(0).margin(1e-6 * 1e6));
  }
}

namespace {

// Relative errors [%] of u and v (eq. 66) of a homogeneous plate under tau_xx = p, tau_yy = 0 (Ex. 1),
// from seed 004's constitutive law alone. On an infinite lattice under a homogeneous strain every
// point has the full family, the same m and theta, and (with w_j = beta_j h^2 by eq. 44 and the
// Gaussian omega of eq. 15) the sums over a family are the lattice moments
//   m = sum omega r^2 w,   B = sum omega r^2 w cos^2 sin^2   (sum omega r^2 w cos^4 = m/2 - B),
// so eqs. (14) and (20) give theta = c_theta tr(eps) / 2 and eq. (49)
//   tau = k_theta theta / 2 I + (k_e / m) A4 : eps,  A4_1111 = m/2 - B,  A4_1122 = B,
// with c_theta, k_theta, k_e of eqs. (16), (18), (19) in plane stress. The fraction beta_j of
// cell j in the disk comes from disk_square_area (tests/quadrature/test_cell_area.cpp).
std::array<double, 2> homogeneous_errors(double mbar, double E, double nu, double p) {
  double m = 0, B = 0;
  const int reach = int(std::ceil(mbar)) + 1;
  for (int a = -reach; a <= reach; ++a)
    for (int b = -reach; b <= reach; ++b) {
      if (a == 0 && b == 0) continue;
      const double r2 = a * a + b * b, w = std::exp(-r2 / (mbar * mbar)) * r2 * disk_square_area(a, b, 0.5, mbar);
      m += w;
      B += w * a * a * b * b / (r2 * r2);
    }
  const double c_theta = 2 * (1 - 2 * nu) / (1 - nu), k_theta = -(1 - 3 * nu) / ((1 + nu) * (1 - 2 * nu)) * E, k_e = 4 / (1 + nu) * E;
  const double iso = k_theta * c_theta / 4, C11 = iso + k_e * (m / 2 - B) / m, C12 = iso + k_e * B / m;
  const double exx = p * C11 / (C11 * C11 - C12 * C12), eyy = -p * C12 / (C11 * C11 - C12 * C12);
  return {std::abs(exx * E / p - 1) * 100, std::abs(eyy * E / (-nu * p) - 1) * 100};
}

}  // namespace

TEST_CASE("The homogeneous response of seed 004's constitutive law gives Table 2's errors, and the m = 3.5 deck's", "[osb]") {
  // Table 2 (Ex. 1, corrected): u and v errors 0.43 / 2.15 % at m = 3, 0.09 / 0.45 at 4, 0.04 /
  // 0.18 at 5, 0.02 / 0.09 at 6, the same at every node. The closed form above reproduces them to
  // the printed digits; the corrected plate deforms homogeneously (the patch test: a uniform
  // error), so the solved m = 3.5 deck must have the closed form's error to solver round-off.
  const double E = 1e9, nu = 0.2, p = 1e6;
  const std::array<std::array<double, 3>, 4> table2{{{3, 0.43, 2.15}, {4, 0.09, 0.45}, {5, 0.04, 0.18}, {6, 0.02, 0.09}}};
  for (const auto& [mbar, eu, ev] : table2) {
    const auto e = homogeneous_errors(mbar, E, nu, p);
    INFO("m = " << mbar << ": closed form eu " << e[0] << " %, ev " << e[1] << " %");
    CHECK(round2(e[0]) == Approx(eu).margin(1e-12));
    CHECK(round2(e[1]) == Approx(ev).margin(1e-12));
  }
  const auto r = run_deck("traction_m3.5.yaml");
  const auto e = homogeneous_errors(3.5, E, nu, p);
  INFO("m = 3.5, n_max = 2: eu " << r.errors.rel_u_min << " to " << r.errors.rel_u_max << " % (closed form " << e[0] << "), ev "
                                  << r.errors.rel_v_min << " to " << r.errors.rel_v_max << " % (closed form " << e[1] << ")");
  CHECK(r.errors.rel_u_max - r.errors.rel_u_min < 1e-5 * r.errors.rel_u_max);
  CHECK(r.errors.rel_v_max - r.errors.rel_v_min < 1e-5 * r.errors.rel_v_max);
  CHECK(r.errors.rel_u_max == Approx(e[0]).epsilon(1e-6));
  CHECK(r.errors.rel_v_max == Approx(e[1]).epsilon(1e-6));
}

namespace {

// Where the crack is: damage on the real points, and in the top row the runs of contiguous
// cracked points (phi >= 0.3): one run is a single crack reaching the edge, two a branched one.
struct CrackPath {
  std::size_t broken = 0, solves = 0;
  bool singular = false;
  int runs_at_top = 0;
  double max_abs_x_at_top = 0;  // [m]
};

CrackPath crack_path(const Run& r) {
  CrackPath c{r.result.broken, r.result.solves, r.result.stopped_singular, 0, 0};
  std::vector<double> phi;
  damage(r.setup.body, phi);
  const auto& pc = r.setup.body.points;
  const auto g = lattice_grid(pc);
  int top = -1 << 30, lo = 1 << 30, hi = -1 << 30;
  for (std::size_t i = 0; i < pc.size(); ++i)
    if (pc.role[i] == Role::interior) top = std::max(top, g.gy[i]), lo = std::min(lo, g.gx[i]), hi = std::max(hi, g.gx[i]);
  bool in_run = false;
  for (int ix = lo; ix <= hi; ++ix) {
    const auto i = std::size_t(g.at(ix, top));
    const bool cracked = phi[i] >= 0.3;
    if (cracked && !in_run) ++c.runs_at_top;
    if (cracked) c.max_abs_x_at_top = std::max(c.max_abs_x_at_top, std::abs(pc.x[0][i]));
    in_run = cracked;
  }
  return c;
}

// The crack decks at half size: a 0.05 m square, pre-crack a = 0.01 m, half the imposed
// displacement; same material, grid and horizon.
std::string half_size(std::string t) {
  t = deck_text::replaced(t, "rectangle: {min: [-0.05, -0.05], max: [0.05, 0.05]}", "rectangle: {min: [-0.025, -0.025], max: [0.025, 0.025]}");
  t = deck_text::replaced(t, "segment: {from: [0, -0.06], to: [0, -0.03]}", "segment: {from: [0, -0.035], to: [0, -0.015]}");
  if (t.find("displacement: 0.001}") != std::string::npos) t = deck_text::replaced(t, "displacement: 0.001}", "displacement: 0.0005}");
  return t;
}

}  // namespace

// [paper]: about 45 s alone on 2 cores, 80 s beside another test; the default suite runs the
// corrected Dirichlet deck with 16 bonds removed per solve below.
TEST_CASE("Sequentially linear cracks cut the half-size plate from the pre-crack to the top", "[osb][fracture][paper]") {
  for (const char* name : {"crack_dirichlet.yaml", "crack_neumann.yaml"})
    for (bool corrected : {true, false}) {
      const auto text = half_size(corrected ? deck_text_of(name) : uncorrected(name));
      const auto r = run_text(text, name);
      const auto c = crack_path(r);
      WARN(name << (corrected ? " corrected: " : " uncorrected: ") << c.solves << " solves, " << c.broken << " bonds removed, " << c.runs_at_top
                << " crack(s) at the top edge within |x| <= " << c.max_abs_x_at_top << " m, singular " << c.singular << ", "
                << r.result.assembly_seconds + r.result.factor_seconds << " s");
      // The crack crosses the plate from the pre-crack tip to the top edge.
      CHECK(c.runs_at_top >= 1);
      // With the correction it stays one crack (the paper's finding for Ex. 5); without it the
      // paper saw two branches; that is reported, not asserted (our specimen is a guess).
      if (corrected) CHECK(c.runs_at_top == 1);
    }
}

namespace {

// The rows of real points from the pre-crack tip (y = `tip_y`) to the top edge in which no point
// within |x| <= half_width is cracked (phi >= 0.3): 0 for a crack that runs from the tip to the top
// inside that band.
int rows_without_crack(const Run& r, double tip_y, double half_width) {
  std::vector<double> phi;
  damage(r.setup.body, phi);
  const auto& pc = r.setup.body.points;
  const auto g = lattice_grid(pc);
  int top = -1 << 30, first = 1 << 30;
  for (std::size_t i = 0; i < pc.size(); ++i)
    if (pc.role[i] == Role::interior) {
      top = std::max(top, g.gy[i]);
      if (pc.x[1][i] > tip_y) first = std::min(first, g.gy[i]);
    }
  int missing = 0;
  for (int iy = first; iy <= top; ++iy) {
    bool cracked = false;
    for (std::size_t i = 0; i < pc.size(); ++i)
      cracked = cracked || (g.gy[i] == iy && pc.role[i] == Role::interior && std::abs(pc.x[0][i]) <= half_width && phi[i] >= 0.3);
    missing += !cracked;
  }
  return missing;
}

}  // namespace

TEST_CASE("Removing 16 bonds per solve, one sequentially linear crack still cuts the corrected half-size Dirichlet plate from the pre-crack tip to the top", "[osb][fracture][slow]") {
  // The paper's finding for Ex. 5 with the correction: one crack from the pre-crack tip through
  // the ligament to the opposite edge. Removing 16 of the most stretched bonds per solve instead
  // of 4 takes about a third of the solves; every removed bond is still past s_c under the
  // linear solution of its step. Measured: 51 solves, 762 bonds removed, one crack reaching the
  // top within |x| <= 3.75 mm (with 4 per solve: 164 solves, 649 bonds, within 8.75 mm). The
  // path is asserted inside the middle half of the plate, |x| <= 12.5 mm, in every row above the
  // tip (y = -15 mm).
  const auto text = deck_text::replaced(half_size(deck_text_of("crack_dirichlet.yaml")), "bonds_per_solve: 4", "bonds_per_solve: 16");
  const auto r = run_text(text, "crack_dirichlet.yaml");
  const auto c = crack_path(r);
  WARN(c.solves << " solves, " << c.broken << " bonds removed, " << c.runs_at_top << " crack(s) at the top edge within |x| <= "
                << c.max_abs_x_at_top << " m, singular " << c.singular << ", " << r.result.assembly_seconds + r.result.factor_seconds << " s");
  CHECK(c.runs_at_top == 1);
  CHECK(c.max_abs_x_at_top <= 0.0125);
  CHECK(rows_without_crack(r, -0.015, 0.0125) == 0);
}

TEST_CASE("An explicit OSB run closes the energy balance", "[osb]") {
  // Second law check: the work of the loads equals kinetic plus strain energy of the same run.
  const Problem p = read_deck(deck_file("explicit_plate.yaml"));
  Setup s = setup(p);
  const auto& model = std::get<Osb>(s.model);
  ExplicitSolver solver(s.body, model, s.boundaries, s.time_step, p.solver.scheme);
  State state(s.body.size());
  solver.initialize(state);
  for (std::size_t k = 0; k < s.time_step.steps; ++k) solver.step(state);
  double kinetic = 0;
  for (std::size_t i = 0; i < s.body.size(); ++i)
    kinetic += 0.5 * s.body.density * s.body.points.volume[i] * (state.v[0][i] * state.v[0][i] + state.v[1][i] * state.v[1][i]);
  const double strain = model.strain_energy(s.body, state.u), work = solver.external_work();
  INFO("kinetic " << kinetic << " J/m, strain " << strain << " J/m, external work " << work << " J/m");
  CHECK(kinetic > 0.1 * work);
  CHECK(strain > 0.1 * work);
  CHECK(kinetic + strain == Approx(work).epsilon(2e-3));
}

namespace {

// Two runs of 12 solves of the half-size Dirichlet crack plate (4 bonds removed each), the
// options of run k (0, 1) set by `configure`: the set-ups (their bond states) and the results.
std::pair<std::array<OsbStaticSetup, 2>, std::array<OsbStaticResult, 2>> twelve_crack_solves(const std::function<void(int, OsbStaticOptions&)>& configure) {
  const Problem problem = parse_deck(half_size(deck_text_of("crack_dirichlet.yaml")), "crack_dirichlet.yaml");
  std::array<OsbStaticSetup, 2> setups;
  std::array<OsbStaticResult, 2> results;
  for (int k = 0; k < 2; ++k) {
    setups[std::size_t(k)] = std::move(std::get<OsbStaticSetup>(compose(problem)));
    auto& s = setups[std::size_t(k)];
    s.options.max_solves = 12;
    configure(k, s.options);
    results[std::size_t(k)] = solve_osb_static(s.body, s.model, s.problem, s.options);
  }
  return {std::move(setups), std::move(results)};
}

}  // namespace

TEST_CASE("Re-solves that reuse the first solve's UMFPACK ordering remove the same bonds and reach the displacements of fresh factorisations", "[osb][fracture]") {
  // Two paths to the same sequence of linear systems: every matrix analysed afresh, or one
  // symbolic analysis reused by every re-solve (the assembly keeps the first pattern, broken
  // bonds entering as zeros). 12 solves of the half-size Dirichlet plate, 4 bonds each.
  auto [setups, results] = twelve_crack_solves([](int k, OsbStaticOptions& o) {
    o.reuse_ordering = k == 1;
    o.banded = OsbStaticOptions::Banded::never;  // UMFPACK's orderings are the subject
  });
  const auto &fresh = results[0], &reused = results[1];
  REQUIRE(fresh.solves == 12);
  REQUIRE(reused.solves == 12);
  CHECK(fresh.orderings == 12);
  // The pattern held through 44 bond removals: one analysis served every solve.
  CHECK(reused.orderings == 1);
  CHECK(reused.broken == fresh.broken);
  CHECK(same::difference(setups[1].body.bonds.intact, setups[0].body.bonds.intact, "bond states") == "");
  double umax = 0, diff = 0;
  for (int c = 0; c < 2; ++c)
    for (std::size_t i = 0; i < fresh.u[std::size_t(c)].size(); ++i) {
      umax = std::max(umax, std::abs(fresh.u[std::size_t(c)][i]));
      diff = std::max(diff, std::abs(fresh.u[std::size_t(c)][i] - reused.u[std::size_t(c)][i]));
    }
  INFO("max |u| " << umax << " m, largest difference " << diff << " m");
  CHECK(diff <= 1e-10 * umax);
  CHECK(reused.residual < 1e-12);
}

// The banded LU (LAPACK's dgbsv, the unknowns ordered column by column across the plate),
// chosen by default for small systems, against UMFPACK on the same matrices: Ex. 1, and 12
// re-solves of the half-size Dirichlet crack plate (the band, kept from the first matrix, holds
// every later one).
TEST_CASE("The banded LU chosen for small systems gives UMFPACK's displacements and removes the same bonds", "[osb][fracture]") {
  const auto largest = [](const OsbStaticResult& a, const OsbStaticResult& b, double& umax) {
    double diff = 0;
    umax = 0;
    for (int c = 0; c < 2; ++c)
      for (std::size_t i = 0; i < a.u[std::size_t(c)].size(); ++i) {
        umax = std::max(umax, std::abs(a.u[std::size_t(c)][i]));
        diff = std::max(diff, std::abs(a.u[std::size_t(c)][i] - b.u[std::size_t(c)][i]));
      }
    return diff;
  };
  SECTION("Ex. 1 takes the banded LU by default") {
    const Problem problem = parse_deck(deck_text_of("traction.yaml"), "traction.yaml");
    auto by_default = std::get<OsbStaticSetup>(compose(problem)), umfpack = std::get<OsbStaticSetup>(compose(problem));
    umfpack.options.banded = OsbStaticOptions::Banded::never;
    const auto b = solve_osb_static(by_default.body, by_default.model, by_default.problem, by_default.options);
    const auto u = solve_osb_static(umfpack.body, umfpack.model, umfpack.problem, umfpack.options);
    CHECK(u.band == 0);
    // Ex. 1's 30 x 20 real points swept column by column: a column holds 20 points x 3 unknowns
    // and the 4 condition rows of its top and bottom sides, a horizon of 3h reaches the 3 columns
    // beside it, and the 40 rows of a vertical edge's sides sit beside its end column. So no
    // entry lies farther from the diagonal than 4 columns and one edge's rows. (A reverse
    // Cuthill-McKee order's diagonal levels gave 339.)
    CHECK(b.band > 0);
    CHECK(b.band <= 4 * (20 * 3 + 4) + 40);
    double umax = 0;
    const double diff = largest(b, u, umax);
    INFO("max |u| " << umax << " m, largest difference " << diff << " m");
    REQUIRE(umax > 0);
    CHECK(diff <= 1e-10 * umax);
    CHECK(b.residual < 1e-12);
  }
  SECTION("re-solves of a crack plate") {
    auto [setups, results] = twelve_crack_solves([](int k, OsbStaticOptions& o) {
      o.banded = k == 0 ? OsbStaticOptions::Banded::never : OsbStaticOptions::Banded::always;
    });
    REQUIRE(results[1].solves == 12);
    CHECK(results[1].band > 0);
    CHECK(results[1].broken == results[0].broken);
    CHECK(same::difference(setups[1].body.bonds.intact, setups[0].body.bonds.intact, "bond states") == "");
    double umax = 0;
    const double diff = largest(results[1], results[0], umax);
    INFO("max |u| " << umax << " m, largest difference " << diff << " m");
    CHECK(diff <= 1e-10 * umax);
    CHECK(results[1].residual < 1e-12);
  }
}
