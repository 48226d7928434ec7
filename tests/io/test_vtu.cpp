#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <string>
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
