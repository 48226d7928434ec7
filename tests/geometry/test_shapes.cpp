#include <catch2/catch.hpp>
import peridot.geometry;

using namespace peridot;

TEST_CASE("primitive shapes contain exactly their points") {
  const auto r = rectangle({0, 0, 0}, {2, 1, 0});
  CHECK(r.contains({1, 0.5, 0}));
  CHECK_FALSE(r.contains({2.1, 0.5, 0}));
  const auto b = box({0, 0, 0}, {1, 1, 1});
  CHECK(b.contains({0.5, 0.5, 0.5}));
  CHECK_FALSE(b.contains({0.5, 0.5, 1.5}));
  const auto d = disk({1, 1, 0}, 0.5);
  CHECK(d.contains({1.4, 1, 0}));
  CHECK_FALSE(d.contains({1.4, 1.4, 0}));
  const auto s = sphere({0, 0, 0}, 1);
  CHECK(s.contains({0.5, 0.5, 0.5}));
  CHECK_FALSE(s.contains({0.6, 0.6, 0.6}));
  const auto a = annulus({0, 0, 0}, 0.08, 0.15);
  CHECK(a.contains({0.1, 0, 0}));
  CHECK_FALSE(a.contains({0.05, 0, 0}));
  CHECK_FALSE(a.contains({0.2, 0, 0}));
  const auto c = cylinder_shell({0, 0, 0}, 1, 2, 0, 1);
  CHECK(c.contains({0, 1.5, 0.5}));
  CHECK_FALSE(c.contains({0, 1.5, 1.5}));
  CHECK_FALSE(c.contains({0, 0.5, 0.5}));
}

TEST_CASE("a polygon uses the even-odd rule, so a concave notch is outside") {
  // A V-notched block: the notch between (1, 2), (1.5, 1), (2, 2) is cut out of the top.
  const auto p = polygon({{0, 0, 0}, {3, 0, 0}, {3, 2, 0}, {2, 2, 0}, {1.5, 1, 0}, {1, 2, 0}, {0, 2, 0}});
  CHECK(p.contains({0.5, 1.5, 0}));
  CHECK(p.contains({1.5, 0.5, 0}));
  CHECK_FALSE(p.contains({1.5, 1.8, 0}));
  CHECK_FALSE(p.contains({4, 1, 0}));
  CHECK(p.bounds().hi[0] == 3);
}

TEST_CASE("union and difference combine shapes") {
  const auto u = unite(rectangle({0, 0, 0}, {1, 1, 0}), disk({2, 0.5, 0}, 0.5));
  CHECK(u.contains({0.5, 0.5, 0}));
  CHECK(u.contains({2.2, 0.5, 0}));
  CHECK_FALSE(u.contains({1.2, 0.95, 0}));
  CHECK(u.bounds().hi[0] == 2.5);
  const auto h = subtract(rectangle({-1, -1, 0}, {1, 1, 0}), disk({0, 0, 0}, 0.2));
  CHECK_FALSE(h.contains({0.1, 0, 0}));
  CHECK(h.contains({0.5, 0, 0}));
  CHECK_THROWS_WITH(unite(rectangle({0, 0, 0}, {1, 1, 0}), sphere({0, 0, 0}, 1)), Catch::Contains("same dimension"));
}

TEST_CASE("invalid shapes are rejected with the rule they break") {
  CHECK_THROWS_WITH(rectangle({1, 0, 0}, {0, 1, 0}), Catch::Contains("max must exceed min"));
  CHECK_THROWS_WITH(disk({0, 0, 0}, -1), Catch::Contains("radius"));
  CHECK_THROWS_WITH(annulus({0, 0, 0}, 2, 1), Catch::Contains("inner_radius"));
  CHECK_THROWS_WITH(polygon({{0, 0, 0}, {1, 0, 0}}), Catch::Contains("3 vertices"));
}

TEST_CASE("a segment crosses a 2D crack only when it properly passes through it") {
  const CrackSegment c{{0, 0, 0}, {1, 0, 0}};
  CHECK(crosses(c, {0.5, -0.1, 0}, {0.5, 0.1, 0}));
  CHECK_FALSE(crosses(c, {1.5, -0.1, 0}, {1.5, 0.1, 0}));   // beyond the tip
  CHECK_FALSE(crosses(c, {0.5, 0.0, 0}, {0.5, 0.1, 0}));    // touching is not crossing
  CHECK_FALSE(crosses(c, {0.2, 0.1, 0}, {0.8, 0.1, 0}));    // running alongside
}

TEST_CASE("a segment crosses a 3D planar crack only inside the rectangle") {
  const CrackRectangle c{{0, 0, 0}, {1, 0, 0}, {0, 0, 1}};  // in the plane y = 0
  CHECK(crosses(c, {0.5, -0.1, 0.5}, {0.5, 0.1, 0.5}));
  CHECK_FALSE(crosses(c, {0.5, -0.1, 1.5}, {0.5, 0.1, 1.5}));
  CHECK_FALSE(crosses(c, {1.5, -0.1, 0.5}, {1.5, 0.1, 0.5}));
  CHECK_FALSE(crosses(c, {0.5, 0.1, 0.5}, {0.5, 0.2, 0.5}));
  const std::vector<Crack> both{CrackSegment{{0, 0, 0}, {1, 0, 0}}, c};
  CHECK(crosses_any(both, {0.5, -0.1, 0.5}, {0.5, 0.1, 0.5}));
}

TEST_CASE("projection onto a region's surface gives the nearest point and the normal pointing into the region") {
  const auto top = rectangle({-10, 1, 0}, {10, 10, 0});
  const auto a = top.project({0.3, 0.8, 0});
  REQUIRE(a);
  CHECK(a->point[0] == Approx(0.3));
  CHECK(a->point[1] == Approx(1.0));
  CHECK(a->normal[1] == Approx(1.0));
  const auto hole = disk({0, 0, 0}, 0.5);
  const auto b = hole.project({0.6, 0.8, 0});
  REQUIRE(b);
  CHECK(b->point[0] == Approx(0.3));
  CHECK(b->point[1] == Approx(0.4));
  CHECK(b->normal[0] == Approx(-0.6));
  CHECK(b->normal[1] == Approx(-0.8));
  const auto both = unite(top, rectangle({1, -10, 0}, {10, 10, 0}));
  const auto c = both.project({0.9, 0.5, 0});  // nearer the right face
  REQUIRE(c);
  CHECK(c->normal[0] == Approx(1.0));
  CHECK_FALSE(top.project({0, 2, 0}));                    // inside: no projection
  CHECK_FALSE(polygon({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}).project({2, 2, 0}));
}
