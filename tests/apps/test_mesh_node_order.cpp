// A mesh file's nodes are renumbered along a Morton curve at set-up (discretization.mesh.node_order,
// spatial by default) for the force passes' memory locality: a run must not depend on it
// beyond the round-off of sums taken in another order.
#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <map>
#include <string>
#include <vector>
#include "../support/csv_columns.hpp"
#include "../support/in_process.hpp"
import peridot.run;
import peridot.io;

using namespace peridot;
namespace fs = std::filesystem;

namespace {

// The seed 003 pre-cracked plate (a .geo meshed by Gmsh, about 10^4 nodes) for 200 steps
// with the given node order, a VTU at the end.
fs::path run_plate(const std::string& order) {
  return in_process::run_edited("fe/hole_precrack_coarse.yaml",
                                {{"mesh: {file: hole_precrack.geo, size: 0.5e-3}",
                                  "mesh: {file: " + (fs::path(PERIDOT_SOURCE_DIR) / "data/decks/fe/hole_precrack.geo").string() +
                                      ", size: 0.5e-3, node_order: " + order + "}"},
                                 {"end_time: 600.0e-6", "end_time: 6.0e-6"},
                                 {"csv: {every: 100}", "csv: {every: 20}\n  vtu: {every: 200}"},
                                 {"  png: {every: 2500, field: damage}\n", ""}},
                                "peridot_node_order_", order, 2);
}

// Point -> (u_x, u_y, damage), keyed by position.
std::map<std::array<double, 2>, std::array<double, 3>> by_position(const VtuData& d) {
  const auto* u = d.find("displacement");
  const auto* z = d.find("damage");
  REQUIRE(u);
  REQUIRE(z);
  std::map<std::array<double, 2>, std::array<double, 3>> out;
  for (std::size_t i = 0; i < d.x[0].size(); ++i)
    out[{d.x[0][i], d.x[1][i]}] = {u->values[3 * i], u->values[3 * i + 1], z->values[i]};
  return out;
}

}  // namespace

TEST_CASE("A mesh run with its nodes in Morton order equals the run in the file's order to round-off, point by point", "[input]") {
  const fs::path spatial = run_plate("spatial"), file = run_plate("file");
  const auto a = csv_columns::read(spatial / "fe_hole_precrack_coarse_history.csv");
  const auto b = csv_columns::read(file / "fe_hole_precrack_coarse_history.csv");
  REQUIRE(a.size() == b.size());
  for (const char* column : {"kinetic_J", "strain_J", "external_work_J", "damage_fraction"}) {
    INFO(column);
    REQUIRE(a.count(column) == 1);
    REQUIRE(a.at(column).size() == 11);  // steps 0, 20, ..., 200
    REQUIRE(b.at(column).size() == 11);
    for (std::size_t r = 0; r < a.at(column).size(); ++r) CHECK(a.at(column)[r] == Approx(b.at(column)[r]).epsilon(1e-9).margin(1e-300));
  }
  CHECK(a.at("strain_J").back() > 0);

  const auto va = read_vtu(spatial / "fe_hole_precrack_coarse_0000200.vtu");
  const auto vb = read_vtu(file / "fe_hole_precrack_coarse_0000200.vtu");
  REQUIRE(va.x[0].size() == vb.x[0].size());
  REQUIRE(va.cells == vb.cells);
  const auto pa = by_position(va), pb = by_position(vb);
  REQUIRE(pa.size() == va.x[0].size());  // every node at its own position
  double umax = 0;
  for (const auto& [x, v] : pb) umax = std::max({umax, std::abs(v[0]), std::abs(v[1])});
  REQUIRE(umax > 0);
  std::size_t differ = 0, missing = 0;
  for (const auto& [x, v] : pa) {
    const auto it = pb.find(x);
    if (it == pb.end()) {
      ++missing;
      continue;
    }
    for (std::size_t k = 0; k < 2; ++k) differ += std::abs(v[k] - it->second[k]) > 1e-9 * umax;
    differ += std::abs(v[2] - it->second[2]) > 1e-9 * std::max(1.0, std::abs(v[2]));
  }
  CHECK(missing == 0);
  CHECK(differ == 0);
  // The renumbering is a real one: the two files list their points in different orders.
  std::size_t same_place = 0;
  for (std::size_t i = 0; i < va.x[0].size(); ++i) same_place += va.x[0][i] == vb.x[0][i] && va.x[1][i] == vb.x[1][i];
  CHECK(same_place < va.x[0].size() / 2);
  fs::remove_all(spatial);
  fs::remove_all(file);
}
