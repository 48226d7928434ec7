#include <catch2/catch.hpp>
#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>
import peridot.discretization;

using namespace peridot;

// A rank of an MPI run makes only a box of a structured mesh's nodes: it must be exactly the
// whole mesh's nodes in the box and the elements among them, in the whole mesh's order, since the
// run must equal one process's bit for bit.
namespace {

// Whether `part` is the whole mesh's nodes in the index box {i0, i1, j0, j1, k0, k1} (inclusive)
// of a grid of n[0] x n[1] x n[2] nodes, x fastest, and the elements among them.
template <class Mesh, class Elements>
void require_box_of_whole(const Mesh& whole, const Mesh& part, Elements Mesh::*elements, std::array<int, 3> n, std::array<int, 6> box) {
  // The box's whole-mesh node ids, ascending: the part's nodes in order.
  std::vector<std::int32_t> ids;
  std::map<std::int32_t, std::int32_t> local;
  for (int k = box[4]; k <= box[5]; ++k)
    for (int j = box[2]; j <= box[3]; ++j)
      for (int i = box[0]; i <= box[1]; ++i) {
        local[(k * n[1] + j) * n[0] + i] = std::int32_t(ids.size());
        ids.push_back((k * n[1] + j) * n[0] + i);
      }
  REQUIRE(part.nodes.size() == ids.size());
  std::size_t differing = 0;
  for (std::size_t k = 0; k < ids.size(); ++k)
    for (int a = 0; a < 3; ++a) differing += part.nodes[k][a] != whole.nodes[std::size_t(ids[k])][a];
  CHECK(differing == 0);
  // The whole mesh's elements whose nodes all lie in the box, in order, renumbered.
  std::vector<std::decay_t<decltype((whole.*elements)[0])>> expected;
  for (auto e : whole.*elements) {
    bool in = true;
    for (auto& v : e) {
      const auto at = local.find(v);
      in &= at != local.end();
      if (at != local.end()) v = at->second;
    }
    if (in) expected.push_back(e);
  }
  CHECK(part.*elements == expected);
  CHECK(part.groups.size() == whole.groups.size());
  for (const auto& [name, members] : whole.groups) {
    INFO("group " << name);
    std::vector<std::int32_t> in;
    for (auto v : members)
      if (local.count(v)) in.push_back(local.at(v));
    REQUIRE(part.groups.count(name) == 1);
    CHECK(part.groups.at(name) == in);
  }
}

}  // namespace

TEST_CASE("A structured triangle mesh made on a box of its nodes is the whole mesh's nodes there, elements in order, groups included", "[unit]") {
  const Vec3 lo{-0.3, 0.1, 0}, hi{0.7, 0.83, 0};
  for (bool lower_left : {true, false}) {
    const auto whole = structured_triangles(lo, hi, 7, 9, lower_left);
    for (const std::array<int, 4> box : {std::array{0, 7, 0, 9}, std::array{0, 7, 0, 3}, std::array{2, 5, 2, 5}, std::array{3, 7, 6, 9}, std::array{0, 2, 4, 4},
                                         std::array{7, 7, 0, 9}}) {
      INFO("nodes [" << box[0] << ", " << box[1] << "] x [" << box[2] << ", " << box[3] << "]" << (lower_left ? ", lower-left diagonal" : ", lower-right diagonal"));
      require_box_of_whole(whole, structured_triangles(lo, hi, 7, 9, lower_left, box), &TriangleMesh::triangles, {8, 10, 1}, {box[0], box[1], box[2], box[3], 0, 0});
    }
  }
  CHECK_THROWS_AS(structured_triangles(lo, hi, 7, 9, true, {0, 7, 5, 4}), std::invalid_argument);
}

TEST_CASE("A structured tetrahedral mesh made on a box of its nodes is the whole mesh's nodes there, elements in order, groups included", "[unit]") {
  const Vec3 lo{0, -0.2, 0.1}, hi{0.5, 0.4, 0.77};
  const auto whole = structured_tetrahedra(lo, hi, 4, 3, 6);
  for (const std::array<int, 6> box : {std::array{0, 4, 0, 3, 0, 6}, std::array{0, 4, 0, 3, 0, 2}, std::array{1, 3, 1, 2, 1, 4}, std::array{2, 4, 0, 1, 3, 6},
                                       std::array{0, 4, 3, 3, 6, 6}}) {
    INFO("nodes [" << box[0] << ", " << box[1] << "] x [" << box[2] << ", " << box[3] << "] x [" << box[4] << ", " << box[5] << "]");
    require_box_of_whole(whole, structured_tetrahedra(lo, hi, 4, 3, 6, box), &TetMesh::tetrahedra, {5, 4, 7}, box);
  }
}
