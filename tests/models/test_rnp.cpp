#include <catch2/catch.hpp>
#include <cmath>
#include <cstddef>
#include <numbers>
import peridot.models;

using namespace peridot;

namespace {

// Two points 0.3 m apart along (0.6, 0.8), bonded both ways (horizon 0.5 m), on a full, a
// compact (xi and |xi| from the positions) or a lean list (also float weights, and forces in
// single precision).
enum class Layout { full, compact, lean };
Body pair(Layout layout) {
  Body b;
  b.points.dim = 2;
  b.points.push_back({0.1, -0.2, 0}, 0.01);
  b.points.push_back({0.1 + 0.18, -0.2 + 0.24, 0}, 0.02);
  b.bonds = build_bonds(b.points, {.horizon = 0.5, .lean = layout == Layout::lean, .geometry = layout == Layout::full});
  b.density = 1;
  return b;
}

}  // namespace

TEST_CASE("an RNP bond gives the pair force of its closed form below break_factor r_c and breaks for good, both ways, just above it, on every list") {
  const double C = 3.0, beta = 40.0, eps = 0.5, bf = 2.0, L = 0.3;
  const Rnp m = Rnp::make(2, C, beta, eps, bf);
  const double rc = std::sqrt(0.5 / beta), P = 2.0 / (eps * eps * eps * std::numbers::pi);
  for (Layout layout : {Layout::full, Layout::compact, Layout::lean}) {
    INFO((layout == Layout::full ? "full list" : layout == Layout::compact ? "compact list" : "lean list"));
    // Single precision: a few float roundings of the force.
    const double tolerance = layout == Layout::lean ? 1e-6 : 1e-12;
    for (double ratio : {0.99, 1.01}) {
      INFO("sqrt|xi| S / (break_factor r_c) = " << ratio);
      Body b = pair(layout);
      REQUIRE(b.bonds.size() == 2);
      REQUIRE(b.bonds.compact() == (layout == Layout::compact));
      REQUIRE(b.bonds.lean() == (layout == Layout::lean));
      // Point 1 moves along the bond: S = du / |xi|, and sqrt|xi| S = ratio bf r_c.
      const double S = ratio * bf * rc / std::sqrt(L), du = S * L;
      VectorField u = zero_field(2), f = zero_field(2);
      u[0][1] = 0.6 * du;
      u[1][1] = 0.8 * du;
      const ForceReport report = m.forces(b, u, f);
      if (ratio < 1) {
        CHECK(report.newly_broken_directed == 0);
        CHECK(b.bonds.intact[0] == 1);
        CHECK(b.bonds.intact[1] == 1);
        // f_i = P 2 C beta S exp(-beta |xi| S^2) w_ij e, w_ij = V_j (volume quadrature).
        const double g = P * 2 * C * beta * S * std::exp(-beta * L * S * S);
        CHECK(f[0][0] == Approx(g * 0.02 * 0.6).epsilon(tolerance));
        CHECK(f[1][0] == Approx(g * 0.02 * 0.8).epsilon(tolerance));
        CHECK(f[0][1] == Approx(-g * 0.01 * 0.6).epsilon(tolerance));
        CHECK(f[1][1] == Approx(-g * 0.01 * 0.8).epsilon(tolerance));
      } else {
        CHECK(report.newly_broken_directed == 2);
        CHECK(b.bonds.intact[0] == 0);
        CHECK(b.bonds.intact[1] == 0);
        CHECK(f[0][0] == 0);
        CHECK(f[1][1] == 0);
        // For good: back at rest the bond stays broken.
        u = zero_field(2);
        CHECK(m.forces(b, u, f).newly_broken_directed == 0);
        CHECK(b.bonds.intact[0] == 0);
      }
    }
  }
}
