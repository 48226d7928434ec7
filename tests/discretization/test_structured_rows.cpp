#include <catch2/catch.hpp>
#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>
import peridot.discretization;

using namespace peridot;

// A rank of an MPI run makes only a range of a structured mesh's rows (layers in 3D): with the
// ids shifted by the rows below, it must be exactly the whole mesh's rows, element order
// included, since the run must equal one process's bit for bit.
namespace {

// Whether `part`, made from node row `first` up, is the whole mesh's rows [first, last].
template <class Mesh, class Elements>
void require_rows_of_whole(const Mesh& whole, const Mesh& part, Elements Mesh::*elements, std::int32_t per_row, int first, int last) {
  const std::int32_t offset = first * per_row;
  REQUIRE(part.nodes.size() == std::size_t(last - first + 1) * std::size_t(per_row));
  std::size_t differing = 0;
  for (std::size_t k = 0; k < part.nodes.size(); ++k)
    for (int a = 0; a < 3; ++a) differing += part.nodes[k][a] != whole.nodes[std::size_t(offset) + k][a];
  CHECK(differing == 0);
  // The whole mesh's elements whose nodes all lie in the rows, in order.
  std::vector<std::decay_t<decltype((whole.*elements)[0])>> expected;
  for (auto e : whole.*elements) {
    bool in = true;
    for (auto& n : e) in &= n >= offset && n < offset + std::int32_t(part.nodes.size()), n -= offset;
    if (in) expected.push_back(e);
  }
  CHECK(part.*elements == expected);
  CHECK(part.groups.size() == whole.groups.size());
  for (const auto& [name, ids] : whole.groups) {
    INFO("group " << name);
    std::vector<std::int32_t> in;
    for (auto n : ids)
      if (n >= offset && n < offset + std::int32_t(part.nodes.size())) in.push_back(n - offset);
    REQUIRE(part.groups.count(name) == 1);
    CHECK(part.groups.at(name) == in);
  }
}

}  // namespace

TEST_CASE("A structured triangle mesh made on a range of rows is the whole mesh's rows, elements in order, groups included", "[unit]") {
  const Vec3 lo{-0.3, 0.1, 0}, hi{0.7, 0.83, 0};
  for (bool lower_left : {true, false}) {
    const auto whole = structured_triangles(lo, hi, 7, 9, lower_left);
    for (const std::array<int, 2> rows : {std::array{0, 9}, std::array{0, 3}, std::array{2, 5}, std::array{6, 9}, std::array{4, 4}}) {
      INFO("rows " << rows[0] << " to " << rows[1] << (lower_left ? ", lower-left diagonal" : ", lower-right diagonal"));
      require_rows_of_whole(whole, structured_triangles(lo, hi, 7, 9, lower_left, rows), &TriangleMesh::triangles, 8, rows[0], rows[1]);
    }
  }
  CHECK_THROWS_AS(structured_triangles(lo, hi, 7, 9, true, {5, 4}), std::invalid_argument);
}

TEST_CASE("A structured tetrahedral mesh made on a range of layers is the whole mesh's layers, elements in order, groups included", "[unit]") {
  const Vec3 lo{0, -0.2, 0.1}, hi{0.5, 0.4, 0.77};
  const auto whole = structured_tetrahedra(lo, hi, 4, 3, 6);
  for (const std::array<int, 2> layers : {std::array{0, 6}, std::array{0, 2}, std::array{1, 4}, std::array{3, 6}, std::array{6, 6}}) {
    INFO("layers " << layers[0] << " to " << layers[1]);
    require_rows_of_whole(whole, structured_tetrahedra(lo, hi, 4, 3, 6, layers), &TetMesh::tetrahedra, 5 * 4, layers[0], layers[1]);
  }
}
