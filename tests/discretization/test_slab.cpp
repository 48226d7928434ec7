// Parts of a body for N ranks, checked against the body itself: slabs of a lattice (slab_of)
// against its layer geometry, coordinate bisection (rcb_of) against its bond list. Every point
// owned once, every partner an owned point needs held, ghosts found on their owners.
#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <set>
#include <stdexcept>
#include <vector>
#include "../support/same.hpp"
import peridot.discretization;

using namespace peridot;

namespace {

// What every layout must hold, however cut: each point owned once, each ghost found at its
// owner's index on its owner (where it is owned), and rank 0's gather order listing every point
// once, rank by rank.
void check_exchange_and_gather(const std::vector<Slab>& parts, std::size_t points) {
  std::vector<int> owners(points, 0);
  for (const auto& s : parts) {
    for (auto j : s.owned) ++owners[std::size_t(s.local_ids[std::size_t(j)])];
    for (std::size_t g = 0; g < s.ghost.size(); ++g) {
      const auto& o = parts[std::size_t(s.ghost_owner[g])];
      REQUIRE(s.ghost_owner[g] != s.rank);
      const auto k = std::size_t(s.ghost_owner_index[g]);
      REQUIRE(k < o.local_ids.size());
      CHECK(o.local_ids[k] == s.local_ids[std::size_t(s.ghost[g])]);
      CHECK(o.is_owned[k]);
    }
  }
  CHECK(std::all_of(owners.begin(), owners.end(), [](int c) { return c == 1; }));
  auto ids = parts[0].gather_ids;
  REQUIRE(ids.size() == points);
  for (std::size_t r = 0; r < parts.size(); ++r)
    for (std::size_t j = parts[0].owned_starts[r]; j < parts[0].owned_starts[r + 1]; ++j)
      CHECK(ids[j] == parts[r].local_ids[std::size_t(parts[r].owned[j - parts[0].owned_starts[r]])]);
  std::sort(ids.begin(), ids.end());
  std::vector<std::int64_t> all(points);
  std::iota(all.begin(), all.end(), 0);
  CHECK(same::difference(ids, all, "ids") == "");
}

// Checks the slabs or bricks of `pc` on `ranks` ranks for a stencil reaching `reach` lattice
// steps: the process grid, and every point within `reach` layers of a rank's brick (on every
// axis) held by it.
void check_bricks(const PointCloud& pc, int ranks, int reach, std::array<int, 3> grid) {
  std::vector<Slab> slabs;
  for (int r = 0; r < ranks; ++r) slabs.push_back(slab_of(pc, r, ranks, reach));
  const double h = pc.spacing;
  const auto b = pc.bounds();
  std::size_t least = pc.size(), most = 0;
  for (const auto& s : slabs) {
    REQUIRE((s.grid == grid));
    REQUIRE(std::is_sorted(s.local_ids.begin(), s.local_ids.end()));
    REQUIRE(s.owned.size() + s.ghost.size() == s.local_ids.size());
    std::set<std::int64_t> held(s.local_ids.begin(), s.local_ids.end());
    least = std::min(least, s.owned.size());
    most = std::max(most, s.owned.size());
    std::array<double, 3> lo{INFINITY, INFINITY, INFINITY}, hi{-INFINITY, -INFINITY, -INFINITY};
    for (auto j : s.owned)
      for (int a = 0; a < pc.dim; ++a) {
        lo[std::size_t(a)] = std::min(lo[std::size_t(a)], pc.x[a][std::size_t(s.local_ids[std::size_t(j)])]);
        hi[std::size_t(a)] = std::max(hi[std::size_t(a)], pc.x[a][std::size_t(s.local_ids[std::size_t(j)])]);
      }
    std::size_t wrong = 0;
    for (std::size_t i = 0; i < pc.size(); ++i) {
      bool near = true;
      for (int a = 0; a < pc.dim; ++a)
        near = near && pc.x[a][i] > lo[std::size_t(a)] - (reach + 0.5) * h && pc.x[a][i] < hi[std::size_t(a)] + (reach + 0.5) * h;
      wrong += near != held.contains(std::int64_t(i));
    }
    CHECK(wrong == 0);
  }
  check_exchange_and_gather(slabs, pc.size());
  // Balanced: each cut is a layer boundary within half a layer of the ideal one, so two parts
  // differ by less than two of the largest layers of each axis cut.
  std::size_t allowed = 0;
  for (int a = 0; a < pc.dim; ++a) {
    if (grid[std::size_t(a)] == 1) continue;
    std::vector<std::size_t> layer(std::size_t(std::lround((b.hi[a] - b.lo[a]) / h)) + 1);
    for (std::size_t i = 0; i < pc.size(); ++i) ++layer[std::size_t(std::lround((pc.x[a][i] - b.lo[a]) / h))];
    allowed += 2 * *std::max_element(layer.begin(), layer.end());
  }
  CHECK(most - least < allowed);
}

void check_slabs(const PointCloud& pc, int ranks, int reach, int axis) {
  std::array<int, 3> grid{1, 1, 1};
  grid[std::size_t(axis)] = ranks;
  check_bricks(pc, ranks, reach, grid);
  CHECK(slab_of(pc, 0, ranks, reach).axis == axis);
}

}  // namespace

TEST_CASE("slabs cut the longest lattice axis, own every point once and hold every partner within reach") {
  const double h = 0.01;
  SECTION("a 2D plate, cut across x") { check_slabs(lattice(rectangle({0, 0, 0}, {0.4, 0.12, 0}), {.spacing = h}), 3, 2, 0); }
  SECTION("a 2D strip standing up, cut across y, ghosts two ranks away") {
    check_slabs(lattice(rectangle({0, 0, 0}, {0.1, 0.3, 0}), {.spacing = h}), 4, 9, 1);
  }
  SECTION("a thin 3D plate, cut across x") { check_slabs(lattice(box({0, 0, 0}, {0.2, 0.08, 0.04}), {.spacing = h}), 2, 3, 0); }
  SECTION("a disc, whose layers hold different numbers of points, on 3 ranks") {
    check_slabs(lattice(disk({0, 0, 0}, 0.2), {.spacing = h}), 3, 3, 1);
  }
}

TEST_CASE("bricks cut a square or a cube across two or three axes once slabs would cost more halo") {
  const double h = 0.01;
  // 4 slabs of a square cost 3 cross-sections, 2 x 2 bricks 2; 8 ranks on a cube: 2 x 2 x 2
  // bricks cost 3 cross-sections, against 7 for slabs.
  SECTION("a disc on 4 ranks: 2 x 2, nested cuts balancing its uneven layers") {
    check_bricks(lattice(disk({0, 0, 0}, 0.2), {.spacing = h}), 4, 3, {2, 2, 1});
  }
  SECTION("a 3:2 rectangle on 6 ranks: 3 x 2") { check_bricks(lattice(rectangle({0, 0, 0}, {0.3, 0.2, 0}), {.spacing = h}), 6, 2, {3, 2, 1}); }
  SECTION("a cube on 8 ranks: 2 x 2 x 2") { check_bricks(lattice(box({0, 0, 0}, {0.1, 0.1, 0.1}), {.spacing = h}), 8, 2, {2, 2, 2}); }
  SECTION("a long bar on 4 ranks stays in slabs") {
    check_slabs(lattice(box({0, 0, 0}, {0.4, 0.1, 0.1}), {.spacing = h}), 4, 2, 0);
  }
  CHECK(slab_of(lattice(box({0, 0, 0}, {0.1, 0.1, 0.1}), {.spacing = h}), 0, 8, 2).axis == -2);
}

TEST_CASE("a body whose lattice layers fit no grid of the ranks, or off a lattice, cannot be cut into slabs") {
  const double h = 0.01;
  // 3 x 3 layers: 4 ranks fit as 2 x 2 bricks, 5 do not fit at all.
  CHECK_THROWS_WITH(slab_of(lattice(rectangle({0, 0, 0}, {0.03, 0.03, 0}), {.spacing = h}), 0, 5, 2),
                    Catch::Contains("no grid of 5 MPI ranks fits the body's 3 x 3 lattice layers"));
  CHECK_NOTHROW(slab_of(lattice(rectangle({0, 0, 0}, {0.03, 0.03, 0}), {.spacing = h}), 0, 4, 2));
  CHECK_THROWS_AS(slab_of(lattice(rectangle({0, 0, 0}, {0.2, 0.1, 0}), {.spacing = h, .perturbation = 0.2}), 0, 2, 2), std::invalid_argument);
  // One rank: the whole body, nothing listed.
  const auto one = slab_of(lattice(rectangle({0, 0, 0}, {0.2, 0.1, 0}), {.spacing = h}), 0, 1, 2);
  CHECK(one.local_size() == 200);
  CHECK(one.local_ids.empty());
}

namespace {

// Checks the bisection of `pc` with bonds `bl` on `ranks` ranks, ghosts `depth` bonds deep,
// against the bond list itself.
void check_bisection(const PointCloud& pc, const BondList& bl, int ranks, int depth = 1) {
  std::vector<Slab> parts;
  for (int r = 0; r < ranks; ++r) parts.push_back(rcb_of(pc, bl, r, ranks, depth));
  std::size_t least = pc.size(), most = 0;
  for (const auto& s : parts) {
    REQUIRE(s.axis == -1);
    REQUIRE(std::is_sorted(s.local_ids.begin(), s.local_ids.end()));
    REQUIRE(s.owned.size() + s.ghost.size() == s.local_ids.size());
    least = std::min(least, s.owned.size());
    most = std::max(most, s.owned.size());
    // The ghosts are exactly the points within `depth` bonds of an owned point that another
    // rank owns; the rows held are those of points less than `depth` bonds away.
    std::set<std::int64_t> owned, partners, ghosts, rows;
    for (auto j : s.owned) owned.insert(s.local_ids[std::size_t(j)]);
    std::set<std::int64_t> frontier = owned, reached = owned, full = owned;
    for (int level = 1; level <= depth; ++level) {
      std::set<std::int64_t> next;
      for (auto g : frontier)
        for (auto q : bl.neighbors(std::size_t(g)))
          if (!reached.contains(q)) next.insert(q);
      reached.insert(next.begin(), next.end());
      if (level < depth) full.insert(next.begin(), next.end());
      frontier = next;
    }
    for (auto g : reached)
      if (!owned.contains(g)) partners.insert(g);
    for (auto g : s.ghost) ghosts.insert(s.local_ids[std::size_t(g)]);
    CHECK(same::difference(ghosts, partners, "ghosts") == "");
    for (std::size_t j = 0; j < s.local_ids.size(); ++j)
      if (s.full_row[j]) rows.insert(s.local_ids[j]);
    CHECK(same::difference(rows, full, "rows") == "");
    // The rank's list: each owned row is the whole row, partner by partner in the same order,
    // with the same weight; ghost rows are empty.
    const BondList mine = local_bonds(bl, s);
    REQUIRE(mine.points() == s.local_ids.size());
    std::size_t wrong = 0;
    for (std::size_t j = 0; j < s.local_ids.size(); ++j) {
      const auto g = std::size_t(s.local_ids[j]);
      if (!s.full_row[j]) {
        wrong += mine.count(j) != 0;
        continue;
      }
      REQUIRE(mine.count(j) == bl.count(g));
      for (std::size_t c = 0; c < bl.count(g); ++c) {
        wrong += s.local_ids[std::size_t(mine.neighbor[std::size_t(mine.begin(j)) + c])] != bl.neighbor[std::size_t(bl.begin(g)) + c];
        wrong += mine.weight_of(mine.begin(j) + std::int64_t(c)) != bl.weight_of(bl.begin(g) + std::int64_t(c));
      }
    }
    CHECK(wrong == 0);
  }
  check_exchange_and_gather(parts, pc.size());
  // Each cut splits its part at the count its ranks' share asks for: parts differ by at most one
  // point per level of the bisection.
  CHECK(most - least <= std::size_t(std::ceil(std::log2(ranks))));
  // The bond starts count the owned rows' bonds.
  for (int r = 0; r < ranks; ++r) {
    std::size_t bonds = 0;
    for (auto j : parts[std::size_t(r)].owned) bonds += bl.count(std::size_t(parts[std::size_t(r)].local_ids[std::size_t(j)]));
    CHECK(parts[0].bond_starts[std::size_t(r) + 1] - parts[0].bond_starts[std::size_t(r)] == bonds);
  }
}

}  // namespace

TEST_CASE("coordinate bisection owns every point once, balances the parts and holds exactly the partners of owned points") {
  const double h = 0.01;
  SECTION("a perturbed 2D plate on 3 ranks") {
    const auto pc = lattice(rectangle({0, 0, 0}, {0.3, 0.12, 0}), {.spacing = h, .perturbation = 0.3});
    check_bisection(pc, build_bonds(pc, {.horizon = 3.015 * h}), 3);
  }
  SECTION("a disc on 4 ranks, lean list") {
    const auto pc = lattice(disk({0, 0, 0}, 0.1), {.spacing = h});
    check_bisection(pc, build_bonds(pc, {.horizon = 3.015 * h, .lean = true}), 4);
  }
  SECTION("a 3D box on 5 ranks") {
    const auto pc = lattice(box({0, 0, 0}, {0.1, 0.06, 0.04}), {.spacing = h});
    check_bisection(pc, build_bonds(pc, {.horizon = 2.015 * h}), 5);
  }
  SECTION("a 2D plate on 4 ranks, ghosts two bonds deep (state-based models)") {
    const auto pc = lattice(rectangle({0, 0, 0}, {0.3, 0.12, 0}), {.spacing = h});
    check_bisection(pc, build_bonds(pc, {.horizon = 3.015 * h}), 4, 2);
  }
}

TEST_CASE("a body with fewer points than ranks cannot be bisected") {
  const auto pc = lattice(rectangle({0, 0, 0}, {0.02, 0.01, 0}), {.spacing = 0.01});
  CHECK_THROWS_WITH(rcb_of(pc, build_bonds(pc, {.horizon = 0.0301}), 0, 3), Catch::Contains("fewer than the 3 MPI ranks"));
}

namespace {

// A part's layout against the expected one, field for field.
void check_layout(const Slab& part, const Slab& expected) {
  CHECK(same::difference(part.local_ids, expected.local_ids, "local ids") == "");
  CHECK(same::difference(part.owned, expected.owned, "owned") == "");
  CHECK(same::difference(part.ghost, expected.ghost, "ghosts") == "");
  CHECK(same::difference(part.ghost_owner, expected.ghost_owner, "ghost owners") == "");
  CHECK(same::difference(part.full_row, expected.full_row, "held rows") == "");
}

// The rows a part keeps of the bonds built on its near points (held: each local point's index
// into them) against the whole body's rows of the expected layout, bit for bit.
void check_held_rows(const BondList& near_bonds, const Slab& part, const std::vector<std::int64_t>& held, const BondList& whole,
                     const Slab& expected) {
  Slab by_near = part;
  by_near.local_ids = held;
  BondList mine = near_bonds;
  keep_held_rows(mine, by_near);
  const BondList theirs = local_bonds(whole, expected);
  CHECK(same::difference(local_bonds(near_bonds, by_near).neighbor, theirs.neighbor, "partners (copied)") == "");
  CHECK(same::difference(mine.offset, theirs.offset, "offsets") == "");
  CHECK(same::difference(mine.neighbor, theirs.neighbor, "partners") == "");
  CHECK(same::difference(mine.intact, theirs.intact, "bond states") == "");
  CHECK(same::difference(mine.weight, theirs.weight, "weights") == "");
  CHECK(same::difference(mine.weight_f, theirs.weight_f, "float weights") == "");
  CHECK(same::difference(mine.length, theirs.length, "lengths") == "");
}

// Builds every rank's part from its neighbourhood alone (rcb_owners, points_near_part, bonds on
// the near points, rcb_part) and compares it with the cut of the whole body (rcb_of,
// local_bonds): the same points, ghosts, held rows and bonds, bit for bit. The ghosts' indices
// on their owners are looked up in the owners' own local parts, as index_on_owners does.
void check_local_cut(const PointCloud& pc, const BondOptions& options, int ranks, int depth) {
  const BondList whole = build_bonds(pc, options);
  const auto owner = rcb_owners(pc, ranks);
  const double reach = bond_cutoff(options, pc.dim, pc.spacing) + pc.spacing;
  std::vector<Slab> local;
  // Every rank's neighbourhood at once, as rank 0 finds them to send a mesh's shares.
  const auto near_of = points_near_parts(pc, owner, ranks, depth * reach);
  REQUIRE(near_of.size() == std::size_t(ranks));
  std::vector<std::uint64_t> counts(std::size_t(ranks), 0);
  for (int o : owner) ++counts[std::size_t(o)];
  for (int r = 0; r < ranks; ++r) {
    const Slab cut = rcb_of(pc, whole, r, ranks, depth);
    const auto near = points_near_part(pc, owner, r, depth * reach);
    CHECK(same::difference(near_of[std::size_t(r)], near, "near points of all parts") == "");
    // On a body much wider than the horizon a rank's neighbourhood is a fraction of it.
    if (ranks == 4 && pc.size() >= 5000) CHECK(near.size() < pc.size() / 2);
    const BondList near_bonds = build_bonds(subset(pc, near), options);
    std::vector<std::int64_t> held;
    Slab part = rcb_part(owner, near, near_bonds, r, ranks, depth, held);
    check_layout(part, cut);
    CHECK(same::difference(part.owned_starts, cut.owned_starts, "owned starts") == "");
    CHECK(same::difference(part.gather_ids, cut.gather_ids, "gather order") == "");
    {
      // The same part from the near points' owners and the ranks' counts only (a mesh's share).
      std::vector<int> near_owner;
      for (auto id : near) near_owner.push_back(owner[std::size_t(id)]);
      std::vector<std::int64_t> held_too;
      const Slab sent = rcb_part(near_owner, counts, r == 0 ? &owner : nullptr, near, near_bonds, r, depth, held_too);
      check_layout(sent, cut);
      CHECK(same::difference(sent.owned_starts, cut.owned_starts, "owned starts (sent)") == "");
      CHECK(same::difference(sent.gather_ids, cut.gather_ids, "gather order (sent)") == "");
      CHECK(same::difference(held_too, held, "held (sent)") == "");
    }
    check_held_rows(near_bonds, part, held, whole, cut);
    local.push_back(std::move(part));
    local.back().ghost_owner_index = cut.ghost_owner_index;  // checked below from the owners' parts
  }
  for (auto& s : local)
    for (std::size_t g = 0; g < s.ghost.size(); ++g) {
      const auto& o = local[std::size_t(s.ghost_owner[g])];
      const auto id = s.local_ids[std::size_t(s.ghost[g])];
      const auto at = std::lower_bound(o.local_ids.begin(), o.local_ids.end(), id);
      REQUIRE(at != o.local_ids.end());
      CHECK(at - o.local_ids.begin() == s.ghost_owner_index[g]);
    }
}

}  // namespace

TEST_CASE("a part built from its neighbourhood alone equals the part cut from the whole body") {
  const double h = 0.01;
  const Crack notch = CrackSegment{{0.1, 0.06, 0}, {0.2, 0.06, 0}};
  SECTION("a perturbed 2D plate with a pre-crack, partial volumes, on 2, 3 and 4 ranks") {
    const auto pc = lattice(rectangle({0, 0, 0}, {0.3, 0.12, 0}), {.spacing = h, .perturbation = 0.3});
    for (int ranks : {2, 3, 4}) check_local_cut(pc, {.horizon = 3.015 * h, .partial_volume = true, .cracks = {notch}}, ranks, 1);
  }
  SECTION("a 2D plate, ghosts two bonds deep (state-based models), on 4 ranks") {
    const auto pc = lattice(rectangle({0, 0, 0}, {0.3, 0.12, 0}), {.spacing = h});
    check_local_cut(pc, {.horizon = 3.015 * h, .cracks = {notch}}, 4, 2);
  }
  SECTION("a 1 m x 0.5 m plate on 4 ranks: each rank's neighbourhood is under half the body") {
    const auto pc = lattice(rectangle({0, 0, 0}, {1.0, 0.5, 0}), {.spacing = h});
    check_local_cut(pc, {.horizon = 3.015 * h, .lean = true}, 4, 1);
  }
  SECTION("a 3D box, lean list, on 4 ranks") {
    const auto pc = lattice(box({0, 0, 0}, {0.1, 0.06, 0.04}), {.spacing = h, .perturbation = 0.2});
    check_local_cut(pc, {.horizon = 2.015 * h, .lean = true}, 4, 1);
  }
}

TEST_CASE("a lattice's slab or brick from its grid alone equals the one cut from the whole cloud, points included, for boxes and other shapes") {
  // Extents that are no multiple of h drop the last site along an axis (the ceiling of the
  // extent over h sites, the last outside): uneven layer counts, unbalanced cuts. Then bodies
  // that are no box: a plate with a hole, a dog-bone, a ring, a hollow cylinder.
  const std::vector<peridot::Shape> shapes{
      peridot::rectangle({0, 0, 0}, {0.037, 0.023, 0}), peridot::rectangle({-1, 2, 0}, {-0.9549, 2.0321, 0}),
      peridot::box({0, 0, 0}, {0.013, 0.0091, 0.0072}), peridot::box({0, 0, 0}, {0.02, 0.02, 0.02}),
      peridot::subtract(peridot::rectangle({0, 0, 0}, {0.037, 0.023, 0}), peridot::disk({0.02, 0.011, 0}, 0.006)),
      peridot::unite(peridot::unite(peridot::rectangle({0, 0, 0}, {0.012, 0.01, 0}), peridot::rectangle({0.003, 0.01, 0}, {0.009, 0.03, 0})),
                     peridot::rectangle({0, 0.03, 0}, {0.012, 0.04, 0})),
      peridot::annulus({0, 0, 0}, 0.006, 0.015), peridot::cylinder_shell({0, 0, 0}, 0.004, 0.01, 0, 0.006)};
  const std::vector<double> spacings{1e-3, 1e-3, 1e-3, 2.5e-3, 1e-3, 1e-3, 1e-3, 1e-3};
  int compared = 0;
  for (std::size_t k = 0; k < shapes.size(); ++k) {
    const peridot::LatticeOptions o{.spacing = spacings[k]};
    const auto whole = peridot::lattice(shapes[k], o);
    const auto grid = peridot::shape_lattice(shapes[k], o);
    REQUIRE(grid);
    REQUIRE(grid->size() == whole.size());
    for (int ranks : {2, 3, 4, 6, 8})
      for (int reach : {1, 3}) {
        peridot::Slab expected;
        try {
          expected = peridot::slab_of(whole, 0, ranks, reach);
        } catch (const std::invalid_argument&) {
          CHECK_THROWS_AS(peridot::slab_of(*grid, 0, ranks, reach), std::invalid_argument);
          continue;
        }
        for (int rank = 0; rank < ranks; ++rank) {
          CAPTURE(k, ranks, reach, rank);
          const auto a = peridot::slab_of(whole, rank, ranks, reach), b = peridot::slab_of(*grid, rank, ranks, reach);
          CHECK(a.grid == b.grid);
          CHECK(a.axis == b.axis);
          CHECK(a.global_size == b.global_size);
          CHECK(same::difference(a.local_ids, b.local_ids) == "");
          CHECK(same::difference(a.owned, b.owned) == "");
          CHECK(same::difference(a.is_owned, b.is_owned) == "");
          CHECK(same::difference(a.ghost, b.ghost) == "");
          CHECK(same::difference(a.ghost_owner, b.ghost_owner) == "");
          CHECK(same::difference(a.ghost_owner_index, b.ghost_owner_index) == "");
          CHECK(same::difference(a.owned_starts, b.owned_starts) == "");
          CHECK(same::difference(a.gather_ids, b.gather_ids) == "");
          const auto part = peridot::lattice_points(*grid, b.local_ids), cut = peridot::subset(whole, a.local_ids);
          for (int c = 0; c < 3; ++c) CHECK(same::difference(part.x[c], cut.x[c]) == "");
          CHECK(same::difference(part.volume, cut.volume) == "");
          ++compared;
        }
      }
  }
  CHECK(compared > 120);
  // Not a full grid: no box lattice (shape_lattice keeps its rows' runs instead).
  CHECK_FALSE(peridot::box_lattice(peridot::disk({0, 0, 0}, 0.01), {.spacing = 1e-3}));
  CHECK_FALSE(peridot::box_lattice(peridot::subtract(peridot::rectangle({0, 0, 0}, {0.01, 0.01, 0}), peridot::disk({0.005, 0.005, 0}, 0.002)),
                                   {.spacing = 1e-3}));
}

namespace {

// Builds every rank's part of a lattice from its brick alone (brick_cut, brick_sites,
// lattice_points, bonds on those points, brick_part) and compares it with the same owners
// applied to the whole body: the whole cloud's points, and the owned points' partners (and
// their partners, at depth 2) found on the whole bond list, with its rows bit for bit.
void check_brick_parts(const Shape& shape, const LatticeOptions& lo, const BondOptions& options, int ranks, int depth) {
  const PointCloud pc = lattice(shape, lo);
  const BondList whole = build_bonds(pc, options);
  const auto grid = shape_lattice(shape, lo);
  REQUIRE(grid);
  REQUIRE(grid->full() == shape.is_box());
  REQUIRE(grid->size() == pc.size());
  const BrickCut cut = brick_cut(*grid, ranks);
  // Balanced by points, also where the body is no box: no brick owns more than its share of
  // the body plus two mean layers across its longest axis (a cut by sites, not points, gives
  // the dog-bone's ends 120 of its 360 points on 4 ranks, over 108).
  for (int r = 0; r < ranks; ++r) {
    CAPTURE(r, ranks);
    const double layer = double(pc.size()) / double(*std::max_element(grid->m.begin(), grid->m.begin() + pc.dim));
    CHECK(double(cut.count(r, 0)) <= double(pc.size()) / ranks + 2 * layer);
    CHECK(cut.count(r, 0) > 0);
  }
  const double reach = bond_cutoff(options, pc.dim, pc.spacing) + pc.spacing;
  const auto grow = std::int64_t(std::ceil(depth * reach / lo.spacing)) + 1;
  std::vector<Slab> parts;
  for (int r = 0; r < ranks; ++r) {
    CAPTURE(r, ranks, depth);
    const auto near = brick_sites(cut, r, grow);
    if (ranks == 4 && pc.size() >= 5000) CHECK(near.size() < pc.size() / 2);
    const PointCloud near_points = lattice_points(*grid, near);
    const PointCloud expected_points = subset(pc, near);
    for (int c = 0; c < 3; ++c) CHECK(same::difference(near_points.x[c], expected_points.x[c], "positions") == "");
    const BondList near_bonds = build_bonds(near_points, options);
    std::vector<std::int64_t> held;
    Slab part = brick_part(cut, near, near_bonds, r, depth, held);
    // The reference: levels over the whole list from the owners alone.
    std::vector<int> level(pc.size(), 0);
    for (std::size_t i = 0; i < pc.size(); ++i) level[i] = cut.owner_of(std::int64_t(i)) == r;
    for (int d = 1; d <= depth; ++d)
      for (std::size_t i = 0; i < pc.size(); ++i)
        if (level[i] == d)
          for (auto j : whole.neighbors(i))
            if (!level[std::size_t(j)]) level[std::size_t(j)] = d + 1;
    Slab expected;
    expected.rank = r;
    expected.ranks = ranks;
    expected.global_size = pc.size();
    for (std::size_t i = 0; i < pc.size(); ++i) {
      if (!level[i]) continue;
      const int o = cut.owner_of(std::int64_t(i));
      (o == r ? expected.owned : expected.ghost).push_back(std::int64_t(expected.local_ids.size()));
      if (o != r) expected.ghost_owner.push_back(o);
      expected.full_row.push_back(level[i] <= depth);
      expected.local_ids.push_back(std::int64_t(i));
    }
    CHECK(part.global_size == pc.size());
    check_layout(part, expected);
    check_held_rows(near_bonds, part, held, whole, expected);
    parts.push_back(std::move(part));
  }
  // Ghosts' indices on their owners, as index_on_owners finds them, and rank 0's gather order.
  for (auto& s : parts)
    for (std::size_t g = 0; g < s.ghost.size(); ++g) {
      const auto& o = parts[std::size_t(s.ghost_owner[g])];
      const auto at = std::lower_bound(o.local_ids.begin(), o.local_ids.end(), s.local_ids[std::size_t(s.ghost[g])]);
      REQUIRE(at != o.local_ids.end());
      s.ghost_owner_index[g] = at - o.local_ids.begin();
    }
  check_exchange_and_gather(parts, pc.size());
}

}  // namespace

TEST_CASE("a box lattice's part built from its brick alone holds the points and bond rows the whole body gives its owners") {
  const double h = 0.01;
  const Crack notch = CrackSegment{{0.1, 0.06, 0}, {0.2, 0.06, 0}};
  SECTION("a perturbed 2D plate with a pre-crack, partial volumes, on 2, 3 and 4 ranks") {
    for (int ranks : {2, 3, 4})
      check_brick_parts(rectangle({0, 0, 0}, {0.3, 0.12, 0}), {.spacing = h, .perturbation = 0.3, .seed = 7},
                        {.horizon = 3.015 * h, .partial_volume = true, .cracks = {notch}}, ranks, 1);
  }
  SECTION("a perturbed 2D plate, ghosts two bonds deep (state-based models), on 4 ranks") {
    check_brick_parts(rectangle({0, 0, 0}, {0.3, 0.12, 0}), {.spacing = h, .perturbation = 0.2}, {.horizon = 3.015 * h, .cracks = {notch}}, 4, 2);
  }
  SECTION("a 1 m x 0.5 m plate on 4 ranks: each rank's neighbourhood is under half the body") {
    check_brick_parts(rectangle({0, 0, 0}, {1.0, 0.5, 0}), {.spacing = h, .perturbation = 0.1}, {.horizon = 3.015 * h, .lean = true}, 4, 1);
  }
  SECTION("a perturbed 3D box, lean list, on 4 and 8 ranks") {
    for (int ranks : {4, 8})
      check_brick_parts(box({0, 0, 0}, {0.1, 0.06, 0.04}), {.spacing = h, .perturbation = 0.2}, {.horizon = 2.015 * h, .lean = true}, ranks, 1);
  }
}

TEST_CASE("a lattice body that is no box is cut into bricks from its rows of sites, each part holding the rows the whole body gives it") {
  const double h = 0.01;
  const Crack notch = CrackSegment{{0.0, 0.1, 0}, {0.06, 0.1, 0}};
  SECTION("a perturbed plate with a hole and a pre-crack, partial volumes, on 2, 3 and 4 ranks") {
    const Shape plate = subtract(rectangle({0, 0, 0}, {0.3, 0.2, 0}), disk({0.15, 0.1, 0}, 0.05));
    for (int ranks : {2, 3, 4})
      check_brick_parts(plate, {.spacing = h, .perturbation = 0.3, .seed = 11}, {.horizon = 3.015 * h, .partial_volume = true, .cracks = {notch}}, ranks, 1);
  }
  SECTION("a dog-bone specimen (a union of rectangles), ghosts two bonds deep, on 4 ranks") {
    const Shape bone = unite(unite(rectangle({0, 0, 0}, {0.12, 0.1, 0}), rectangle({0.03, 0.1, 0}, {0.09, 0.3, 0})), rectangle({0, 0.3, 0}, {0.12, 0.4, 0}));
    check_brick_parts(bone, {.spacing = h, .perturbation = 0.2}, {.horizon = 3.015 * h}, 4, 2);
  }
  SECTION("a disk, unperturbed, lean list, on 3 ranks") {
    check_brick_parts(disk({0, 0, 0}, 0.2), {.spacing = h}, {.horizon = 3.015 * h, .lean = true}, 3, 1);
  }
  SECTION("a perturbed 3D cylinder shell, lean list, on 4 ranks") {
    check_brick_parts(cylinder_shell({0, 0, 0}, 0.05, 0.1, 0, 0.04), {.spacing = h, .perturbation = 0.2}, {.horizon = 2.015 * h, .lean = true}, 4, 1);
  }
}

TEST_CASE("a shape's grid finds each point's site and each site's point, and numbers a box's points in site order, as the whole lattice does") {
  const peridot::LatticeOptions o{.spacing = 1e-3};
  for (const auto& shape : {subtract(rectangle({0, 0, 0}, {0.037, 0.023, 0}), disk({0.02, 0.01, 0}, 0.006)), annulus({0, 0, 0}, 0.004, 0.011),
                            cylinder_shell({0, 0, 0}, 0.003, 0.007, 0, 0.004)}) {
    const auto whole = lattice(shape, o);
    const auto grid = shape_lattice(shape, o);
    REQUIRE(grid);
    REQUIRE_FALSE(grid->full());
    REQUIRE(grid->size() == whole.size());
    // Every site of the bounding grid: a point there exactly where the whole lattice has one.
    std::size_t found = 0, mismatched = 0;
    for (std::int64_t site = 0; site < std::int64_t(grid->sites()); ++site) {
      const auto id = grid->id_of_site(site);
      if (id < 0) continue;
      ++found;
      const Vec3 at = grid->site(site);
      mismatched += grid->site_of(id) != site || at[0] != whole.x[0][std::size_t(id)] || at[1] != whole.x[1][std::size_t(id)] ||
                    at[2] != whole.x[2][std::size_t(id)];
    }
    CHECK(found == whole.size());
    CHECK(mismatched == 0);
    // A box's points numbered in site order: the same as counting the whole lattice's points in
    // the box, one by one.
    const std::array<std::int64_t, 6> box{3, std::min<std::int64_t>(17, grid->m[0]), 2, 11, 0, grid->m[2] > 1 ? 3 : 1};
    const BoxNumbering numbering(*grid, box);
    std::int64_t next = 0;
    std::size_t misnumbered = 0;
    for (auto z = box[4]; z < box[5]; ++z)
      for (auto y = box[2]; y < box[3]; ++y)
        for (auto x = box[0]; x < box[1]; ++x)
          if (grid->id_of_site(x + grid->m[0] * (y + grid->m[1] * z)) >= 0) misnumbered += numbering.index(x, y, z) != next++;
    CHECK(numbering.size() == next);
    CHECK(misnumbered == 0);
  }
}

TEST_CASE("a perturbed lattice's points made from their ids alone are the whole lattice's, bit for bit, for boxes and other shapes") {
  const peridot::LatticeOptions o{.spacing = 1e-3, .perturbation = 0.25, .seed = 42};
  for (const auto& shape : {rectangle({0, 0, 0}, {0.037, 0.023, 0}), box({0, 0, 0}, {0.013, 0.0091, 0.0072}), rectangle({0, 0, 0}, {0.05, 0.001, 0}),
                            subtract(rectangle({0, 0, 0}, {0.037, 0.023, 0}), disk({0.02, 0.01, 0}, 0.006)), sphere({0, 0, 0}, 0.008),
                            annulus({0, 0, 0}, 0.004, 0.011)}) {
    const auto whole = lattice(shape, o);
    const auto grid = shape_lattice(shape, o);
    REQUIRE(grid);
    REQUIRE(grid->size() == whole.size());
    std::vector<std::int64_t> ids;  // scattered: the first, gaps of every size, the last
    for (std::int64_t k = 0; k < std::int64_t(whole.size()); k += 1 + k % 17) ids.push_back(k);
    ids.push_back(std::int64_t(whole.size()) - 1);
    ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
    const auto part = lattice_points(*grid, ids), expected = subset(whole, ids);
    for (int c = 0; c < 3; ++c) CHECK(same::difference(part.x[c], expected.x[c], "positions") == "");
    CHECK(same::difference(part.volume, expected.volume, "volumes") == "");
  }
  const auto grid = box_lattice(rectangle({0, 0, 0}, {0.01, 0.01, 0}), o);
  REQUIRE(grid);
  CHECK_THROWS_AS(lattice_points(*grid, std::vector<std::int64_t>{3, 3}), std::invalid_argument);
  CHECK_THROWS_AS(lattice_points(*grid, std::vector<std::int64_t>{4, 2}), std::invalid_argument);
  CHECK_THROWS_AS(lattice_points(*grid, std::vector<std::int64_t>{std::int64_t(grid->size())}), std::invalid_argument);
}
