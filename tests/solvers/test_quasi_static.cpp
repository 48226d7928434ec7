#include <catch2/catch.hpp>
#include "../support/bond_pairs.hpp"
#include <cmath>
#include <numbers>
#include <string>
#include <utility>
#include <algorithm>
#include <variant>
#include <vector>
import peridot.problem;

using namespace peridot;

namespace {

std::string rnp_deck(const std::string& name) { return std::string(PERIDOT_SOURCE_DIR) + "/data/decks/rnp/" + name; }

Body lattice_body(const Shape& s, double h, double delta, bool partial) {
  Body b;
  b.points = lattice(s, {.spacing = h});
  b.bonds = build_bonds(b.points, {.horizon = delta, .partial_volume = partial});
  b.density = 1;
  return b;
}

std::size_t nearest(const PointCloud& pc, Vec3 p) {
  std::size_t best = 0;
  for (std::size_t i = 0; i < pc.size(); ++i)
    if (norm(pc.position(i) - p) < norm(pc.position(best) - p)) best = i;
  return best;
}

// Largest |K_FD - K| over the blocks of the points listed, relative to the largest |K| entry:
// K_FD by central differences of the force (eq. 36), step tau.
double tangent_mismatch(const Rnp& m, Body& b, const VectorField& u, const std::vector<std::size_t>& rows, double tau) {
  TangentBlocks K;
  m.tangent(b, u, K);
  const int d = b.dim();
  double worst = 0, scale = 0;
  for (double v : K.bond) scale = std::max(scale, std::abs(v));
  VectorField up = u, fp = zero_field(b.size()), fm = zero_field(b.size());
  for (auto i : rows) {
    // Columns of point i itself (diagonal block) and of each partner j (bond block (i, j)).
    std::vector<std::pair<std::size_t, const double*>> cols{{i, K.diagonal.data() + i * std::size_t(d * d)}};
    for (auto bnd = b.bonds.begin(i); bnd < b.bonds.end(i); ++bnd)
      cols.push_back({std::size_t(b.bonds.neighbor[bnd]), K.bond.data() + std::size_t(bnd) * std::size_t(d * d)});
    for (const auto& [j, block] : cols)
      for (int c = 0; c < d; ++c) {
        up[c][j] = u[c][j] + tau;
        m.forces(b, up, fp);
        up[c][j] = u[c][j] - tau;
        m.forces(b, up, fm);
        up[c][j] = u[c][j];
        for (int r = 0; r < d; ++r) worst = std::max(worst, std::abs((fp[r][i] - fm[r][i]) / (2 * tau) - block[r * d + c]));
      }
  }
  return worst / scale;
}

}  // namespace

TEST_CASE("the explicit RNP tangent equals central differences of the force (eq. 36) in 1D, 2D and 3D, softening bonds included", "[slow]") {
  struct Case {
    Shape shape;
    double h;
    int dim;
  };
  for (const auto& c : {Case{interval(0, 2), 0.1, 1}, Case{rectangle({0, 0, 0}, {1, 1, 0}), 0.1, 2}, Case{box({0, 0, 0}, {0.6, 0.6, 0.6}), 0.1, 3}}) {
    INFO("dimension " << c.dim);
    Body b = lattice_body(c.shape, c.h, 3 * c.h, true);
    const auto m = Rnp::make(c.dim, 2.0, 4.0, 3 * c.h);
    // A field strong enough that sqrt|xi| |S| passes r_c on some bonds (g'' < 0 there).
    VectorField u = zero_field(b.size());
    for (std::size_t i = 0; i < b.size(); ++i)
      for (int k = 0; k < c.dim; ++k) u[k][i] = 0.4 * std::sin(3.0 * b.points.x[0][i] + k) * std::cos(2.0 * b.points.x[k][i]);
    REQUIRE(m.softening_bonds(b, u) > 0);
    const auto centre = nearest(b.points, c.dim == 1 ? Vec3{1, 0, 0} : Vec3{0.3, 0.3, c.dim == 3 ? 0.3 : 0.0});
    CHECK(tangent_mismatch(m, b, u, {0, centre}, 1e-6) < 1e-6);
  }
}

TEST_CASE("RNP under a homogeneous strain gradient gives div sigma of the deck's E and nu within 1% (Peridot's convention)") {
  // u = a x^2 / 2 along x gives f_x = (lambda + 2 mu) a; along y, f_y = mu a. E and G_c set C and
  // beta through the exact linearisation (2D plane stress: C beta = 9E/4, mu = C beta / 6).
  const double E = 2.0e9, a = 1e-3;
  for (auto kin : {Kinematics::plane_stress, Kinematics::plane_strain}) {
    INFO(to_string(kin));
    const double h = 0.01, delta = 8 * h;
    Body b = lattice_body(rectangle({-0.3, -0.3, 0}, {0.3, 0.3, 0}), h, delta, true);
    const auto m = Rnp::from_elastic(E, 100.0, delta, kin, 2);
    const auto el = lame(E, bond_based_poisson_ratio(kin), kin);
    const auto i = nearest(b.points, {0.005, 0.005, 0});
    VectorField u = zero_field(b.size()), f = zero_field(b.size());
    for (std::size_t k = 0; k < b.size(); ++k) u[0][k] = 0.5 * a * b.points.x[0][k] * b.points.x[0][k];
    m.forces(b, u, f);
    CHECK(f[0][i] == Approx((el.lambda + 2 * el.mu) * a).epsilon(0.01));
    u = zero_field(b.size());
    for (std::size_t k = 0; k < b.size(); ++k) u[1][k] = 0.5 * a * b.points.x[0][k] * b.points.x[0][k];
    m.forces(b, u, f);
    CHECK(f[1][i] == Approx(el.mu * a).epsilon(0.01));
  }
  // 1D bar: f = E a.
  Body bar = lattice_body(interval(-1, 1), 0.01, 0.08, true);
  const auto m1 = Rnp::from_elastic(E, 100.0, 0.08, Kinematics::bar, 1);
  VectorField u = zero_field(bar.size()), f = zero_field(bar.size());
  for (std::size_t k = 0; k < bar.size(); ++k) u[0][k] = 0.5 * a * bar.points.x[0][k] * bar.points.x[0][k];
  m1.forces(bar, u, f);
  CHECK(f[0][nearest(bar.points, {0.005, 0, 0})] == Approx(E * a).epsilon(0.01));
}

TEST_CASE("breaking every RNP bond across a plane costs the deck's fracture energy G_c") {
  // Energy of a fully softened bond pair: P C w (both directions); summed over the pairs that
  // cross y = 0 per unit length, on a fine lattice: G_c = C P 2 eps^3 / 3 in 2D.
  const double E = 72e9, Gc = 3.8, eps = 1e-3;
  const auto m = Rnp::from_elastic(E, Gc, eps, Kinematics::plane_stress, 2);
  const int n = 40;
  const double h = eps / n, V = h * h;
  double energy = 0;
  for (int iy = 0; iy < n; ++iy)
    for (int jy = 0; jy < n; ++jy)
      for (int dx = -n; dx <= n; ++dx) {
        const double r = std::hypot(dx * h, (iy + jy + 1) * h);
        if (r <= eps) energy += m.prefactor * m.C * V * V;  // g(infinity) = C, P/2 each way
      }
  CHECK(energy / h == Approx(Gc).epsilon(0.01));  // one column of i per unit length: divide by h
}

TEST_CASE("the 1D bar converges in one Newton step to the classical strain F / (A E), closer with the volume correction", "[slow]") {
  double ratio[2];
  for (int partial = 0; partial < 2; ++partial) {
    Problem p = read_deck(rnp_deck("bar_1d.yaml"));
    p.partial_volume = partial;
    auto s = setup_quasi_static(p);
    QuasiStaticSolver solver(s.body, s.model, s.boundaries, s.solver.options);
    VectorField u = zero_field(s.body.size());
    const auto reports = solver.run(u);
    REQUIRE(reports.size() == 1);
    CHECK(reports[0].iterations <= 3);
    const auto end = nearest(s.body.points, {16, 0, 0});
    // Displacement of the end node over its distance from the clamped node, against F/(A E) = 1e-9.
    ratio[partial] = u[0][end] / (s.body.points.x[0][end] - 0.125) / 1e-9;
    WARN("u_end / L over eps_CCM " << (partial ? "with" : "without") << " the volume correction: " << ratio[partial]);
  }
  CHECK(std::abs(ratio[1] - 1) < std::abs(ratio[0] - 1));
  CHECK(ratio[1] == Approx(1.0).epsilon(0.05));
}

namespace {

// max_i |u - v| and max_i |u| over both components of a 2D field.
std::pair<double, double> difference_2d(const VectorField& u, const VectorField& v) {
  double diff = 0, scale = 0;
  for (int k = 0; k < 2; ++k)
    for (std::size_t i = 0; i < u[k].size(); ++i) diff = std::max(diff, std::abs(u[k][i] - v[k][i])), scale = std::max(scale, std::abs(u[k][i]));
  return {diff, scale};
}

}  // namespace

TEST_CASE("Newton on the 2D plate converges in at most 3 iterations, and Ceres' trust region reaches the same solution", "[slow]") {
  Problem p = read_deck(rnp_deck("plate_2d.yaml"));
  auto s = setup_quasi_static(p);
  QuasiStaticSolver newton(s.body, s.model, s.boundaries, s.solver.options);
  VectorField u = zero_field(s.body.size());
  const auto r = newton.run(u);
  REQUIRE(r.size() == 1);
  CHECK(r[0].iterations <= 3);
  CHECK(r[0].linear_solver == "cholmod");  // elastic: -K is SPD
  auto options = s.solver.options;
  options.nonlinear = QsNonlinear::ceres;
  QuasiStaticSolver ceres(s.body, s.model, s.boundaries, options);
  VectorField v = zero_field(s.body.size());
  const auto rc = ceres.run(v);
  REQUIRE(rc.size() == 1);
  const auto [diff, scale] = difference_2d(u, v);
  CHECK(diff < 1e-8 * scale);
  CHECK(rc[0].linear_solver == "ceres LM (dense normal Cholesky)");  // 480 unknowns
  // Plain Newton (no line search) lands on the same solution.
  options = s.solver.options;
  options.line_search = false;
  QuasiStaticSolver plain(s.body, s.model, s.boundaries, options);
  VectorField w = zero_field(s.body.size());
  plain.run(w);
  for (std::size_t i = 0; i < s.body.size(); ++i) REQUIRE(std::abs(w[0][i] - u[0][i]) <= 1e-10 * scale);
}

TEST_CASE("Above 600 unknowns Ceres solves its normal equations sparse and still reaches Newton's solution", "[slow]") {
  Problem p = read_deck(rnp_deck("plate_2d.yaml"));
  p.lattice.spacing = 0.07;  // 966 unknowns
  auto s = setup_quasi_static(p);
  QuasiStaticSolver newton(s.body, s.model, s.boundaries, s.solver.options);
  VectorField u = zero_field(s.body.size());
  newton.run(u);
  auto options = s.solver.options;
  options.nonlinear = QsNonlinear::ceres;
  QuasiStaticSolver ceres(s.body, s.model, s.boundaries, options);
  REQUIRE(ceres.system().unknowns() > ceres_dense_max_unknowns);
  VectorField v = zero_field(s.body.size());
  const auto rc = ceres.run(v);
  REQUIRE(rc.size() == 1);
  CHECK(rc[0].linear_solver == "ceres LM (sparse normal Cholesky)");
  const auto [diff, scale] = difference_2d(u, v);
  CHECK(diff < 1e-8 * scale);
}

namespace {

// Classical plane-stress solution of the same plate with P1 triangles (1.6 / n cells).
struct Classical {
  TriangleMesh mesh;
  std::vector<std::array<double, 2>> u;
};

Classical classical_plate(const Rnp& m, int n) {
  P1Problem p;
  // Peridot's convention: the small-strain micromodulus of E in plane stress, nu = 1/3.
  const double E = 4 * m.C * m.beta / 9;
  p.material = lame(E, 1.0 / 3.0, Kinematics::plane_stress);
  p.body_force = [](const Vec3& x) { return std::array<double, 2>{x[0] < 0.5 ? -50.0 : 0.0, 0.0}; };
  p.clamped = [](const Vec3& x) { return x[0] >= 1.5 - 1e-12; };
  Classical c{structured_triangles({0, 0, 0}, {1.6, 1.6, 0}, n, n), {}};
  c.u = solve_p1_elasticity(c.mesh, p);
  return c;
}

}  // namespace

TEST_CASE("refined at fixed m = delta / h = 5, the RNP plate approaches the classical (P1 finite element) solution at order 1.5 or better", "[slow]") {
  Problem base = read_deck(rnp_deck("plate_2d.yaml"));
  const auto fe = classical_plate(std::get<Rnp>(make_model(base)), 160);
  std::vector<double> errors;
  for (double h : {0.1, 0.05, 0.025}) {
    Problem p = base;
    p.lattice.spacing = h;
    p.horizon = 5 * h;
    auto s = setup_quasi_static(p);
    QuasiStaticSolver solver(s.body, s.model, s.boundaries, s.solver.options);
    VectorField u = zero_field(s.body.size());
    const auto r = solver.run(u);
    CHECK(r.back().iterations <= 3);
    // Relative L2 difference of u over the nodes, against the P1 solution at the same points.
    double num = 0, den = 0;
    for (std::size_t i = 0; i < s.body.size(); ++i) {
      const auto ref = interpolate(fe.mesh, fe.u, s.body.points.position(i));
      num += std::pow(u[0][i] - ref[0], 2) + std::pow(u[1][i] - ref[1], 2);
      den += ref[0] * ref[0] + ref[1] * ref[1];
    }
    errors.push_back(std::sqrt(num / den));
    const auto i0 = nearest(s.body.points, {0, 0.8, 0});
    WARN("h = " << h << ": relative L2 difference from P1 " << errors.back() << "; u_x at (" << s.body.points.x[0][i0] << ", "
                << s.body.points.x[1][i0] << ") = " << u[0][i0] << " (P1: " << interpolate(fe.mesh, fe.u, s.body.points.position(i0))[0] << ")");
  }
  // The nonlocal operator differs from the local one by O(delta^2) in the bulk; the softer strips
  // of width delta along the free edges (surface effect) add an O(delta) part, so the order falls
  // from 2 towards 1 under refinement. Measured on these levels (1 and 2 threads alike): 2.04
  // (h = 0.1 to 0.05) and 1.63 (0.05 to 0.025), the bulk term still dominant. The bound 1.5 holds
  // there and fails if either term is lost (a first-order bulk error, or a larger edge error).
  for (std::size_t k = 0; k + 1 < errors.size(); ++k) {
    const double order = std::log2(errors[k] / errors[k + 1]);
    INFO("observed order between levels " << k << " and " << k + 1 << ": " << order);
    CHECK(order >= 1.5);
  }
}

TEST_CASE("the RNP model runs in the explicit solver: a pulse in a 1D bar travels at sqrt(E / rho) within 2%", "[slow]") {
  Problem p = read_deck(rnp_deck("bar_1d_explicit.yaml"));
  Setup s = setup(p);
  const auto& m = std::get<Rnp>(s.model);
  ExplicitSolver solver(s.body, m, s.boundaries, s.time_step);
  State st(s.body.size());
  solver.initialize(st);
  const auto i1 = nearest(s.body.points, {0.1, 0, 0}), i2 = nearest(s.body.points, {0.2, 0, 0});
  // Arrival: the displacement reaches half its plateau, v0 T / 2 with the table's mean of 1/2.
  const double half = 0.5 * 0.1 * 10e-6 * 0.5;
  double t1 = -1, t2 = -1;
  for (std::size_t k = 0; k < s.time_step.steps; ++k) {
    solver.step(st);
    if (t1 < 0 && st.u[0][i1] >= half) t1 = st.time;
    if (t2 < 0 && st.u[0][i2] >= half) t2 = st.time;
  }
  REQUIRE(t1 > 0);
  REQUIRE(t2 > t1);
  const double speed = (s.body.points.x[0][i2] - s.body.points.x[0][i1]) / (t2 - t1);
  INFO("measured " << speed << " m/s");
  CHECK(speed == Approx(std::sqrt(200e9 / 7800)).epsilon(0.02));
}

TEST_CASE("with a linear influence J = 1 - r the E convention still gives div sigma of the deck's E within 1%") {
  const double E = 2.0e9, a = 1e-3, h = 0.01, delta = 8 * h;
  Body b = lattice_body(rectangle({-0.3, -0.3, 0}, {0.3, 0.3, 0}), h, delta, true);
  const auto m = Rnp::from_elastic(E, 100.0, delta, Kinematics::plane_stress, 2, RnpInfluence::linear);
  const auto el = lame(E, 1.0 / 3.0, Kinematics::plane_stress);
  VectorField u = zero_field(b.size()), f = zero_field(b.size());
  for (std::size_t k = 0; k < b.size(); ++k) u[0][k] = 0.5 * a * b.points.x[0][k] * b.points.x[0][k];
  m.forces(b, u, f);
  CHECK(f[0][nearest(b.points, {0.005, 0.005, 0})] == Approx((el.lambda + 2 * el.mu) * a).epsilon(0.01));
}

TEST_CASE("with break_factor set, RNP bonds past that multiple of r_c break for good from both ends") {
  Body b = lattice_body(rectangle({0, 0, 0}, {1, 0.5, 0}), 0.05, 0.15, false);
  const auto m = Rnp::make(2, 1.0, 1.0, 0.15, 2.0);
  VectorField u = zero_field(b.size()), f = zero_field(b.size());
  // Open a gap at x = 0.5 wide enough that every crossing bond passes 2 r_c.
  for (std::size_t i = 0; i < b.size(); ++i) u[0][i] = b.points.x[0][i] > 0.5 ? 5.0 : 0.0;
  const auto first = m.forces(b, u, f).newly_broken_directed;
  REQUIRE(first > 0);
  CHECK(b.bonds.broken() == first);
  CHECK(bond_pairs::broken_one_way(b.bonds) == 0);
  for (auto& c : u) std::fill(c.begin(), c.end(), 0.0);
  CHECK(m.forces(b, u, f).newly_broken_directed == 0);  // unloading does not heal
  CHECK(b.bonds.broken() == first);
  // Without a break factor the same stretch only softens.
  Body c = lattice_body(rectangle({0, 0, 0}, {1, 0.5, 0}), 0.05, 0.15, false);
  const auto soft = Rnp::make(2, 1.0, 1.0, 0.15);
  for (std::size_t i = 0; i < c.size(); ++i) u[0][i] = c.points.x[0][i] > 0.5 ? 5.0 : 0.0;
  CHECK(soft.forces(c, u, f).newly_broken_directed == 0);
  CHECK(soft.softening_bonds(c, u) > 0);
}

TEST_CASE("Newton with the finite-difference tangent (eq. 36) reaches the analytic-tangent solution of the plate") {
  Problem p = read_deck(rnp_deck("plate_2d.yaml"));
  auto s = setup_quasi_static(p);
  QuasiStaticSolver analytic(s.body, s.model, s.boundaries, s.solver.options);
  VectorField u = zero_field(s.body.size());
  const auto ra = analytic.run(u);
  auto options = s.solver.options;
  options.tangent = QsTangent::finite_difference;
  QuasiStaticSolver fd(s.body, s.model, s.boundaries, options);
  VectorField v = zero_field(s.body.size());
  const auto rf = fd.run(v);
  WARN("plate: analytic tangent " << ra[0].iterations << " iterations in " << ra[0].seconds << " s; finite differences "
                                  << rf[0].iterations << " iterations in " << rf[0].seconds << " s");
  double diff = 0, scale = 0;
  for (std::size_t i = 0; i < s.body.size(); ++i) diff = std::max(diff, std::abs(u[0][i] - v[0][i])), scale = std::max(scale, std::abs(u[0][i]));
  CHECK(diff < 1e-8 * scale);
  CHECK(rf[0].iterations <= ra[0].iterations + 1);
}

namespace {

// Three points on a line: 0 clamped, 1 free along x, 2 pulled along x by lambda * 1 m. Bond a
// (0-1, 0.1 m) is short and bond b (1-2, 1 m) long, with V_2 = 3.5 V_0, so a softens first and
// b, unloading, gives back more length than a gains: the path snaps back. With RNP's pair force
// g(S, L) ~ S exp(-beta L S^2), point 1 balances when g(S_a, L_a) V_0 = g(S_b, L_b) V_2, and the
// load is lambda = L_a S_a + L_b S_b (m, over the full load's 1 m).
struct SnapBack {
  static constexpr double La = 0.1, Lb = 1.0, V0 = 1.0, V2 = 3.5, beta = 1.0;
  Body body;
  Rnp model = Rnp::make(2, 1.0, beta, 1.05);
  std::vector<Boundary> boundaries;
  SnapBack() {
    body.points.dim = 2;
    body.points.push_back({0, 0, 0}, V0);
    body.points.push_back({La, 0, 0}, 1.0);
    body.points.push_back({La + Lb, 0, 0}, V2);
    body.bonds = build_bonds(body.points, {.horizon = 1.05});  // 0-2 (1.1 m) is outside
    body.density = 1;
    boundaries.push_back({.name = "clamp", .kind = BoundaryKind::displacement, .points = {0}});
    boundaries.push_back({.name = "pull", .kind = BoundaryKind::displacement, .points = {2}, .value = {1.0, 0, 0}});
    boundaries.push_back({.name = "line", .kind = BoundaryKind::displacement, .points = {1}, .components = {false, true, false}});
  }
  static double g(double S, double L) { return S * std::exp(-beta * L * S * S); }
  // Out of balance of point 1 at (lambda, u_1), relative to the larger pull.
  static double imbalance(double lambda, double u1) {
    const double a = g(u1 / La, La) * V0, b = g((lambda - u1) / Lb, Lb) * V2;
    return std::abs(a - b) / std::max(a, b);
  }
  // The closed-form path's first maximum of lambda and the minimum after it: S_a runs up, S_b
  // solves the balance on its rising branch (bisection).
  static std::pair<double, double> extremes() {
    const double Sb_top = 1 / std::sqrt(2 * beta * Lb);
    double peak = 0, valley = INFINITY, last = 0;
    for (double Sa = 0.0005; Sa < 8; Sa += 0.0005) {
      const double target = g(Sa, La) * V0 / V2;
      double lo = 0, hi = Sb_top;
      for (int k = 0; k < 100; ++k) (g(0.5 * (lo + hi), Lb) < target ? lo : hi) = 0.5 * (lo + hi);
      const double lambda = La * Sa + Lb * lo;
      if (lambda >= last && valley == INFINITY) peak = lambda;
      else valley = std::min(valley, lambda);
      last = lambda;
    }
    return {peak, valley};
  }
};

}  // namespace

TEST_CASE("arc length follows a hard-loaded softening chain down its snap-back and up to the full load, every arc in closed-form balance, where load control stops at the peak") {
  SnapBack chain;
  const auto [peak, valley] = SnapBack::extremes();
  // Below the full load: the path must come down and go up again.
  REQUIRE(peak == Approx(0.733).margin(0.002));
  REQUIRE(valley == Approx(0.619).margin(0.002));
  QuasiStaticOptions o;
  o.steps = 40;
  o.line_search = false;
  // Load control cannot pass the peak: its increments are cut down to min_increment there.
  double load_top = 0;
  {
    QuasiStaticSolver load(chain.body, chain.model, chain.boundaries, o);
    VectorField u = zero_field(3);
    CHECK_THROWS_AS(load.run(u, [&](const LoadStepReport& r, const VectorField&) { load_top = r.load; }), LoadPathFailure);
  }
  CHECK(load_top <= peak + 1e-9);
  CHECK(load_top > peak - 1e-3);
  o.control = QsControl::arc_length;
  QuasiStaticSolver arc(chain.body, chain.model, chain.boundaries, o);
  VectorField u = zero_field(3);
  double top = 0, bottom = INFINITY, previous_load = 0, previous_u1 = 0, worst = 0, arc_jump = 0;
  std::size_t falling = 0, arcs = 0;
  while (!arc.done() && arcs < 1000) {
    const auto r = arc.advance(u);
    ++arcs;
    worst = std::max(worst, SnapBack::imbalance(r.load, u[0][1]));
    CHECK(u[0][1] > previous_u1);  // bond a only ever stretches
    arc_jump = std::max(arc_jump, u[0][1] - previous_u1);
    if (r.load < previous_load) ++falling, bottom = std::min(bottom, r.load);
    if (!falling) top = r.load;
    previous_load = r.load, previous_u1 = u[0][1];
  }
  INFO(arcs << " arcs, first peak " << top << " (closed form " << peak << "), lowest after it " << bottom << " (" << valley
            << "); largest step of point 1 " << arc_jump << " m");
  REQUIRE(arc.done());
  CHECK(previous_load == Approx(1.0));
  CHECK(u[0][2] == Approx(1.0));  // the pulled point at the full load
  CHECK(worst < 1e-7);
  CHECK(falling >= 5);
  CHECK(top <= peak + 1e-9);
  CHECK(top > peak - 0.01);
  CHECK(bottom >= valley - 1e-9);
  CHECK(bottom < valley + 0.01);
  CHECK(arc_jump < 0.05);
}

TEST_CASE("arc length stops with a load-path failure once a soft-loaded bond past its peak has fallen back to almost no load") {
  // One RNP bond, point 0 clamped, point 1 pulled along the bond by a body force 1.2 times the
  // bond's peak force: the path rises to lambda = 1 / 1.2 and then falls towards zero for ever.
  constexpr double L = 0.1, V = 1.0, beta = 1.0;
  Body body;
  body.points.dim = 2;
  body.points.push_back({0, 0, 0}, V);
  body.points.push_back({L, 0, 0}, V);
  body.bonds = build_bonds(body.points, {.horizon = 0.2});
  body.density = 1;
  const Rnp model = Rnp::make(2, 1.0, beta, 0.2);
  // The peak pull on point 1 (closed form, test_rnp's): P 2 C beta S* exp(-1/2) V, S* = 1 / sqrt(2 beta L).
  const double P = 2.0 / (0.2 * 0.2 * 0.2 * std::numbers::pi), S = 1 / std::sqrt(2 * beta * L);
  const double peak = P * 2 * beta * S * std::exp(-0.5) * V;
  std::vector<Boundary> bcs{{.name = "clamp", .kind = BoundaryKind::displacement, .points = {0}},
                            {.name = "line", .kind = BoundaryKind::displacement, .points = {1}, .components = {false, true, false}},
                            {.name = "pull", .kind = BoundaryKind::body_force, .points = {1}, .value = {1.2 * peak, 0, 0}}};
  QuasiStaticOptions o;
  o.steps = 20;
  o.min_increment = 1e-2;
  o.line_search = false;
  o.control = QsControl::arc_length;
  QuasiStaticSolver arc(body, model, bcs, o);
  VectorField u = zero_field(2);
  double top = 0, last = 0;
  std::size_t arcs = 0;
  std::string message;
  try {
    arc.run(u, [&](const LoadStepReport& r, const VectorField&) { top = std::max(top, r.load), last = r.load, ++arcs; });
  } catch (const LoadPathFailure& e) {
    message = e.what();
  }
  INFO(arcs << " arcs, peak " << top << ", last " << last << ": " << message);
  CHECK_THAT(message, Catch::Contains("fell back") && Catch::Contains("cannot carry the full load"));
  CHECK(top <= 1 / 1.2 + 1e-9);
  CHECK(top > 1 / 1.2 - 0.02);
  CHECK(last < 1e-2);
  CHECK(arcs < 2000);  // far below the 100 x steps bound
}
