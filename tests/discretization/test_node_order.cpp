#include <catch2/catch.hpp>
#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdlib>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <string>
#include <vector>
import peridot.discretization;

using namespace peridot;

namespace {

// The mesh with its nodes numbered in a random order (as a mesh generator's order is, for
// locality), elements and groups following.
template <class Mesh, class Elements>
void shuffle_nodes(Mesh& m, Elements& elements, unsigned seed) {
  std::vector<std::int32_t> to(m.nodes.size());
  std::iota(to.begin(), to.end(), 0);
  std::mt19937 rng(seed);
  std::shuffle(to.begin(), to.end(), rng);
  std::vector<Vec3> nodes(m.nodes.size());
  for (std::size_t i = 0; i < to.size(); ++i) nodes[std::size_t(to[i])] = m.nodes[i];
  m.nodes = nodes;
  for (auto& e : elements)
    for (auto& v : e) v = to[std::size_t(v)];
  for (auto& [name, ids] : m.groups) {
    for (auto& v : ids) v = to[std::size_t(v)];
    std::ranges::sort(ids);
  }
}

// The mean index distance between the two ends of every element edge.
template <class Elements>
double mean_edge_spread(const Elements& elements) {
  double sum = 0;
  std::size_t edges = 0;
  for (const auto& e : elements)
    for (std::size_t a = 0; a < e.size(); ++a)
      for (std::size_t b = a + 1; b < e.size(); ++b, ++edges) sum += std::abs(double(e[a]) - double(e[b]));
  return sum / double(edges);
}

template <class Mesh>
std::map<std::string, std::set<Vec3>> group_positions(const Mesh& m) {
  std::map<std::string, std::set<Vec3>> out;
  for (const auto& [name, ids] : m.groups)
    for (auto i : ids) out[name].insert(m.nodes[std::size_t(i)]);
  return out;
}

}  // namespace

TEST_CASE("The Morton order of a 4 x 4 grid is the Z curve, x before y, and of a cube's corners x, then y, then z", "[mesh]") {
  // The Z curve visits each 2 x 2 block in the order (0,0) (1,0) (0,1) (1,1), blocks in the same order.
  std::vector<Vec3> grid;
  for (int y = 3; y >= 0; --y)
    for (int x = 3; x >= 0; --x) grid.push_back({double(x), double(y), 0});
  const std::array<std::array<int, 2>, 16> z{{{0, 0}, {1, 0}, {0, 1}, {1, 1}, {2, 0}, {3, 0}, {2, 1}, {3, 1},
                                              {0, 2}, {1, 2}, {0, 3}, {1, 3}, {2, 2}, {3, 2}, {2, 3}, {3, 3}}};
  const auto order = morton_order(grid, 2);
  REQUIRE(order.size() == 16);
  for (std::size_t k = 0; k < 16; ++k) {
    INFO("position " << k);
    CHECK(grid[std::size_t(order[k])][0] == z[k][0]);
    CHECK(grid[std::size_t(order[k])][1] == z[k][1]);
  }
  std::vector<Vec3> corners;
  for (int c = 7; c >= 0; --c) corners.push_back({0.5 + (c & 1), -2.0 + ((c >> 1) & 1), 10.0 + (c >> 2)});
  const auto corner_order = morton_order(corners, 3);
  for (std::size_t k = 0; k < 8; ++k) CHECK(corner_order[k] == std::int32_t(7 - k));
  CHECK_THROWS_WITH(morton_order(corners, 4), Catch::Contains("dimension 4"));
}

TEST_CASE("A mesh renumbered along the Morton curve is the same mesh with near nodes at near indices", "[mesh]") {
  SECTION("triangles") {
    TriangleMesh m = structured_triangles({0, 0, 0}, {2, 1, 0}, 120, 60);
    shuffle_nodes(m, m.triangles, 7);
    const TriangleMesh before = m;
    const double spread = mean_edge_spread(m.triangles);
    order_nodes_spatially(m);
    REQUIRE(m.nodes.size() == before.nodes.size());
    REQUIRE(m.triangles.size() == before.triangles.size());
    // Element by element the same corners in the same order, so the same orientation.
    std::size_t moved = 0;
    for (std::size_t t = 0; t < m.triangles.size(); ++t)
      for (std::size_t a = 0; a < 3; ++a)
        moved += m.nodes[std::size_t(m.triangles[t][a])] != before.nodes[std::size_t(before.triangles[t][a])];
    CHECK(moved == 0);
    CHECK(std::set<Vec3>(m.nodes.begin(), m.nodes.end()).size() == m.nodes.size());
    CHECK(group_positions(m) == group_positions(before));
    for (const auto& [name, ids] : m.groups) CHECK(std::ranges::is_sorted(ids));
    validate(m);
    // A shuffled mesh's edges span a third of the nodes on average; along the curve a few rows.
    CHECK(spread > 0.3 * double(m.nodes.size()));
    CHECK(mean_edge_spread(m.triangles) < 0.01 * double(m.nodes.size()));
  }
  SECTION("tetrahedra") {
    TetMesh m = structured_tetrahedra({0, 0, 0}, {1, 1, 1}, 16, 16, 16);
    shuffle_nodes(m, m.tetrahedra, 11);
    const TetMesh before = m;
    const double spread = mean_edge_spread(m.tetrahedra);
    order_nodes_spatially(m);
    std::size_t moved = 0;
    for (std::size_t t = 0; t < m.tetrahedra.size(); ++t)
      for (std::size_t a = 0; a < 4; ++a)
        moved += m.nodes[std::size_t(m.tetrahedra[t][a])] != before.nodes[std::size_t(before.tetrahedra[t][a])];
    CHECK(moved == 0);
    CHECK(group_positions(m) == group_positions(before));
    validate(m);
    CHECK(spread > 0.3 * double(m.nodes.size()));
    CHECK(mean_edge_spread(m.tetrahedra) < 0.05 * double(m.nodes.size()));
  }
}
