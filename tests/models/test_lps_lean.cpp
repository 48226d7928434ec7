// Explicit LPS in single precision (Lps::single_precision, lean_kernel.cpp's two LPS passes)
// against the double path on the same deck-built body (GMLS weights, exterior moments) as a
// second code path: dilatations and forces within the float analysis, break decisions that
// differ only within it of s0, and the AVX-512VL, AVX2 and portable kernels giving the same bits.
#include <omp.h>

#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <string>
#include <variant>
#include <vector>
#include "../support/deck_text.hpp"
#include "../support/lean_checks.hpp"
#include "../support/max_abs.hpp"
#include "../support/same.hpp"
import peridot.run;

using namespace peridot;
namespace fs = std::filesystem;

namespace {

// 2^-24: the relative rounding of a double to the nearest float.
constexpr double float_rounding = 5.9604644775390625e-8;

struct Case {
  Body body;
  Lps model;
};

// The explicit glass plate at h = 1 mm (2D, 4,000 points) or the LPS Kalthoff-Winkler block at
// dx = 2 mm (3D, 25,000 points), set up by the library in double.
Case deck_case(int dim) {
  const fs::path deck = fs::path(PERIDOT_SOURCE_DIR) / "data/decks" / (dim == 2 ? "lps_dynamic/glass_plate_explicit.yaml" : "lps_3d/kalthoff_winkler.yaml");
  std::string text = deck_text::file_text(deck);
  if (dim == 2) {
    text = deck_text::replaced(text, "spacing: 5.0e-4 ", "spacing: 1.0e-3 ");
  } else {
    text = deck_text::replaced(text, "spacing: 1.0e-3 ", "spacing: 2.0e-3 ");
    text = deck_text::replaced(text, "horizon: 3.0e-3 ", "horizon: 6.0e-3 ");
  }
  Problem p = parse_deck(text, deck.string());
  p.output = OutputSpec{};
  Setup s = std::get<Setup>(compose(p));
  return {std::move(s.body), std::get<Lps>(s.model)};
}

// The same model in single precision on a copy of the body.
Case single_of(const Case& c, int vector = -1) {
  Case s{c.body, c.model};
  s.model.single_precision = true;
  s.model.lean_vector = vector;
  s.model.prepare(s.body);
  return s;
}

// A smooth field with strains up to `strain`, plus an opening of `jump` s0 delta across the
// vertical line through the body's middle.
VectorField field(const Body& b, double delta, double strain, double jump, double s0) {
  const std::size_t n = b.size();
  double lo = b.points.x[0][0], hi = lo, ylo = b.points.x[1][0], yhi = ylo;
  for (std::size_t i = 0; i < n; ++i) {
    lo = std::min(lo, b.points.x[0][i]), hi = std::max(hi, b.points.x[0][i]);
    ylo = std::min(ylo, b.points.x[1][i]), yhi = std::max(yhi, b.points.x[1][i]);
  }
  const double k1 = 6.0 / (yhi - ylo), k2 = 5.0 / (hi - lo), k3 = 4.0 / (hi - lo), mid = 0.5 * (lo + hi) + 0.3 * delta;
  VectorField u = zero_field(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double x = b.points.x[0][i], y = b.points.x[1][i];
    u[0][i] = strain / k1 * std::sin(k1 * y + 0.3) + strain * 0.4 * x + (x > mid ? jump * s0 * delta : 0.0);
    u[1][i] = strain / k2 * std::sin(k2 * x) - strain * 0.1 * y;
    if (b.dim() == 3) u[2][i] = strain / k3 * std::sin(k3 * x + 50 * y);
  }
  return u;
}

// Per point, the float analysis's bound on |f_single - f_double| and the sum of the bond terms'
// magnitudes, over the intact bonds of `b` (the double path's masks):
//  - inputs: the bond vector is within sqrt(3) q + 2^-24 |xi| < 4 delta 2^-24 (fixed point, then
//    float); eta = u_j - u_i from float u / q within (4 |u|max + |eta|) 2^-24; M_i's entries and the
//    weights are rounded once;
//  - dilatation: per bond t = w (M xi) . eta / |xi| takes about 12 roundings and |xi|'s error moves
//    1 / |xi| by 4 delta / |xi| 2^-24, so
//      dt <= 2^-24 |w| |M| / |xi| ((18 + 4 delta / |xi|) |xi| |eta| + 4 delta |eta| + 4 |xi| |u|max),
//    plus 2 roundings of |t| in the float partial sums; theta = d / m sum t;
//  - force: per bond g xi = w / |xi| (ct (theta_i + theta_j) + cs xi . eta / |xi|^2) xi: the two
//    dilatations' errors and their rounding to float, xi . eta's error as above, and about 16
//    roundings plus 16 delta / |xi| of |ct part| + |cs part|, 2 more in the partial sums; the w^
//    term a_i theta_i carries theta_i's error.
struct Bounds {
  std::vector<double> bound, total;
};

Bounds force_bounds(const Body& b, const Lps& m, const VectorField& u) {
  const double umax = max_abs(u), ct = m.theta_coefficient(0, 0, 1.0), cs = m.shear_coefficient(0, 0, 1.0, 1.0);
  const double scale = m.dim / m.m;
  const std::size_t n = b.size();
  std::vector<LpsFrame> frames(n);
  std::vector<double> theta(n), dtheta(n);
  const auto bonds_of = [&](std::size_t i, auto&& f) {
    for (auto q = b.bonds.begin(i); q < b.bonds.end(i); ++q) {
      if (!b.bonds.intact[std::size_t(q)]) continue;
      const auto j = std::size_t(b.bonds.neighbor[std::size_t(q)]);
      const BondGeometry g = bond_geometry(b.points, b.bonds, i, q);
      const double eta = std::hypot(u[0][j] - u[0][i], u[1][j] - u[1][i], u[2][j] - u[2][i]);
      f(j, g, std::abs(b.bonds.weight[std::size_t(q)]), eta);
    }
  };
  for (std::size_t i = 0; i < n; ++i) {
    frames[i] = lps_frame(b, m, i, m.exterior.empty() ? nullptr : &m.exterior[i]);
    theta[i] = lps_dilatation(b, m, frames[i], i, u);
    double Mn = 0;
    for (double v : frames[i].M) Mn += v * v;
    Mn = std::sqrt(Mn);
    double err = 0, total = 0;
    bonds_of(i, [&](std::size_t, const BondGeometry& g, double w, double eta) {
      const double L = g.len;
      err += w * Mn / L * ((18 + 4 * m.delta / L) * L * eta + 4 * m.delta * eta + 4 * L * umax);
      total += w * Mn * eta;
    });
    dtheta[i] = scale * float_rounding * (err + 2 * total);
  }
  Bounds out{std::vector<double>(n), std::vector<double>(n)};
  for (std::size_t i = 0; i < n; ++i) {
    double bound = 0, total = 0;
    bonds_of(i, [&](std::size_t j, const BondGeometry& g, double w, double eta) {
      const double L = g.len, Kw = w / L;
      double xu = 0;
      for (int k = 0; k < 3; ++k) xu += g.xi[k] * (u[std::size_t(k)][j] - u[std::size_t(k)][i]);
      const double t = std::abs(ct) * Kw * std::abs(theta[i] + theta[j]) * L, s = std::abs(cs) * Kw * std::abs(xu) / L;
      bound += std::abs(ct) * Kw * L * (dtheta[i] + dtheta[j] + float_rounding * (std::abs(theta[i]) + std::abs(theta[j])));
      bound += std::abs(cs) * Kw / L * float_rounding * (4 * m.delta * eta + L * (4 * umax + 4 * eta));
      bound += float_rounding * (18 + 16 * m.delta / L) * (t + s);
      total += t + s;
    });
    const auto a = m.missing_theta(i, frames[i]);
    out.bound[i] = bound + std::hypot(a[0], a[1], a[2]) * dtheta[i];
    out.total[i] = total;
  }
  return out;
}

}  // namespace

TEST_CASE("LPS's single-precision passes stay within their float analysis of the double path, in 2D and 3D") {
  for (int dim : {2, 3}) {
    INFO("dimension " << dim);
    Case dbl = deck_case(dim);
    dbl.model.s0 = 0;  // nothing breaks: forces alone
    dbl.model.prepare(dbl.body);
    Case sgl = single_of(dbl);
    const Body& b = dbl.body;
    const Lps& m = dbl.model;
    const VectorField u = field(b, m.delta, 2e-3, 0, 0);
    VectorField f_dbl = zero_field(b.size()), f_sgl = zero_field(b.size());
    m.forces(dbl.body, u, f_dbl);
    sgl.model.forces(sgl.body, u, f_sgl);
    // Within the float analysis (force_bounds) of the double forces.
    const Bounds e = force_bounds(b, m, u);
    double worst = 0, largest_bound = 0, largest_total = 0;
    for (std::size_t i = 0; i < b.size(); ++i) {
      largest_bound = std::max(largest_bound, e.bound[i]);
      largest_total = std::max(largest_total, e.total[i]);
      for (int k = 0; k < dim; ++k) {
        REQUIRE(std::abs(f_sgl[k][i] - f_dbl[k][i]) <= e.bound[i]);
        worst = std::max(worst, std::abs(f_sgl[k][i] - f_dbl[k][i]) / e.bound[i]);
      }
    }
    INFO("largest error / bound " << worst);
    CHECK(worst > 0);                                // the paths do differ: not one code path compared with itself
    CHECK(largest_bound <= 1e-4 * largest_total);    // and the analysis bounds something far below the forces
    // Observers read the list in double either way.
    CHECK(sgl.model.strain_energy(sgl.body, u) == dbl.model.strain_energy(dbl.body, u));
  }
}

TEST_CASE("LPS's single-precision pass breaks the double path's bonds but within its float analysis of s0") {
  for (int dim : {2, 3}) {
    INFO("dimension " << dim);
    Case dbl = deck_case(dim);
    REQUIRE(dbl.model.s0 > 0);
    Case sgl = single_of(dbl);
    const double s0 = dbl.model.s0;
    const VectorField u = field(dbl.body, dbl.model.delta, 0.5 * s0, 4, s0);
    VectorField f_dbl = zero_field(dbl.body.size()), f_sgl = zero_field(dbl.body.size());
    const std::vector<std::uint8_t> before(dbl.body.bonds.intact.begin(), dbl.body.bonds.intact.end());
    const auto broken_dbl = dbl.model.forces(dbl.body, u, f_dbl).newly_broken_directed;
    const auto broken_sgl = sgl.model.forces(sgl.body, u, f_sgl).newly_broken_directed;
    REQUIRE(broken_dbl > 100);
    // The stretch from float inputs: |xi| within 4 delta 2^-24, eta within (4 |u|max + |eta|) 2^-24,
    // and 2 xi . eta + eta . eta in a few roundings: far inside 1e-5 of s0 here.
    const double umax = max_abs(u);
    std::size_t differ = 0;
    const Body& b = dbl.body;
    for (std::size_t i = 0; i < b.size(); ++i)
      for (auto q = b.bonds.begin(i); q < b.bonds.end(i); ++q)
        if (b.bonds.intact[std::size_t(q)] != sgl.body.bonds.intact[std::size_t(q)]) {
          const auto j = std::size_t(b.bonds.neighbor[std::size_t(q)]);
          const BondGeometry g = bond_geometry(b.points, b.bonds, i, q);
          double y2 = 0;
          for (int k = 0; k < 3; ++k) {
            const double y = g.xi[k] + u[std::size_t(k)][j] - u[std::size_t(k)][i];
            y2 += y * y;
          }
          const double s = std::sqrt(y2) / g.len - 1;
          REQUIRE(std::abs(s - s0) <= 1e-5 * s0 + 8 * umax / g.len * float_rounding);
          ++differ;
        }
    // The forces after breaking (new M_i, normals and dilatations where a bond broke) within the
    // float analysis on the double path's masks, at the points whose dilatations and partners'
    // dilatations saw the same masks on both paths.
    std::vector<std::uint8_t> same_row(b.size(), 1);
    for (std::size_t i = 0; i < b.size(); ++i)
      for (auto q = b.bonds.begin(i); q < b.bonds.end(i); ++q)
        if (b.bonds.intact[std::size_t(q)] != sgl.body.bonds.intact[std::size_t(q)]) same_row[i] = 0;
    const Bounds e = force_bounds(b, dbl.model, u);
    std::size_t compared = 0, near_break = 0;
    for (std::size_t i = 0; i < b.size(); ++i) {
      bool same = same_row[i] != 0;
      bool lost = false;
      for (auto q = b.bonds.begin(i); q < b.bonds.end(i); ++q) {
        same = same && same_row[std::size_t(b.bonds.neighbor[std::size_t(q)])];
        lost = lost || (before[std::size_t(q)] && !b.bonds.intact[std::size_t(q)]);
      }
      if (!same) continue;
      ++compared;
      near_break += lost;
      for (int k = 0; k < dim; ++k) REQUIRE(std::abs(f_sgl[k][i] - f_dbl[k][i]) <= e.bound[i]);
    }
    CHECK(compared >= b.size() * 9 / 10);
    CHECK(near_break > 50);  // points that lost a bond in this pass among them
    lean_checks::check_break_counts(broken_sgl, broken_dbl, differ);
  }
}

TEST_CASE("LPS's AVX-512VL, AVX2 and portable single-precision kernels give the same bits on any thread count, bonds breaking") {
  if (!lean_checks::vector_kernels_run()) return;
  for (int dim : {2, 3}) {
    INFO("dimension " << dim);
    const Case dbl = deck_case(dim);
    Case reference = single_of(dbl, 0);
    const double s0 = dbl.model.s0;
    const VectorField u = field(dbl.body, dbl.model.delta, 0.5 * s0, 4, s0);
    VectorField f_ref = zero_field(dbl.body.size());
    const auto broken_ref = reference.model.forces(reference.body, u, f_ref).newly_broken_directed;
    REQUIRE(broken_ref > 100);
    const int threads = omp_get_max_threads();
    for (int level : {1, -1})
      for (int t : {threads, 1}) {
        INFO("kernel level " << level << " (-1: the fastest) on " << t << " threads");
        Case c = single_of(dbl, level);
        VectorField f = zero_field(c.body.size());
        omp_set_num_threads(t);
        const auto broken = c.model.forces(c.body, u, f).newly_broken_directed;
        omp_set_num_threads(threads);
        CHECK(broken == broken_ref);
        CHECK(same::difference(c.body.bonds.intact, reference.body.bonds.intact, "intact") == "");
        CHECK(same::difference(f, f_ref, "f") == "");
      }
  }
}
