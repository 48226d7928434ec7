#include <catch2/catch.hpp>
#include <cmath>
import peridot.solvers;

using namespace peridot;

TEST_CASE("time functions follow their definitions") {
  CHECK(TimeFunction::constant()(123.0) == 1.0);
  const auto r = TimeFunction::ramp(1.0, 3.0);
  CHECK(r(0.5) == 0.0);
  CHECK(r(2.0) == Approx(0.5));
  CHECK(r(10.0) == 1.0);
  const auto e = TimeFunction::exp_decay(2.0);
  CHECK(e(0.0) == 1.0);
  CHECK(e(2.0) == Approx(std::exp(-1.0)));
  const auto t = TimeFunction::table({0.0, 1.0, 3.0}, {0.0, 2.0, -2.0});
  CHECK(t(-1.0) == 0.0);
  CHECK(t(0.5) == Approx(1.0));
  CHECK(t(2.0) == Approx(0.0));
  CHECK(t(5.0) == -2.0);
}

TEST_CASE("invalid time functions are rejected") {
  CHECK_THROWS_WITH(TimeFunction::ramp(2.0, 1.0), Catch::Contains("t1 > t0"));
  CHECK_THROWS_WITH(TimeFunction::exp_decay(0.0), Catch::Contains("tau"));
  CHECK_THROWS_WITH(TimeFunction::table({0.0, 0.0}, {1.0, 2.0}), Catch::Contains("increasing"));
  CHECK_THROWS(TimeFunction::table({0.0, 1.0}, {1.0}));
}
