#include <catch2/catch.hpp>
#include "../support/bond_pairs.hpp"
#include <cmath>
#include <numbers>
#include <vector>
import peridot.analysis;

using namespace peridot;

namespace {

// Index of the point nearest to p.
std::size_t nearest(const PointCloud& pc, Vec3 p) {
  std::size_t best = 0;
  double d = 1e300;
  for (std::size_t i = 0; i < pc.size(); ++i) {
    const double e = norm(pc.position(i) - p);
    if (e < d) d = e, best = i;
  }
  return best;
}

Body make_body(const Shape& s, double h, double delta, bool partial) {
  Body b;
  b.points = lattice(s, {.spacing = h});
  b.bonds = build_bonds(b.points, {.horizon = delta, .partial_volume = partial});
  b.density = 1000;
  return b;
}

// Uniaxial strain u = eps (x - x0) e_x; returns the bulk stress (seed 004 eq. 49) at the centre
// point, row-major 3x3.
std::array<double, 9> centre_stress(const Body& b, const Pmb& m, double eps, Vec3 centre) {
  State s(b.size());
  for (std::size_t i = 0; i < b.size(); ++i) s.u[0][i] = eps * (b.points.x[0][i] - centre[0]);
  std::vector<double> g;
  m.pair_forces(b, s.u, g);
  const auto t = bulk_stress(b, g);
  const auto i = nearest(b.points, centre);
  const double zz = t.zz.empty() ? 0.0 : t.zz[i], yz = t.yz.empty() ? 0.0 : t.yz[i], xz = t.xz.empty() ? 0.0 : t.xz[i];
  return {t.xx[i], t.xy[i], xz, t.xy[i], t.yy[i], yz, xz, yz, zz};
}

}  // namespace

TEST_CASE("PMB under homogeneous strain gives the classical bulk stress within 2% at delta = 4h (2D plane stress)") {
  const double E = 72e9, h = 1e-3, delta = 4 * h, eps = 1e-6;
  const auto body = make_body(rectangle({0, 0, 0}, {0.03, 0.03, 0}), h, delta, true);
  const auto pmb = Pmb::from_elastic(E, 3.8, delta, Kinematics::plane_stress);
  const auto el = lame(E, bond_based_poisson_ratio(Kinematics::plane_stress), Kinematics::plane_stress);
  const auto sigma = centre_stress(body, pmb, eps, {0.015, 0.015, 0});
  CHECK(sigma[0] == Approx((el.lambda + 2 * el.mu) * eps).epsilon(0.02));
  CHECK(sigma[4] == Approx(el.lambda * eps).epsilon(0.02));
  CHECK(std::abs(sigma[1]) < 1e-6 * std::abs(sigma[0]));
}

TEST_CASE("PMB under homogeneous strain gives the classical bulk stress within 2% at delta = 4h (2D plane strain)") {
  const double E = 1e9, h = 1e-3, delta = 4 * h, eps = 1e-6;
  const auto body = make_body(rectangle({0, 0, 0}, {0.03, 0.03, 0}), h, delta, true);
  const auto pmb = Pmb::from_elastic(E, 1.0, delta, Kinematics::plane_strain);
  const auto el = lame(E, 0.25, Kinematics::plane_strain);
  const auto sigma = centre_stress(body, pmb, eps, {0.015, 0.015, 0});
  CHECK(sigma[0] == Approx((el.lambda + 2 * el.mu) * eps).epsilon(0.02));
  CHECK(sigma[4] == Approx(el.lambda * eps).epsilon(0.02));
}

TEST_CASE("PMB under homogeneous strain gives the classical bulk stress within 2% at delta = 4h (3D)") {
  const double E = 200e9, h = 1e-3, delta = 4 * h, eps = 1e-6;
  const auto body = make_body(box({0, 0, 0}, {0.013, 0.013, 0.013}), h, delta, true);
  const auto pmb = Pmb::from_elastic(E, 1.0, delta, Kinematics::solid);
  const auto el = lame(E, 0.25, Kinematics::solid);
  const auto sigma = centre_stress(body, pmb, eps, {0.0065, 0.0065, 0.0065});
  CHECK(sigma[0] == Approx((el.lambda + 2 * el.mu) * eps).epsilon(0.02));
  CHECK(sigma[4] == Approx(el.lambda * eps).epsilon(0.02));
  CHECK(sigma[8] == Approx(el.lambda * eps).epsilon(0.02));
}

TEST_CASE("without the partial-volume correction the lattice sum misses the classical stress by more") {
  const double E = 72e9, h = 1e-3, delta = 4 * h, eps = 1e-6;
  const auto pmb = Pmb::from_elastic(E, 3.8, delta, Kinematics::plane_stress);
  const double exact = 9.0 / 8.0 * E * eps;
  const auto with = centre_stress(make_body(rectangle({0, 0, 0}, {0.03, 0.03, 0}), h, delta, true), pmb, eps, {0.015, 0.015, 0});
  const auto without = centre_stress(make_body(rectangle({0, 0, 0}, {0.03, 0.03, 0}), h, delta, false), pmb, eps, {0.015, 0.015, 0});
  CHECK(std::abs(with[0] - exact) < std::abs(without[0] - exact));
}

namespace {

// Energy to break every bond that crosses the plane y = 0, per unit area (2D: per unit length),
// summed pair by pair over a lattice of spacing h = delta / n: each bond stores
// w = c s0^2 |xi| / 2 per unit volume squared when it breaks (the PMB micropotential at s0).
// Points i below the plane inside a window of width `a` in x (and z); partners j anywhere above.
double lattice_fracture_energy(const Pmb& m, double delta, int n, int dim) {
  const double h = delta / n, a = 2 * delta;
  const int na = int(std::lround(a / h));
  const double V = dim == 2 ? h * h : h * h * h;
  double energy = 0;
  for (int iz = 0; iz < (dim == 3 ? na : 1); ++iz)
    for (int ix = 0; ix < na; ++ix)
      for (int iy = 0; iy < n; ++iy) {      // y_i = -(iy + 1/2) h
        for (int jy = 0; jy < n; ++jy)      // y_j = +(jy + 1/2) h
          for (int dx = -n; dx <= n; ++dx)
            for (int dz = (dim == 3 ? -n : 0); dz <= (dim == 3 ? n : 0); ++dz) {
              const double xi = std::sqrt(double(dx * dx + dz * dz) + double((iy + jy + 1) * (iy + jy + 1))) * h;
              if (xi <= delta * (1 + 1e-12)) energy += 0.5 * m.c * m.s0 * m.s0 * xi * V * V;
            }
      }
  return energy / (dim == 2 ? a : a * a);
}

}  // namespace

TEST_CASE("breaking every bond across a plane costs the deck's fracture energy G0, in 2D and 3D") {
  const double E = 72e9, G0 = 3.8, delta = 1e-3;
  for (auto kin : {Kinematics::plane_stress, Kinematics::plane_strain}) {
    const auto m = Pmb::from_elastic(E, G0, delta, kin);
    CHECK(lattice_fracture_energy(m, delta, 40, 2) == Approx(G0).epsilon(0.01));
  }
  const auto m3 = Pmb::from_elastic(E, G0, delta, Kinematics::solid);
  CHECK(lattice_fracture_energy(m3, delta, 16, 3) == Approx(G0).epsilon(0.02));
}

TEST_CASE("in 3D the force loop returns div sigma for a quadratic displacement, within 3% at delta = 4h") {
  // u_x = a x^2 / 2: eps_xx = a x, and div sigma = (lambda + 2 mu) a e_x with nu = 1/4.
  const double E = 1e9, h = 1e-3, delta = 4 * h, a = 1e-3;
  Body b = make_body(box({-0.008, -0.008, -0.008}, {0.008, 0.008, 0.008}), h, delta, true);
  const auto pmb = Pmb::from_elastic(E, 1e6, delta, Kinematics::solid);
  const auto el = lame(E, 0.25, Kinematics::solid);
  State s(b.size());
  for (std::size_t i = 0; i < b.size(); ++i) s.u[0][i] = 0.5 * a * b.points.x[0][i] * b.points.x[0][i];
  pmb.forces(b, s.u, s.f);
  const auto i = nearest(b.points, {0.0005, 0.0005, 0.0005});
  CHECK(s.f[0][i] == Approx((el.lambda + 2 * el.mu) * a).epsilon(0.03));
  CHECK(std::abs(s.f[1][i]) < 1e-6 * std::abs(s.f[0][i]));
}

TEST_CASE("bonds stretched past s0 break for good, from both ends, except in no-fail regions") {
  const double h = 1e-3;
  Body b = make_body(rectangle({0, 0, 0}, {0.02, 0.01, 0}), h, 3 * h, false);
  const auto pmb = Pmb::from_elastic(72e9, 3.8, 3 * h, Kinematics::plane_stress);
  State s(b.size());
  // Open a gap of 10 s0 delta between the halves x < 0.01 and x > 0.01.
  for (std::size_t i = 0; i < b.size(); ++i) s.u[0][i] = b.points.x[0][i] > 0.01 ? 10 * pmb.s0 * 3 * h : 0.0;
  const auto first = pmb.forces(b, s.u, s.f).newly_broken_directed;
  REQUIRE(first > 0);
  REQUIRE(b.bonds.broken() == first);
  REQUIRE(bond_pairs::broken_one_way(b.bonds) == 0);
  // Unloading does not heal.
  for (auto& c : s.u) std::fill(c.begin(), c.end(), 0.0);
  REQUIRE(pmb.forces(b, s.u, s.f).newly_broken_directed == 0);
  REQUIRE(b.bonds.broken() == first);
  const auto phi = damage(b);
  for (std::size_t i = 0; i < b.size(); ++i) {
    const double dx = std::abs(b.points.x[0][i] - 0.01);
    if (dx > 3 * h) REQUIRE(phi[i] == 0.0);
    if (dx < h) REQUIRE(phi[i] > 0.2);
  }
  // Same loading with every point in a no-fail region: nothing breaks.
  Body nf = make_body(rectangle({0, 0, 0}, {0.02, 0.01, 0}), h, 3 * h, false);
  nf.no_fail.assign(nf.size(), 1);
  for (std::size_t i = 0; i < nf.size(); ++i) s.u[0][i] = nf.points.x[0][i] > 0.01 ? 10 * pmb.s0 * 3 * h : 0.0;
  REQUIRE(pmb.forces(nf, s.u, s.f).newly_broken_directed == 0);
}

TEST_CASE("internal forces of an intact body sum to zero and vanish under rigid translation") {
  Body b = make_body(disk({0, 0, 0}, 0.01), 1e-3, 4e-3, true);
  const auto pmb = Pmb::from_elastic(1e9, 1e3, 4e-3, Kinematics::plane_stress);
  State s(b.size());
  for (std::size_t i = 0; i < b.size(); ++i) {
    s.u[0][i] = 1e-4 * std::sin(300 * b.points.x[1][i]);
    s.u[1][i] = 2e-5 * b.points.x[0][i];
  }
  pmb.forces(b, s.u, s.f);
  double fx = 0, fy = 0, scale = 0;
  for (std::size_t i = 0; i < b.size(); ++i) {
    fx += s.f[0][i] * b.points.volume[i];
    fy += s.f[1][i] * b.points.volume[i];
    scale += std::abs(s.f[0][i]) * b.points.volume[i];
  }
  CHECK(std::abs(fx) < 1e-12 * scale);
  CHECK(std::abs(fy) < 1e-12 * scale);
  for (std::size_t i = 0; i < b.size(); ++i) s.u[0][i] = 3e-3, s.u[1][i] = -1e-3;
  pmb.forces(b, s.u, s.f);
  for (std::size_t i = 0; i < b.size(); ++i) REQUIRE(std::abs(s.f[0][i]) < 1e-6 * scale / b.points.volume[i] / b.size());
}
