// The points a run on N ranks sends rank 0's crack trackers and DDS publisher (TrackedPoints),
// in-process on one rank: a part whose local points are a shuffle of the body's plus ghosts must
// give what the one-rank observers take from the whole body.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <random>
#include <vector>
import peridot.run;
import peridot.live;

using namespace peridot;

namespace {

// A 2D body of n points with damage and displacements, indexed by global id.
struct Whole {
  PointCloud points;
  VectorField u;
  std::vector<double> phi;
};

Whole whole_body(std::size_t n) {
  Whole w;
  w.points.dim = 2;
  w.points.spacing = 1e-3;
  for (std::size_t g = 0; g < n; ++g) {
    w.points.push_back({1e-3 * double(g % 37), 1e-3 * double(g / 37), 0}, 1e-6 * (1 + double(g % 5)));
    w.u[0].push_back(1e-5 * double(g % 7));
    w.u[1].push_back(-2e-5 * double(g % 3));
    w.u[2].push_back(0);
    w.phi.push_back(double((g * 7) % 11) / 10.0);
  }
  return w;
}

// The same body as one rank's part: every point in a shuffled local order, then `ghosts` copies
// of owned points that the part must not report twice.
struct Part {
  PointCloud points;
  VectorField u;
  std::vector<double> phi;
  std::vector<std::int64_t> ids, owned;
};

Part shuffled_part(const Whole& w, std::size_t ghosts) {
  const std::size_t n = w.points.size();
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::shuffle(order.begin(), order.end(), std::mt19937(7));
  for (std::size_t k = 0; k < ghosts; ++k) order.push_back(order[k * 3]);
  Part p;
  p.points.dim = 2;
  p.points.spacing = w.points.spacing;
  for (std::size_t l = 0; l < order.size(); ++l) {
    const auto g = order[l];
    p.points.push_back(w.points.position(g), w.points.volume[g]);
    for (std::size_t k = 0; k < 3; ++k) p.u[k].push_back(w.u[k][g]);
    p.phi.push_back(w.phi[g]);
    p.ids.push_back(std::int64_t(g));
    if (l < n) p.owned.push_back(std::int64_t(l));
  }
  return p;
}

}  // namespace

TEST_CASE("a part's DDS snapshot points are the whole body's every stride-th point in global order, deformed, with their damage") {
  const std::size_t n = 1001, max_points = 150;
  const auto w = whole_body(n);
  const auto p = shuffled_part(w, 40);
  OutputSpec o;
  o.dds_snapshot_every = 2;
  TrackedPoints tracked(o, p.points, p.owned, p.ids, n, max_points);
  const std::size_t stride = tracked.snapshot_stride();
  // The publisher's own decimation of the whole cloud (snapshot_stride) under the point limit.
  CHECK(stride == snapshot_stride(n, max_points));
  CHECK((n + stride - 1) / stride <= max_points);

  Observers::Totals off_step;
  tracked.gather(3, false, p.u, p.phi, off_step);
  CHECK(off_step.snapshot == nullptr);
  CHECK(off_step.cracked == nullptr);

  Observers::Totals totals;
  tracked.gather(4, false, p.u, p.phi, totals);
  REQUIRE(totals.snapshot != nullptr);
  CHECK(totals.points == n);
  const auto& s = *totals.snapshot;
  REQUIRE(s.points.size() == (n + stride - 1) / stride);
  std::size_t wrong = 0;
  for (std::size_t k = 0; k < s.points.size(); ++k) {
    const std::size_t g = k * stride;
    wrong += s.points.x[0][k] != w.points.x[0][g] + w.u[0][g] || s.points.x[1][k] != w.points.x[1][g] + w.u[1][g] ||
             s.points.volume[k] != w.points.volume[g] || s.damage[k] != w.phi[g];
  }
  CHECK(wrong == 0);
}

TEST_CASE("a part's cracked points are the whole body's at or above the lower tracker threshold, undeformed, with the body's extent") {
  const std::size_t n = 777;
  const auto w = whole_body(n);
  const auto p = shuffled_part(w, 25);
  OutputSpec o;
  o.crack_tip_every = 5;
  o.crack_tip_threshold = 0.6;
  o.crack_front_every = 10;
  o.crack_front_threshold = 0.45;
  o.crack_front_axis = 1;
  TrackedPoints tracked(o, p.points, p.owned, p.ids, n, 1000);
  Observers::Totals totals;
  tracked.gather(10, false, p.u, p.phi, totals);
  REQUIRE(totals.cracked != nullptr);
  CHECK(totals.snapshot == nullptr);
  const auto [lo, hi] = std::minmax_element(w.points.x[1].begin(), w.points.x[1].end());
  CHECK(totals.front_extent[0] == *lo);
  CHECK(totals.front_extent[1] == *hi);
  std::vector<std::size_t> expected;
  for (std::size_t g = 0; g < n; ++g)
    if (w.phi[g] >= 0.45) expected.push_back(g);
  const auto& c = *totals.cracked;
  REQUIRE(c.points.size() == expected.size());
  std::size_t wrong = 0;
  for (std::size_t k = 0; k < expected.size(); ++k) {
    const auto g = expected[k];
    wrong += c.points.x[0][k] != w.points.x[0][g] || c.points.x[1][k] != w.points.x[1][g] || c.damage[k] != w.phi[g];
  }
  CHECK(wrong == 0);
  // The last step observes whatever the cadence.
  Observers::Totals at_end;
  tracked.gather(13, true, p.u, p.phi, at_end);
  CHECK(at_end.cracked != nullptr);
}
