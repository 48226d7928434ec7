#include <catch2/catch.hpp>

#include <cstdint>
#include <map>
#include <numeric>
#include <random>
#include <stdexcept>
#include <vector>
import peridot.analysis;

using namespace peridot;

namespace {

constexpr double h = 0.0025;
constexpr double density = 2440;

// A 0.1 m x 0.1 m plate, optionally cut right across by straight pre-cracks at heights ys.
Body plate(const std::vector<double>& ys = {}) {
  Body body;
  body.points = lattice(rectangle({0, 0, 0}, {0.1, 0.1, 0}), {.spacing = h});
  BondOptions o{.horizon = 3 * h};
  // The cracks overshoot both edges, so every bond crossing their height is cut.
  for (double y : ys) o.cracks.push_back(CrackSegment{{-0.01, y, 0}, {0.11, y, 0}});
  body.bonds = build_bonds(body.points, o);
  body.density = density;
  return body;
}

double total_mass(const Body& body) {
  double m = 0;
  for (double v : body.points.volume) m += density * v;
  return m;
}

// Breaks every bond of point k, from both ends.
void isolate(Body& body, std::size_t k) {
  auto& bl = body.bonds;
  for (auto b = bl.begin(k); b < bl.end(k); ++b) {
    bl.intact[b] = 0;
    const auto j = std::size_t(bl.neighbor[b]);
    for (auto r = bl.begin(j); r < bl.end(j); ++r)
      if (std::size_t(bl.neighbor[r]) == k) bl.intact[r] = 0;
  }
}

std::size_t centre_point(const Body& body) {
  std::size_t best = 0;
  double d = 1e9;
  for (std::size_t i = 0; i < body.size(); ++i) {
    const double e = norm(body.points.position(i) - Vec3{0.05, 0.05, 0});
    if (e < d) d = e, best = i;
  }
  return best;
}

}  // namespace

TEST_CASE("an uncut plate is one fragment holding every point and all the mass") {
  const Body body = plate();
  const auto r = count_fragments(body);
  REQUIRE(r.count == 1);
  REQUIRE(r.large == 1);
  REQUIRE(r.debris == 0);
  REQUIRE(r.fragments[0].nodes == body.size());
  REQUIRE(r.fragments[0].mass == Approx(total_mass(body)));
  for (auto l : r.label) REQUIRE(l == 0);
}

TEST_CASE("a plate cut by three full-width pre-cracks has exactly four fragments, heaviest first") {
  // Strips 0.01, 0.02, 0.03 and 0.04 m high: 10, 20, 30 and 40 % of the mass.
  const std::vector<double> cuts{0.01, 0.03, 0.06};
  const Body body = plate(cuts);
  const auto r = count_fragments(body, {.large_mass_fraction = 0.25});
  REQUIRE(r.count == 4);
  REQUIRE(r.debris == 0);
  REQUIRE(r.large == 2);  // the 30 % and 40 % strips

  // Each fragment is exactly one strip: same label within a strip, different across strips.
  const auto strip = [&](double y) { return int(y > 0.01) + int(y > 0.03) + int(y > 0.06); };
  std::vector<std::int32_t> label_of_strip(4, -1);
  std::vector<std::size_t> nodes_of_strip(4, 0);
  for (std::size_t i = 0; i < body.size(); ++i) {
    const int s = strip(body.points.x[1][i]);
    if (label_of_strip[s] < 0) label_of_strip[s] = r.label[i];
    REQUIRE(r.label[i] == label_of_strip[s]);
    ++nodes_of_strip[s];
  }
  for (int a = 0; a < 4; ++a)
    for (int b = a + 1; b < 4; ++b) REQUIRE(label_of_strip[a] != label_of_strip[b]);
  for (int s = 0; s < 4; ++s) REQUIRE(r.fragments[std::size_t(label_of_strip[s])].nodes == nodes_of_strip[s]);

  double sum = 0;
  for (std::size_t f = 0; f < r.fragments.size(); ++f) {
    if (f > 0) REQUIRE(r.fragments[f].mass <= r.fragments[f - 1].mass);
    sum += r.fragments[f].mass;
  }
  REQUIRE(sum + r.debris_mass == Approx(total_mass(body)));
  REQUIRE(r.total_mass == Approx(total_mass(body)));
}

TEST_CASE("a point with every bond broken is debris, not a fragment, and masses still add up") {
  Body body = plate();
  const std::size_t k = centre_point(body);
  isolate(body, k);
  const auto r = count_fragments(body);
  REQUIRE(r.count == 1);
  REQUIRE(r.debris == 1);
  REQUIRE(r.label[k] == -1);
  REQUIRE(r.debris_mass == Approx(density * body.points.volume[k]));
  REQUIRE(r.fragments[0].nodes == body.size() - 1);
  REQUIRE(r.fragments[0].mass + r.debris_mass == Approx(total_mass(body)));
}

TEST_CASE("a bond still intact from its partner's end keeps the pair linked") {
  Body body = plate();
  const std::size_t k = centre_point(body);
  auto& bl = body.bonds;
  for (auto b = bl.begin(k); b < bl.end(k); ++b) bl.intact[b] = 0;  // k's side only
  const auto r = count_fragments(body);
  REQUIRE(r.count == 1);
  REQUIRE(r.debris == 0);
  REQUIRE(r.label[k] == 0);
}

// Reference partition: union-find over every bond intact from either end.
std::vector<std::size_t> reference_components(const Body& body) {
  std::vector<std::size_t> parent(body.size());
  std::iota(parent.begin(), parent.end(), std::size_t(0));
  const auto find = [&](std::size_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  const auto& bl = body.bonds;
  for (std::size_t i = 0; i < body.size(); ++i)
    for (auto b = bl.begin(i); b < bl.end(i); ++b)
      if (bl.intact[b]) parent[find(i)] = find(std::size_t(bl.neighbor[b]));
  for (std::size_t i = 0; i < body.size(); ++i) parent[i] = find(i);
  return parent;
}

namespace {

// 10^4 points (several blocks), a perturbed lattice (an imperfect skeleton), two cuts and a
// shattered zone where most bonds are broken: many fragments, debris and cross-block pieces.
Body shattered_plate() {
  Body body;
  body.points = lattice(rectangle({0, 0, 0}, {0.1, 0.1, 0}), {.spacing = 1e-3, .perturbation = 0.2, .seed = 3});
  body.bonds = build_bonds(body.points, {.horizon = 3e-3, .cracks = {CrackSegment{{-0.01, 0.031, 0}, {0.11, 0.031, 0}},
                                                                      CrackSegment{{0.052, -0.01, 0}, {0.052, 0.05, 0}}}});
  body.density = density;
  std::mt19937 rng(11);
  std::bernoulli_distribution survive(0.08);
  auto& bl = body.bonds;
  for (std::size_t i = 0; i < body.size(); ++i)
    for (auto b = bl.begin(i); b < bl.end(i); ++b) {
      const auto j = std::size_t(bl.neighbor[b]);
      if (j < i) continue;
      const auto p = body.points.position(i);
      if (p[1] < 0.07 || survive(rng)) continue;
      bl.intact[b] = 0;  // shattered band y > 0.07, broken from both ends
      for (auto r = bl.begin(j); r < bl.end(j); ++r)
        if (std::size_t(bl.neighbor[r]) == i) bl.intact[r] = 0;
    }
  return body;
}

// The whole body cut into `ranks` parts by coordinate bisection, as N MPI ranks hold it (ghosts
// one bond deep, without their rows): each part's share, with the owners' piece ids looked up
// where the halo would bring them, joined as rank 0 joins them.
FragmentReport joined_over_parts(const Body& whole, int ranks) {
  std::vector<Slab> slabs;
  std::vector<Body> parts(std::size_t(ranks), Body{});
  std::vector<std::vector<std::uint32_t>> labels;
  std::vector<double> offset{0};
  for (int r = 0; r < ranks; ++r) {
    slabs.push_back(rcb_of(whole.points, whole.bonds, r, ranks, 1));
    auto& part = parts[std::size_t(r)];
    part.points = subset(whole.points, slabs.back().local_ids);
    part.bonds = local_bonds(whole.bonds, slabs.back());
    part.density = whole.density;
    std::size_t count = 0;
    labels.push_back(piece_labels(part, count));
    offset.push_back(offset.back() + double(count));
  }
  std::vector<double> pieces, joins;
  double debris = 0, debris_mass = 0, mass = 0;
  for (int r = 0; r < ranks; ++r) {
    const auto& slab = slabs[std::size_t(r)];
    std::vector<double> owner_piece(slab.local_size());
    for (std::size_t i = 0; i < owner_piece.size(); ++i)
      for (int q = 0; q < ranks; ++q)
        if (const auto k = slabs[std::size_t(q)].local_of(slab.local_ids[i]); k >= 0 && slabs[std::size_t(q)].is_owned[std::size_t(k)])
          owner_piece[i] = offset[std::size_t(q)] + double(labels[std::size_t(q)][std::size_t(k)]);
    const auto share = fragment_share(parts[std::size_t(r)], labels[std::size_t(r)], std::size_t(offset[std::size_t(r) + 1] - offset[std::size_t(r)]),
                                      slab.is_owned, offset[std::size_t(r)], owner_piece);
    pieces.insert(pieces.end(), share.pieces.begin(), share.pieces.end());
    joins.insert(joins.end(), share.joins.begin(), share.joins.end());
    debris += share.debris, debris_mass += share.debris_mass, mass += share.total_mass;
  }
  return join_fragment_shares(pieces, joins, debris, debris_mass, mass);
}

}  // namespace

TEST_CASE("fragments of a large shattered plate match a plain union-find over all linked bonds") {
  const bool known_spacing = GENERATE(true, false);
  Body body = shattered_plate();
  if (!known_spacing) body.points.spacing = 0;

  const auto r = count_fragments(body);
  const auto ref = reference_components(body);
  std::map<std::size_t, std::size_t> size;
  for (auto c : ref) ++size[c];
  std::map<std::size_t, std::int32_t> ours;  // reference component -> our label
  std::map<std::int32_t, std::size_t> theirs;
  std::size_t debris = 0;
  for (std::size_t i = 0; i < body.size(); ++i) {
    if (size[ref[i]] == 1) {
      ++debris;
      REQUIRE(r.label[i] == -1);
      continue;
    }
    REQUIRE(r.label[i] >= 0);
    const auto [a, fresh_a] = ours.insert({ref[i], r.label[i]});
    const auto [b, fresh_b] = theirs.insert({r.label[i], ref[i]});
    REQUIRE(a->second == r.label[i]);
    REQUIRE(b->second == ref[i]);
  }
  REQUIRE(r.debris == debris);
  REQUIRE(r.count == ours.size());
  REQUIRE(r.count > 10);  // the case really is shattered
  REQUIRE(debris > 10);
}

TEST_CASE("a body without bonds is all debris") {
  Body body = plate();
  body.bonds = BondList{};
  const auto r = count_fragments(body);
  REQUIRE(r.count == 0);
  REQUIRE(r.debris == body.size());
  REQUIRE(r.debris_mass == Approx(total_mass(body)));
}

TEST_CASE("a large_mass_fraction outside [0, 1] is rejected with a message naming it") {
  const Body body = plate();
  REQUIRE_THROWS_WITH(count_fragments(body, {.large_mass_fraction = 1.5}), Catch::Contains("large_mass_fraction"));
  REQUIRE_THROWS_AS(count_fragments(body, {.large_mass_fraction = -0.1}), std::invalid_argument);
}

TEST_CASE("the ranks' fragment shares of a shattered plate, joined, count what one search over the whole body counts") {
  const Body body = shattered_plate();
  const auto whole = count_fragments(body);
  REQUIRE(whole.count > 10);
  for (int ranks : {2, 3, 4}) {
    INFO(ranks << " parts");
    const auto joined = joined_over_parts(body, ranks);
    CHECK(joined.count == whole.count);
    CHECK(joined.debris == whole.debris);
    CHECK(joined.large == whole.large);
    REQUIRE(joined.fragments.size() == whole.fragments.size());
    std::size_t nodes_differ = 0;
    for (std::size_t k = 0; k < whole.fragments.size(); ++k) nodes_differ += joined.fragments[k].nodes != whole.fragments[k].nodes;
    CHECK(nodes_differ == 0);
    CHECK(joined.total_mass == Approx(whole.total_mass).epsilon(1e-12));
  }
}

TEST_CASE("two points held together across a cut by one bond, seen from one end only on each side, are one fragment") {
  // Every bond broken but one pair's, whose ends two parts own: each part holds the row of its
  // own end only, so each sees the pair from one side, whichever end has the lower index.
  Body body = plate();
  const auto slab = rcb_of(body.points, body.bonds, 1, 2, 1);
  auto& bl = body.bonds;
  std::int64_t keep_i = -1, keep_j = -1;
  for (std::size_t i = 0; i < body.size() && keep_i < 0; ++i) {
    const auto li = slab.local_of(std::int64_t(i));
    if (li < 0 || !slab.is_owned[std::size_t(li)]) continue;
    for (auto b = bl.begin(i); b < bl.end(i); ++b)
      if (const auto j = std::int64_t(bl.neighbor[b]); j < std::int64_t(i) && !slab.is_owned[std::size_t(slab.local_of(j))]) {
        keep_i = std::int64_t(i), keep_j = j;
        break;
      }
  }
  REQUIRE(keep_i >= 0);
  for (std::size_t i = 0; i < body.size(); ++i)
    for (auto b = bl.begin(i); b < bl.end(i); ++b) {
      const auto j = std::int64_t(bl.neighbor[b]);
      bl.intact[b] = (std::int64_t(i) == keep_i && j == keep_j) || (std::int64_t(i) == keep_j && j == keep_i);
    }
  const auto whole = count_fragments(body);
  REQUIRE(whole.count == 1);
  const auto joined = joined_over_parts(body, 2);
  CHECK(joined.count == 1);
  CHECK(joined.debris == body.size() - 2);
  REQUIRE(joined.fragments.size() == 1);
  CHECK(joined.fragments[0].nodes == 2);
}
