// Slabs of a lattice for N ranks (slab_of), checked against the lattice's own geometry: every
// point owned once, every bond partner of an owned point held, ghosts found on their owners.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <set>
#include <stdexcept>
#include <vector>
import peridot.discretization;

using namespace peridot;

namespace {

// Checks the slabs of `pc` on `ranks` ranks for a stencil reaching `reach` lattice steps.
void check_slabs(const PointCloud& pc, int ranks, int reach, int axis) {
  std::vector<Slab> slabs;
  for (int r = 0; r < ranks; ++r) slabs.push_back(slab_of(pc, r, ranks, reach));
  const double h = pc.spacing;
  std::vector<int> owners(pc.size(), 0);
  std::size_t least = pc.size(), most = 0;
  for (const auto& s : slabs) {
    REQUIRE(s.axis == axis);
    REQUIRE(std::is_sorted(s.local_ids.begin(), s.local_ids.end()));
    REQUIRE(s.owned.size() + s.ghost.size() == s.local_ids.size());
    std::set<std::int64_t> held(s.local_ids.begin(), s.local_ids.end());
    for (auto j : s.owned) ++owners[std::size_t(s.local_ids[std::size_t(j)])];
    least = std::min(least, s.owned.size());
    most = std::max(most, s.owned.size());
    // Every point within `reach` steps (along the cut axis) of an owned point is held.
    double lo = INFINITY, hi = -INFINITY;
    for (auto j : s.owned) {
      lo = std::min(lo, pc.x[axis][std::size_t(s.local_ids[std::size_t(j)])]);
      hi = std::max(hi, pc.x[axis][std::size_t(s.local_ids[std::size_t(j)])]);
    }
    for (std::size_t i = 0; i < pc.size(); ++i) {
      const bool near = pc.x[axis][i] > lo - (reach + 0.5) * h && pc.x[axis][i] < hi + (reach + 0.5) * h;
      CHECK(near == held.contains(std::int64_t(i)));
    }
    // A ghost is at its owner's index on the owner.
    for (std::size_t g = 0; g < s.ghost.size(); ++g) {
      const auto& o = slabs[std::size_t(s.ghost_owner[g])];
      REQUIRE(s.ghost_owner[g] != s.rank);
      const auto k = std::size_t(s.ghost_owner_index[g]);
      REQUIRE(k < o.local_ids.size());
      CHECK(o.local_ids[k] == s.local_ids[std::size_t(s.ghost[g])]);
      CHECK(o.is_owned[k]);
    }
  }
  CHECK(std::all_of(owners.begin(), owners.end(), [](int c) { return c == 1; }));
  // Balanced: each cut is a layer boundary within half a layer of the ideal one, so two slabs
  // differ by less than two of the largest layers.
  std::vector<std::size_t> layer(std::size_t(std::lround((pc.bounds().hi[axis] - pc.bounds().lo[axis]) / h)) + 1);
  for (std::size_t i = 0; i < pc.size(); ++i) ++layer[std::size_t(std::lround((pc.x[axis][i] - pc.bounds().lo[axis]) / h))];
  CHECK(most - least < 2 * *std::max_element(layer.begin(), layer.end()));
  // Rank 0's gather order lists every point once, rank by rank.
  auto ids = slabs[0].gather_ids;
  REQUIRE(ids.size() == pc.size());
  for (int r = 0; r < ranks; ++r)
    for (std::size_t j = slabs[0].owned_starts[std::size_t(r)]; j < slabs[0].owned_starts[std::size_t(r) + 1]; ++j) {
      const auto& s = slabs[std::size_t(r)];
      CHECK(ids[j] == s.local_ids[std::size_t(s.owned[j - slabs[0].owned_starts[std::size_t(r)]])]);
    }
  std::sort(ids.begin(), ids.end());
  std::vector<std::int64_t> all(pc.size());
  std::iota(all.begin(), all.end(), 0);
  CHECK(ids == all);
}

}  // namespace

TEST_CASE("slabs cut the longest lattice axis, own every point once and hold every partner within reach") {
  const double h = 0.01;
  SECTION("a 2D plate, cut across x") { check_slabs(lattice(rectangle({0, 0, 0}, {0.4, 0.12, 0}), {.spacing = h}), 3, 2, 0); }
  SECTION("a 2D strip standing up, cut across y, ghosts two ranks away") {
    check_slabs(lattice(rectangle({0, 0, 0}, {0.1, 0.3, 0}), {.spacing = h}), 4, 9, 1);
  }
  SECTION("a thin 3D plate, cut across x") { check_slabs(lattice(box({0, 0, 0}, {0.2, 0.08, 0.04}), {.spacing = h}), 2, 3, 0); }
  SECTION("a disc, whose layers hold different numbers of points") {
    check_slabs(lattice(disk({0, 0, 0}, 0.2), {.spacing = h}), 4, 3, 1);
  }
}

TEST_CASE("a body with fewer lattice layers than ranks, or off a lattice, cannot be cut into slabs") {
  const double h = 0.01;
  CHECK_THROWS_WITH(slab_of(lattice(rectangle({0, 0, 0}, {0.03, 0.03, 0}), {.spacing = h}), 0, 4, 2),
                    Catch::Contains("fewer than the 4 MPI ranks"));
  CHECK_THROWS_AS(slab_of(lattice(rectangle({0, 0, 0}, {0.2, 0.1, 0}), {.spacing = h, .perturbation = 0.2}), 0, 2, 2), std::invalid_argument);
  // One rank: the whole body, nothing listed.
  const auto one = slab_of(lattice(rectangle({0, 0, 0}, {0.2, 0.1, 0}), {.spacing = h}), 0, 1, 2);
  CHECK(one.local_size() == 200);
  CHECK(one.local_ids.empty());
}
