#include <catch2/catch.hpp>
import peridot.discretization;

using namespace peridot;

TEST_CASE("no surviving bond crosses a 2D pre-crack and bonds that only come near it survive") {
  const double h = 0.01;
  const auto pc = lattice(rectangle({0, 0, 0}, {1.0, 0.4, 0}), {.spacing = h});
  const CrackSegment crack{{0, 0.2, 0}, {0.5, 0.2, 0}};
  const auto cut = build_bonds(pc, {.horizon = 4 * h, .cracks = {crack}});
  const auto full = build_bonds(pc, {.horizon = 4 * h});
  std::size_t crossing = 0, near_kept = 0;
  for (std::size_t i = 0; i < pc.size(); ++i)
    for (auto b = cut.begin(i); b < cut.end(i); ++b) {
      const auto p = pc.position(i), q = pc.position(std::size_t(cut.neighbor[b]));
      // Crossing test written independently: opposite sides of y = 0.2 and crossing point x < 0.5.
      const bool opposite = (p[1] - 0.2) * (q[1] - 0.2) < 0;
      const double x_cross = p[0] + (0.2 - p[1]) / (q[1] - p[1]) * (q[0] - p[0]);
      if (opposite && x_cross > 0 && x_cross < 0.5) ++crossing;
      if (opposite && x_cross > 0.5 && x_cross < 0.5 + 2 * h) ++near_kept;
    }
  REQUIRE(crossing == 0);
  REQUIRE(near_kept > 0);  // bonds passing just beyond the tip are kept
  REQUIRE(cut.size() < full.size());
}

TEST_CASE("no surviving bond crosses a 3D planar pre-crack through the thickness") {
  const double h = 0.01;
  const auto pc = lattice(box({0, 0, 0}, {0.2, 0.1, 0.04}), {.spacing = h});
  const CrackRectangle crack{{0, 0.05, -0.01}, {0.1, 0, 0}, {0, 0, 0.06}};
  const auto cut = build_bonds(pc, {.horizon = 3 * h, .cracks = {crack}});
  std::size_t crossing = 0, beside = 0;
  for (std::size_t i = 0; i < pc.size(); ++i)
    for (auto b = cut.begin(i); b < cut.end(i); ++b) {
      const auto p = pc.position(i), q = pc.position(std::size_t(cut.neighbor[b]));
      const bool opposite = (p[1] - 0.05) * (q[1] - 0.05) < 0;
      const double x_cross = p[0] + (0.05 - p[1]) / (q[1] - p[1]) * (q[0] - p[0]);
      if (opposite && x_cross < 0.1) ++crossing;
      if (opposite && x_cross > 0.1) ++beside;
    }
  REQUIRE(crossing == 0);
  REQUIRE(beside > 0);
}
