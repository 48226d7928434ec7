#include <catch2/catch.hpp>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <utility>
#include <vector>
import peridot.discretization;

using namespace peridot;
using Catch::Contains;

namespace {

// The three nodes of each face of each tetrahedron, sorted, with how many tetrahedra hold it.
std::map<std::array<std::int32_t, 3>, int> face_counts(const TetMesh& m) {
  std::map<std::array<std::int32_t, 3>, int> faces;
  for (const auto& t : m.tetrahedra)
    for (std::size_t skip = 0; skip < 4; ++skip) {
      std::array<std::int32_t, 3> f{};
      std::size_t k = 0;
      for (std::size_t a = 0; a < 4; ++a)
        if (a != skip) f[k++] = t[a];
      std::ranges::sort(f);
      ++faces[f];
    }
  return faces;
}

}  // namespace

TEST_CASE("A structured tetrahedral mesh fills its box with positive tetrahedra, six per cell", "[unit]") {
  const Vec3 lo{-0.5, 0, 1}, hi{1.5, 0.75, 1.5};
  const int nx = 4, ny = 3, nz = 2;
  const auto m = structured_tetrahedra(lo, hi, nx, ny, nz);
  REQUIRE(m.nodes.size() == std::size_t((nx + 1) * (ny + 1) * (nz + 1)));
  REQUIRE(m.tetrahedra.size() == std::size_t(6 * nx * ny * nz));
  // Each cell splits into six tetrahedra of equal volume, a sixth of the cell.
  const double cell = (hi[0] - lo[0]) / nx * (hi[1] - lo[1]) / ny * (hi[2] - lo[2]) / nz;
  double total = 0, worst = 0;
  for (std::size_t t = 0; t < m.tetrahedra.size(); ++t) {
    total += m.volume(t);
    worst = std::max(worst, std::abs(m.volume(t) - cell / 6));
  }
  CHECK(worst < 1e-15);
  CHECK(total == Approx(2.0 * 0.75 * 0.5).epsilon(1e-13));
  CHECK_NOTHROW(validate(m));
}

TEST_CASE("Kuhn's cut is conforming: an interior face belongs to two tetrahedra, a face on one lies on the box", "[unit]") {
  const auto m = structured_tetrahedra({0, 0, 0}, {1, 1, 1}, 3, 2, 2);
  std::size_t boundary = 0;
  for (const auto& [f, count] : face_counts(m)) {
    REQUIRE(count <= 2);
    if (count == 2) continue;
    ++boundary;
    // A boundary face: its three nodes share a coordinate at a side of the box.
    bool on_side = false;
    for (int k = 0; k < 3; ++k)
      for (double side : {0.0, 1.0})
        on_side = on_side || std::ranges::all_of(f, [&](std::int32_t v) { return m.nodes[std::size_t(v)][k] == side; });
    REQUIRE(on_side);
  }
  // Two triangles per boundary square: 2 (3x2 + 3x2 + 2x2) squares in all.
  CHECK(boundary == std::size_t(2 * 2 * (3 * 2 + 3 * 2 + 2 * 2)));
}

TEST_CASE("Lumped volumes are a quarter of the adjacent tetrahedra: h^3 inside, and they tile the box", "[unit]") {
  const double h = 0.1;
  const auto m = structured_tetrahedra({0, 0, 0}, {4 * h, 4 * h, 4 * h}, 4, 4, 4);
  const auto pc = mesh_points(m);
  REQUIRE(pc.dim == 3);
  REQUIRE(pc.tetrahedra.size() == m.tetrahedra.size());
  REQUIRE(pc.triangles.empty());
  double total = 0;
  for (double v : pc.volume) total += v;
  CHECK(total == Approx(std::pow(4 * h, 3)).epsilon(1e-13));
  // 24 tetrahedra of h^3 / 6 meet at an interior node of Kuhn's cut. Of a cell's six, all hold
  // the two ends of its main diagonal and two hold each other corner.
  const auto id = [](int i, int j, int k) { return std::size_t((k * 5 + j) * 5 + i); };
  CHECK(pc.volume[id(2, 2, 2)] == Approx(h * h * h).epsilon(1e-12));
  CHECK(pc.volume[id(0, 0, 0)] == Approx(h * h * h / 4).epsilon(1e-12));
  CHECK(pc.volume[id(4, 0, 0)] == Approx(h * h * h / 12).epsilon(1e-12));
  CHECK(pc.volume[id(4, 4, 4)] == Approx(h * h * h / 4).epsilon(1e-12));
  // The mean edge of the cube's cut: 6 tets x (3 edges h, 2 face diagonals, 1 body diagonal).
  CHECK(pc.spacing == Approx(h * (3 + 2 * std::sqrt(2.0) + std::sqrt(3.0)) / 6).epsilon(1e-12));
}

TEST_CASE("The side groups of a structured tetrahedral mesh hold exactly the nodes on each side", "[unit]") {
  const auto m = structured_tetrahedra({0, 0, 0}, {1, 2, 3}, 2, 3, 4);
  const std::map<std::string, std::pair<int, double>> sides{{"left", {0, 0.0}},   {"right", {0, 1.0}}, {"bottom", {1, 0.0}},
                                                            {"top", {1, 2.0}},    {"back", {2, 0.0}},  {"front", {2, 3.0}}};
  REQUIRE(m.groups.size() == sides.size());
  for (const auto& [name, side] : sides) {
    INFO(name);
    const auto& g = m.groups.at(name);
    CHECK(std::ranges::is_sorted(g));
    std::size_t on = 0;
    for (const auto& p : m.nodes) on += p[std::size_t(side.first)] == side.second;
    CHECK(g.size() == on);
    for (auto v : g) CHECK(m.nodes[std::size_t(v)][std::size_t(side.first)] == side.second);
  }
}

TEST_CASE("Bad tetrahedral meshes are refused naming the element and the reason", "[unit][input]") {
  auto m = structured_tetrahedra({0, 0, 0}, {1, 1, 1}, 1, 1, 1);
  SECTION("inverted") {
    std::swap(m.tetrahedra[3][0], m.tetrahedra[3][1]);
    CHECK_THROWS_WITH(validate(m), Contains("tetrahedron 3") && Contains("inverted"));
  }
  SECTION("degenerate") {
    m.nodes.push_back({0.5, 0.5, 0});
    m.tetrahedra[0] = {0, 1, 2, std::int32_t(m.nodes.size() - 1)};  // all in z = 0
    CHECK_THROWS_WITH(validate(m), Contains("tetrahedron 0") && Contains("degenerate"));
  }
  SECTION("a node out of range") {
    m.tetrahedra[5][2] = 8;
    CHECK_THROWS_WITH(validate(m), Contains("tetrahedron 5 refers to node 8") && Contains("8 nodes"));
  }
  SECTION("a node no tetrahedron uses") {
    m.nodes.push_back({2, 2, 2});
    CHECK_THROWS_WITH(mesh_points(m), Contains("mesh node 8 belongs to no tetrahedron"));
  }
  SECTION("empty") {
    m.tetrahedra.clear();
    CHECK_THROWS_WITH(validate(m), Contains("no tetrahedra"));
  }
  CHECK_THROWS_WITH(structured_tetrahedra({0, 0, 0}, {1, 1, 0}, 1, 1, 1), Contains("hi > lo"));
}
