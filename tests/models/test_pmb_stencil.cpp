// PMB on a lattice stencil (a state byte per point and offset, float displacements) against PMB
// on the full CSR list (stored xi, double weights, double stretches) as a second code path, on
// lattice bodies with a hole, a pre-crack, partial volumes and no-fail points.
#include <catch2/catch.hpp>
#include <algorithm>
#include <cmath>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <omp.h>
#include "../support/same.hpp"
import peridot.analysis;

using namespace peridot;

namespace {

constexpr double float_rounding = 5.9604644775390625e-8;  // 2^-24
constexpr double h = 5e-4, delta = 3 * h;

struct Pair {
  Body list, stencil;
};

// The same lattice body twice: bonds as a full list and as a stencil. The pre-crack cuts
// bonds that stay in the body broken (precrack_damage), so damage sees them.
// In 3D a box `thickness` thick (0.004: 8 layers; 0.001: 2, thinner than the stencil's reach of 3).
Pair bodies(int dim, double thickness = 0.004) {
  const auto shape = dim == 2 ? subtract(rectangle({0, 0, 0}, {0.03, 0.015, 0}), disk({0.02, 0.008, 0}, 0.003))
                              : box({0, 0, 0}, {0.012, 0.008, thickness});
  const Crack crack = dim == 2 ? Crack{CrackSegment{{0.0, 0.00751, 0}, {0.01, 0.00751, 0}}}
                               : Crack{CrackRectangle{{-0.001, 0.00401, -0.001}, {0.007, 0, 0}, {0, 0, 0.008}}};
  Pair p;
  p.list.points = lattice(shape, {.spacing = h});
  p.list.bonds = build_bonds(p.list.points, {.horizon = delta, .partial_volume = true});
  cut_bonds(p.list.points, p.list.bonds, {crack});
  p.list.density = 2440;
  p.list.no_fail.assign(p.list.size(), 0);
  for (std::size_t i = 0; i < p.list.size(); ++i) p.list.no_fail[i] = p.list.points.x[1][i] < 1.2e-3;  // a no-fail strip
  p.stencil.points = p.list.points;
  p.stencil.density = 2440;
  p.stencil.no_fail = p.list.no_fail;
  std::string why;
  auto st = build_stencil(p.stencil.points, {.horizon = delta, .partial_volume = true, .cracks = {crack}}, true, why);
  REQUIRE(st.has_value());
  p.stencil.stencil = std::move(*st);
  set_no_fail(p.stencil.stencil, p.stencil.no_fail);
  return p;
}

// Smooth strains of order 1e-5 (below s0 = 1.8e-4 for glass at this horizon) plus, with
// `jump`, an opening of 3 s0 delta across x = 6 mm that breaks the bonds crossing it.
VectorField field(const Body& b, double s0, bool jump) {
  VectorField u = zero_field(b.size());
  for (std::size_t i = 0; i < b.size(); ++i) {
    const double x = b.points.x[0][i], y = b.points.x[1][i], z = b.points.x[2][i];
    u[0][i] = 2e-7 * std::sin(300 * y) + 1e-5 * x + (jump && x > 0.006 ? 3 * s0 * delta : 0.0);
    u[1][i] = 1.5e-7 * std::cos(250 * x) - 4e-6 * y;
    u[2][i] = b.dim() == 3 ? 1e-7 * std::sin(400 * z + 100 * x) : 0.0;
  }
  return u;
}

// Bonds of point i as (partner, weight, intact), sorted by partner.
using Bonds = std::vector<std::tuple<std::int32_t, double, int>>;
Bonds list_bonds(const Body& b, std::size_t i) {
  Bonds out;
  for (auto k = b.bonds.begin(i); k < b.bonds.end(i); ++k)
    out.emplace_back(b.bonds.neighbor[std::size_t(k)], b.bonds.weight_of(k), int(b.bonds.intact[std::size_t(k)]));
  std::sort(out.begin(), out.end());
  return out;
}
Bonds stencil_bonds(const Body& b, std::size_t i) {
  Bonds out;
  const Stencil& st = b.stencil;
  for (std::size_t k = 0; k < st.offsets(); ++k) {
    const auto s = st.state[st.state_index(i, k)];
    if (s & Stencil::exists) out.emplace_back(st.partner(i, k), st.weight[k], int(s & Stencil::intact));
  }
  std::sort(out.begin(), out.end());
  return out;
}

// s of bond (i, j) in double, as the list computes it.
double stretch(const Body& b, const VectorField& u, std::size_t i, std::size_t j) {
  double r2 = 0, l2 = 0;
  for (int k = 0; k < 3; ++k) {
    const double xi = b.points.x[k][j] - b.points.x[k][i];
    r2 += (xi + u[k][j] - u[k][i]) * (xi + u[k][j] - u[k][i]);
    l2 += xi * xi;
  }
  return (std::sqrt(r2) - std::sqrt(l2)) / std::sqrt(l2);
}

}  // namespace

TEST_CASE("a stencil holds the list's bonds, weights and pre-crack cuts") {
  for (int dim : {2, 3}) {
    const Pair p = bodies(dim);
    const Stencil& st = p.stencil.stencil;
    REQUIRE(p.stencil.on_stencil());
    REQUIRE(st.size() == p.list.bonds.size());
    REQUIRE(st.broken() == p.list.bonds.broken());
    REQUIRE(st.broken() > 0);  // the pre-crack cut some
    for (std::size_t i = 0; i < p.list.size(); ++i) {
      const Bonds a = list_bonds(p.list, i), b = stencil_bonds(p.stencil, i);
      REQUIRE(a.size() == b.size());
      for (std::size_t k = 0; k < a.size(); ++k) {
        REQUIRE(std::get<0>(a[k]) == std::get<0>(b[k]));
        REQUIRE(std::get<2>(a[k]) == std::get<2>(b[k]));
        REQUIRE(std::abs(std::get<1>(a[k]) - std::get<1>(b[k])) <= 1e-15 * std::get<1>(a[k]));
      }
    }
    CHECK(p.stencil.bond_bytes() < 2.5 * double(st.size()));  // against 45 bytes per bond for the full list
  }
}

TEST_CASE("stencil PMB forces match the list's within the float analysis, on a 3D plate thinner than the horizon too") {
  for (const auto& [dim, thickness] : {std::pair{2, 0.0}, std::pair{3, 0.004}, std::pair{3, 0.001}}) {
    INFO("dimension " << dim << ", thickness " << thickness);
    Pair p = bodies(dim, thickness);
    const auto pmb = Pmb::from_elastic(72e9, 3.8, delta, dim == 2 ? Kinematics::plane_stress : Kinematics::solid);
    const VectorField u = field(p.list, pmb.s0, false);
    VectorField f_list = zero_field(p.list.size()), f_st = zero_field(p.list.size());
    REQUIRE(pmb.forces(p.list, u, f_list).newly_broken_directed == 0);
    REQUIRE(pmb.forces(p.stencil, u, f_st).newly_broken_directed == 0);
    double umax = 0;
    for (int k = 0; k < 3; ++k)
      for (double v : u[std::size_t(k)]) umax = std::max(umax, std::abs(v));
    // Per bond, from pmb_stencil.cppm's analysis: eta = u_j - u_i from float u is off by at most
    // 2 |u|max 2^-24, so s by that over L; the float evaluation adds ~8 ulps of the pair force;
    // 16-term float sums add 16 ulps of the terms' magnitudes. With g_b = c w s, the bound is
    //   |f_st - f_list| <= 2^-24 sum_b (24 |g_b| + c w_b 2 |u|max / L_b).
    std::vector<double> g;
    pmb.pair_forces(p.list, u, g);
    double worst = 0;
    for (std::size_t i = 0; i < p.list.size(); ++i) {
      double bound = 0;
      for (auto b = p.list.bonds.begin(i); b < p.list.bonds.end(i); ++b)
        bound += 24 * std::abs(g[std::size_t(b)]) + pmb.c * p.list.bonds.weight[std::size_t(b)] * 2 * umax / p.list.bonds.length[std::size_t(b)];
      bound *= float_rounding;
      for (int k = 0; k < dim; ++k) {
        REQUIRE(std::abs(f_st[k][i] - f_list[k][i]) <= bound);
        worst = std::max(worst, std::abs(f_st[k][i] - f_list[k][i]) / bound);
      }
    }
    INFO("largest error / bound " << worst);
    CHECK(worst > 0);  // the paths do differ: this is not one code path compared with itself
    // Energy and stable step are evaluated in double on both paths. s = (|y| - L) / L cancels:
    // its absolute error is a few 1e-16 on strains of ~1e-5 here, so the energy (~s^2) may
    // differ by ~1e-10 relative between xi = x_j - x_i and xi = k h.
    const double e_st = pmb.strain_energy(p.stencil, u), e_list = pmb.strain_energy(p.list, u);
    INFO("energy " << e_st << " vs " << e_list << ", relative difference " << (e_st - e_list) / e_list);
    CHECK(std::abs(e_st - e_list) <= 1e-9 * e_list);
    CHECK(std::abs(pmb.stable_time_step(p.stencil) - pmb.stable_time_step(p.list)) <= 1e-14 * pmb.stable_time_step(p.list));
  }
}

TEST_CASE("stencil PMB breaks the list's bonds, spares no-fail points") {
  for (int dim : {2, 3}) {
    Pair p = bodies(dim);
    const auto pmb = Pmb::from_elastic(72e9, 3.8, delta, dim == 2 ? Kinematics::plane_stress : Kinematics::solid);
    const VectorField u = field(p.list, pmb.s0, true);
    VectorField f = zero_field(p.list.size());
    const auto broken_list = pmb.forces(p.list, u, f).newly_broken_directed;
    const auto broken_st = pmb.forces(p.stencil, u, f).newly_broken_directed;
    REQUIRE(broken_list > 100);
    // Decisions may differ only for bonds whose stretch lies within a few 1e-7 s0 of s0 (the
    // float analysis in pmb_stencil.cppm); 1e-5 s0 leaves a margin of 30.
    std::size_t differ = 0, spared = 0;
    std::vector<char> touched(p.list.size(), 0);  // points with a bond decided differently
    for (std::size_t i = 0; i < p.list.size(); ++i) {
      const Bonds a = list_bonds(p.list, i), b = stencil_bonds(p.stencil, i);
      REQUIRE(a.size() == b.size());
      for (std::size_t k = 0; k < a.size(); ++k) {
        const auto j = std::size_t(std::get<0>(a[k]));
        const double s = stretch(p.list, u, i, j);
        if (std::get<2>(a[k]) != std::get<2>(b[k])) {
          REQUIRE(std::abs(s - pmb.s0) <= 1e-5 * pmb.s0);
          ++differ;
          touched[i] = touched[j] = 1;
        }
        // The no-fail strip lies far from the pre-crack: its over-stretched bonds stay intact.
        if ((p.list.no_fail[i] || p.list.no_fail[j]) && s > pmb.s0) {
          REQUIRE(std::get<2>(b[k]) == 1);
          ++spared;
        }
      }
    }
    CHECK(spared > 10);
    CHECK(broken_st + differ / 2 >= broken_list);
    CHECK(broken_st <= broken_list + differ / 2);
    // Damage and fragments read the stencil's state like the list's mask.
    const auto phi_list = damage(p.list), phi_st = damage(p.stencil);
    for (std::size_t i = 0; i < p.list.size(); ++i)
      if (!touched[i]) REQUIRE(std::abs(phi_st[i] - phi_list[i]) <= 1e-14);
    const auto frag_list = count_fragments(p.list), frag_st = count_fragments(p.stencil);
    CHECK(frag_st.count == frag_list.count);
    CHECK(frag_st.debris == frag_list.debris);
    CHECK(same::difference(frag_st.label, frag_list.label, "frag_st.label") == "");
  }
}

// Each bond is evaluated once, from one end, and a thread's first rows receive terms from rows
// before them (pmb_stencil.cppm): 3 and 5 threads start their rows part-way through the 27 rows
// a bond can reach ahead here (5 threads: fewer rows each than that).
TEST_CASE("stencil PMB forces and broken bonds are bitwise the same on 1, 2, 3 and 5 threads") {
  Pair a = bodies(3);
  const auto pmb = Pmb::from_elastic(72e9, 3.8, delta, Kinematics::solid);
  const VectorField u = field(a.stencil, pmb.s0, true);
  VectorField fa = zero_field(a.stencil.size());
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  const auto na = pmb.forces(a.stencil, u, fa).newly_broken_directed;
  REQUIRE(na > 0);
  for (int t : {2, 3, 5}) {
    INFO(t << " threads");
    Pair b = bodies(3);
    VectorField fb = zero_field(b.stencil.size());
    omp_set_num_threads(t);
    const auto nb = pmb.forces(b.stencil, u, fb).newly_broken_directed;
    omp_set_num_threads(threads);
    REQUIRE(na == nb);
    for (int k = 0; k < 3; ++k) REQUIRE(same::difference(fa[std::size_t(k)], fb[std::size_t(k)], "fa[std::size_t(k)]") == "");
    REQUIRE(std::equal(a.stencil.stencil.state.begin(), a.stencil.stencil.state.end(), b.stencil.stencil.state.begin()));
  }
}

TEST_CASE("a perturbed cloud or mixed volumes get no stencil, with the reason") {
  std::string why;
  const auto jittered = lattice(box({0, 0, 0}, {0.004, 0.004, 0.004}), {.spacing = h, .perturbation = 0.1, .seed = 3});
  CHECK_FALSE(build_stencil(jittered, {.horizon = delta}, true, why).has_value());
  CHECK(why == "the points are not on one lattice");
  auto uneven = lattice(box({0, 0, 0}, {0.004, 0.004, 0.004}), {.spacing = h});
  uneven.volume[5] *= 0.5;
  CHECK_FALSE(build_stencil(uneven, {.horizon = delta}, true, why).has_value());
  CHECK(why == "the point volumes differ");
}
