// The 3D crack front against fronts drawn by hand on a lattice: a straight front slanted
// through the thickness, moved on by a known distance.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <cstddef>
#include <stdexcept>
#include <vector>
import peridot.analysis;

using namespace peridot;

namespace {

constexpr double h = 1e-3;  // [m]

// A 20 x 10 x 8 lattice with points at (i + 1/2) h: the crack plane is the layer j = 4, and in
// layer k of the thickness it has cracked every point with i <= first + k (a front slanted by
// one spacing per layer), damage 1 there and 0.2 (below the threshold) elsewhere.
PointCloud block() { return lattice(box({0, 0, 0}, {20 * h, 10 * h, 8 * h}), {.spacing = h}); }

std::vector<double> damage_of(const PointCloud& pc, int first) {
  std::vector<double> d(pc.size(), 0.2);
  for (std::size_t p = 0; p < pc.size(); ++p) {
    const int i = int(std::floor(pc.x[0][p] / h)), j = int(std::floor(pc.x[1][p] / h)), k = int(std::floor(pc.x[2][p] / h));
    if (j == 4 && i <= first + k) d[p] = 1.0;
  }
  return d;
}

}  // namespace

TEST_CASE("a front slanted through the thickness has one point per layer, the slant's length and its advance") {
  const auto pc = block();
  REQUIRE(pc.size() == 20 * 10 * 8);
  CrackFrontTracker t({.axis = 2, .direction = {1, 0, 0}, .origin = {0, 0, 0}});
  const auto& f = t.update(pc, damage_of(pc, 5), 1e-6);
  REQUIRE(f.slices == 8);
  REQUIRE(f.cracked_slices == 8);
  for (std::size_t k = 0; k < 8; ++k) {
    INFO("layer " << k);
    REQUIRE(f.front[k]);
    CHECK((*f.front[k])[0] == Approx((5 + double(k) + 0.5) * h));
    CHECK((*f.front[k])[1] == Approx(4.5 * h));
    CHECK((*f.front[k])[2] == Approx((double(k) + 0.5) * h));
  }
  // Seven steps of (h, 0, h) between the eight layers.
  CHECK(f.length == Approx(7 * std::sqrt(2.0) * h));
  CHECK(f.mean_advance == Approx((5 + 3.5 + 0.5) * h));
  CHECK(f.max_advance == Approx((5 + 7 + 0.5) * h));
  CHECK(f.mean_speed == 0);
  CHECK(f.max_speed == 0);
}

TEST_CASE("a front moved on by three spacings in 2 us advances at 1.5 km/s in every layer") {
  const auto pc = block();
  CrackFrontTracker t({.axis = 2, .direction = {2, 0, 0}, .origin = {0, 0, 0}});
  (void)t.update(pc, damage_of(pc, 2), 1e-6);
  const auto& f = t.update(pc, damage_of(pc, 5), 3e-6);
  CHECK(f.mean_speed == Approx(3 * h / 2e-6));
  CHECK(f.max_speed == Approx(3 * h / 2e-6));
  CHECK(t.max_speed() == Approx(1500.0));
}

TEST_CASE("a front cut short in the thickness counts only its cracked layers, and speeds only where both samples saw it") {
  const auto pc = block();
  CrackFrontTracker t({.axis = 2, .direction = {1, 0, 0}});
  auto first = damage_of(pc, 2);
  // Layers 4..7 uncracked at the first sample: a crack through half the thickness.
  for (std::size_t p = 0; p < pc.size(); ++p)
    if (pc.x[2][p] > 4 * h) first[p] = 0;
  const auto& a = t.update(pc, first, 0);
  CHECK(a.cracked_slices == 4);
  CHECK(a.length == Approx(3 * std::sqrt(2.0) * h));
  const auto& b = t.update(pc, damage_of(pc, 3), 1e-6);
  CHECK(b.cracked_slices == 8);
  // Layers 0..3 moved one spacing; layers 4..7 have no earlier front and no speed.
  CHECK(b.mean_speed == Approx(h / 1e-6));
  CHECK(b.max_speed == Approx(h / 1e-6));
}

TEST_CASE("a front direction along the slicing axis is refused") {
  CHECK_THROWS_AS(CrackFrontTracker({.axis = 2, .direction = {0, 0, 1}}), std::invalid_argument);
}

namespace {

// A Y-shaped crack in the layers z < z_cut of a 200 x 100 x 4 mm slab (h = 1 mm), the same in
// each: a stem from (20, 50) mm along +x, forking at x = 80 mm into arms at +-30 degrees; the
// path has grown to `length`. Damage 1 within h of the path, 0 elsewhere.
std::vector<double> y_crack(const PointCloud& pc, double length, double z_cut) {
  const double stem = 0.06, a = std::numbers::pi / 6;
  const Vec3 notch{0.02, 0.05, 0}, fork{0.08, 0.05, 0};
  std::vector<double> d(pc.size(), 0.0);
  for (std::size_t i = 0; i < pc.size(); ++i) {
    if (pc.x[2][i] > z_cut) continue;
    const Vec3 p{pc.x[0][i], pc.x[1][i], 0};
    // Distance to the stem, then to each arm grown to length - stem.
    const double along = std::clamp(p[0] - notch[0], 0.0, std::min(stem, length));
    double dist = std::hypot(p[0] - (notch[0] + along), p[1] - notch[1]);
    for (double side : {1.0, -1.0})
      if (length > stem) {
        const Vec3 e{std::cos(a), side * std::sin(a), 0};
        const double s = std::clamp((p[0] - fork[0]) * e[0] + (p[1] - fork[1]) * e[1], 0.0, length - stem);
        dist = std::min(dist, std::hypot(p[0] - (fork[0] + s * e[0]), p[1] - (fork[1] + s * e[1])));
      }
    if (dist < h) d[i] = 1.0;
  }
  return d;
}

}  // namespace

TEST_CASE("a front that forks in the lower half of the thickness branches in those layers only, at the fork, when the tip passed it", "[unit]") {
  const auto pc = lattice(box({0, 0, 0}, {0.2, 0.1, 0.004}), {.spacing = h});
  const double v = 1000, dt = 2 * h / v;
  CrackFrontTracker tracker({.axis = 2, .direction = {1, 0, 0}, .origin = {0.02, 0.05, 0}});
  FrontSample s;
  for (int k = 1; k <= 55; ++k) s = tracker.update(pc, y_crack(pc, v * k * dt, 0.002), k * dt);
  REQUIRE(s.slices == 4);
  CHECK(s.cracked_slices == 2);
  CHECK(s.branched_slices == 2);
  REQUIRE(s.first_branch);
  const auto& b = *s.first_branch;
  INFO("branch in slice " << b.slice << " at " << b.position[0] << ", " << b.position[1] << ", " << b.position[2] << " t = " << b.time);
  CHECK(b.slice < 2);
  // As for the 2D tracker: within 2 h of the fork, when the tip passed it.
  CHECK(std::hypot(b.position[0] - 0.08, b.position[1] - 0.05) < 2 * h);
  CHECK(b.position[2] == Approx((double(b.slice) + 0.5) * h));
  CHECK(b.time == Approx(0.06 / v).margin(dt));
}

TEST_CASE("a straight front never branches", "[unit]") {
  const auto pc = block();
  CrackFrontTracker tracker({.axis = 2, .direction = {1, 0, 0}, .origin = {0, 4.5 * h, 0}});
  FrontSample s;
  for (int k = 0; k < 10; ++k) s = tracker.update(pc, damage_of(pc, k), 1e-6 * (k + 1));
  CHECK(s.branched_slices == 0);
  CHECK_FALSE(s.first_branch);
}
