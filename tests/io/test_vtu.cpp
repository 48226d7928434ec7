#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>
import peridot.io;

using namespace peridot;

TEST_CASE("a VTU series round-trips positions and fields and lists every step in the PVD") {
  const auto dir = std::filesystem::temp_directory_path() / "peridot_test_vtu";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const auto pc = lattice(disk({0, 0, 0}, 0.01), {.spacing = 1e-3, .perturbation = 0.1});
  std::vector<double> a(pc.size()), b(pc.size());
  for (std::size_t i = 0; i < pc.size(); ++i) a[i] = double(i) * 0.5, b[i] = -double(i);
  const NamedField fields[] = {{"damage", 1, {a, {}, {}}}, {"displacement", 3, {a, b, {}}}};
  PvdSeries series(dir, "run");
  series.write(0.0, 0, pc, fields);
  const auto last = series.write(1e-6, 10, pc, fields);
  const auto steps = read_pvd(series.pvd());
  REQUIRE(steps.size() == 2);
  CHECK(steps[1].first == Approx(1e-6));
  CHECK(steps[1].second == last);
  const auto d = read_vtu(last);
  REQUIRE(d.x[0].size() == pc.size());
  CHECK(d.x[0] == pc.x[0]);
  CHECK(d.x[1] == pc.x[1]);
  const auto* dmg = d.find("damage");
  REQUIRE(dmg);
  CHECK(dmg->values == a);
  const auto* disp = d.find("displacement");
  REQUIRE(disp);
  REQUIRE(disp->components == 3);
  CHECK(disp->values[3 * 7 + 1] == b[7]);
  CHECK(disp->values[3 * 7 + 2] == 0.0);
  // No temporary files are left behind.
  for (const auto& e : std::filesystem::directory_iterator(dir)) CHECK(e.path().extension() != ".tmp");
  std::filesystem::remove_all(dir);
}

TEST_CASE("a truncated VTU is reported, not read as garbage") {
  const auto dir = std::filesystem::temp_directory_path() / "peridot_test_vtu_trunc";
  std::filesystem::create_directories(dir);
  const auto pc = lattice(rectangle({0, 0, 0}, {0.01, 0.01, 0}), {.spacing = 1e-3});
  std::vector<double> a(pc.size(), 1.0);
  const NamedField fields[] = {{"damage", 1, {a, {}, {}}}};
  write_vtu(dir / "x.vtu", pc, fields);
  std::filesystem::resize_file(dir / "x.vtu", std::filesystem::file_size(dir / "x.vtu") - 900);
  CHECK_THROWS_WITH(read_vtu(dir / "x.vtu"), Catch::Contains("truncated"));
  std::filesystem::remove_all(dir);
}

TEST_CASE("a mesh point cloud is written with its triangles as VTU cells") {
  const auto dir = std::filesystem::temp_directory_path() / ("peridot_test_vtu_mesh_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const auto mesh = structured_triangles({0, 0, 0}, {2, 1, 0}, 4, 2, false);
  const auto pc = mesh_points(mesh);
  std::vector<double> a(pc.size(), 1.0);
  const NamedField fields[] = {{"damage", 1, {a, {}, {}}}};
  write_vtu(dir / "mesh.vtu", pc, fields);
  const auto d = read_vtu(dir / "mesh.vtu");
  REQUIRE(d.x[0].size() == 15);
  REQUIRE(d.cells == 16);
  REQUIRE(d.connectivity.size() == 3 * 16);
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t)
    for (std::size_t a_ = 0; a_ < 3; ++a_) REQUIRE(d.connectivity[3 * t + a_] == mesh.triangles[t][a_]);
  // A plain cloud keeps one vertex cell per point.
  write_vtu(dir / "cloud.vtu", lattice(rectangle({0, 0, 0}, {1, 1, 0}), {.spacing = 0.25}), {});
  const auto c = read_vtu(dir / "cloud.vtu");
  REQUIRE(c.cells == 16);
  REQUIRE(c.connectivity.size() == 16);
  std::filesystem::remove_all(dir);
}
