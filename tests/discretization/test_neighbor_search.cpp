#include <catch2/catch.hpp>
#include <vector>
#include "../support/same.hpp"
import peridot.discretization;

using namespace peridot;

namespace {
void require_same(const BondList& a, const BondList& b) {
  REQUIRE(a.points() == b.points());
  REQUIRE(same::difference(a.offset, b.offset, "a.offset") == "");
  REQUIRE(same::difference(a.neighbor, b.neighbor, "a.neighbor") == "");
  REQUIRE(same::difference(a.weight, b.weight, "a.weight") == "");
  REQUIRE(same::difference(a.length, b.length, "a.length") == "");
}
}  // namespace

TEST_CASE("cell-list search finds exactly the brute-force bonds on a perturbed 2D cloud") {
  const auto pc = lattice(unite(rectangle({0, 0, 0}, {1.0, 0.5, 0}), disk({1.0, 0.25, 0}, 0.3)),
                          {.spacing = 0.02, .perturbation = 0.2, .seed = 7});
  for (bool partial : {false, true}) {
    const BondOptions o{.horizon = 0.0613, .partial_volume = partial};
    require_same(build_bonds(pc, o), build_bonds_brute_force(pc, o));
  }
}

TEST_CASE("cell-list search finds exactly the brute-force bonds on a perturbed 3D cloud") {
  const auto pc = lattice(subtract(box({0, 0, 0}, {0.4, 0.3, 0.2}), sphere({0.2, 0.15, 0.1}, 0.07)),
                          {.spacing = 0.02, .perturbation = 0.15, .seed = 3});
  const BondOptions o{.horizon = 0.061};
  const auto a = build_bonds(pc, o);
  require_same(a, build_bonds_brute_force(pc, o));
  REQUIRE(a.size() > 0);
}

TEST_CASE("a horizon of 4h keeps the lattice points that lie exactly on the horizon") {
  const double h = 0.1;
  const auto pc = lattice(rectangle({0, 0, 0}, {2.0, 2.0, 0}), {.spacing = h});
  const auto bl = build_bonds(pc, {.horizon = 4 * h});
  // An interior 2D point has 48 partners with |xi| <= 4h (integer lattice points in a radius-4 disk, minus itself).
  std::size_t max_count = 0;
  for (std::size_t i = 0; i < pc.size(); ++i) max_count = std::max(max_count, bl.count(i));
  REQUIRE(max_count == 48);
}

TEST_CASE("bonds are symmetric: every bond i->j has a partner j->i with the same length") {
  const auto pc = lattice(rectangle({0, 0, 0}, {0.5, 0.3, 0}), {.spacing = 0.01, .perturbation = 0.1});
  const auto bl = build_bonds(pc, {.horizon = 0.03});
  for (std::size_t i = 0; i < pc.size(); ++i)
    for (auto b = bl.begin(i); b < bl.end(i); ++b) {
      const auto j = std::size_t(bl.neighbor[b]);
      bool found = false;
      for (auto c = bl.begin(j); c < bl.end(j); ++c)
        if (std::size_t(bl.neighbor[c]) == i) found = bl.length[c] == bl.length[b];
      REQUIRE(found);
    }
}

TEST_CASE("with the partial-volume correction the weights of a full ball add up to its volume") {
  const double h = 1.0;
  SECTION("2D") {
    const auto pc = lattice(rectangle({0, 0, 0}, {21, 21, 0}), {.spacing = h});
    const auto bl = build_bonds(pc, {.horizon = 4 * h, .partial_volume = true});
    const auto plain = build_bonds(pc, {.horizon = 4 * h});
    double sum = 0, sum_plain = 0;
    const std::size_t centre = pc.size() / 2;  // (10.5, 10.5)
    for (auto b = bl.begin(centre); b < bl.end(centre); ++b) sum += bl.weight[b];
    for (auto b = plain.begin(centre); b < plain.end(centre); ++b) sum_plain += plain.weight[b];
    const double exact = 3.14159265358979 * 16 - 1;  // ball minus the point's own cell
    CHECK(sum == Approx(exact).epsilon(0.005));
    CHECK(std::abs(sum - exact) < std::abs(sum_plain - exact));
    for (double w : bl.weight) REQUIRE((w > 0 && w <= 1.0));
  }
  SECTION("3D") {
    const auto pc = lattice(box({0, 0, 0}, {11, 11, 11}), {.spacing = h});
    const auto bl = build_bonds(pc, {.horizon = 4 * h, .partial_volume = true});
    double sum = 0;
    const std::size_t centre = pc.size() / 2;  // (5.5, 5.5, 5.5)
    for (auto b = bl.begin(centre); b < bl.end(centre); ++b) sum += bl.weight[b];
    CHECK(sum == Approx(4.0 / 3.0 * 3.14159265358979 * 64 - 1).epsilon(0.005));
  }
}

TEST_CASE("bad discretization input is rejected with a message naming the quantity") {
  const auto pc = lattice(rectangle({0, 0, 0}, {1, 1, 0}), {.spacing = 0.1});
  REQUIRE_THROWS_WITH(build_bonds(pc, {.horizon = -1}), Catch::Contains("horizon"));
  REQUIRE_THROWS_WITH(build_bonds(pc, {.horizon = 0}), Catch::Contains("horizon"));
  REQUIRE_THROWS_WITH(lattice(rectangle({0, 0, 0}, {1, 1, 0}), {.spacing = -0.1}), Catch::Contains("spacing"));
  REQUIRE_THROWS_WITH(lattice(Shape{}, {.spacing = 0.1}), Catch::Contains("empty"));
}
