#include <catch2/catch.hpp>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <unistd.h>

#include "../support/same.hpp"
import peridot.io;

using namespace peridot;

TEST_CASE("a VTU series round-trips positions and fields and lists every step in the PVD") {
  const auto dir = std::filesystem::temp_directory_path() / ("peridot_test_vtu_" + std::to_string(::getpid()));
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
  CHECK(same::difference(d.x[0], pc.x[0], "x") == "");
  CHECK(same::difference(d.x[1], pc.x[1], "y") == "");
  const auto* dmg = d.find("damage");
  REQUIRE(dmg);
  CHECK(same::difference(dmg->values, a, "damage") == "");
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
  const auto dir = std::filesystem::temp_directory_path() / ("peridot_test_vtu_trunc_" + std::to_string(::getpid()));
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

// ---- every count, offset and size in a VTU header is bounded by the file ----

namespace {

std::string slurp(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void spit(const std::filesystem::path& file, const std::string& bytes) { std::ofstream(file, std::ios::binary | std::ios::trunc) << bytes; }

// The std::runtime_error message of reading `file` ("" if it reads).
std::string refusal(const std::filesystem::path& file, bool pvd = false) {
  try {
    if (pvd) read_pvd(file);
    else read_vtu(file);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

std::string replaced(std::string s, const std::string& from, const std::string& to) {
  const auto at = s.find(from);
  REQUIRE(at != std::string::npos);
  return s.replace(at, from.size(), to);
}

struct VtuFixture {
  std::filesystem::path dir = std::filesystem::temp_directory_path() / ("peridot_test_vtu_bounds_" + std::to_string(::getpid()));
  std::string good;  // a 3 x 2 point VTU: damage at offset 0 (6 values), then Points, cells
  VtuFixture() {
    std::filesystem::create_directories(dir);
    const auto pc = lattice(rectangle({0, 0, 0}, {0.003, 0.002, 0}), {.spacing = 1e-3});
    REQUIRE(pc.size() == 6);
    std::vector<double> a(pc.size(), 0.5);
    const NamedField fields[] = {{"damage", 1, {a, {}, {}}}};
    write_vtu(dir / "good.vtu", pc, fields);
    good = slurp(dir / "good.vtu");
  }
  ~VtuFixture() { std::filesystem::remove_all(dir); }
  // The first appended byte (after the '_').
  std::size_t data() const { return good.find('_', good.find("<AppendedData")) + 1; }
  std::string with_u64(std::size_t at, std::uint64_t v) const {
    std::string s = good;
    std::memcpy(s.data() + at, &v, 8);
    return s;
  }
  std::string error(const std::string& bytes, const char* name = "x.vtu") const {
    spit(dir / name, bytes);
    return refusal(dir / name);
  }
};

}  // namespace

namespace {

// The raw bytes of the appended array `name` of a VTU written by write_vtu: after the '_' that
// opens the appended data, at its offset, a UInt64 byte count and then the bytes.
std::string appended_array(const std::filesystem::path& file, const std::string& name) {
  std::ifstream in(file, std::ios::binary);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto tag = text.find("Name=\"" + name + "\"");
  REQUIRE(tag != std::string::npos);
  const auto at = text.find("offset=\"", tag) + 8;
  const std::size_t offset = std::stoull(text.substr(at, text.find('"', at) - at));
  const auto data = text.find("<AppendedData encoding=\"raw\">");
  REQUIRE(data != std::string::npos);
  const std::size_t start = text.find('_', data) + 1 + offset;
  std::uint64_t bytes = 0;
  std::memcpy(&bytes, text.data() + start, sizeof bytes);
  REQUIRE(start + 8 + bytes <= text.size());
  return text.substr(start + 8, bytes);
}

}  // namespace

TEST_CASE("a tetrahedral mesh point cloud is written with its tetrahedra as VTK type 10 cells") {
  const auto dir = std::filesystem::temp_directory_path() / ("peridot_test_vtu_tets_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const auto mesh = structured_tetrahedra({0, 0, 0}, {1, 1, 1}, 2, 1, 1);
  const auto pc = mesh_points(mesh);
  write_vtu(dir / "tets.vtu", pc, {});
  const auto d = read_vtu(dir / "tets.vtu");
  REQUIRE(d.x[0].size() == 12);
  REQUIRE(d.cells == 12);
  REQUIRE(d.connectivity.size() == 4 * 12);
  for (std::size_t t = 0; t < mesh.tetrahedra.size(); ++t)
    for (std::size_t a = 0; a < 4; ++a) REQUIRE(d.connectivity[4 * t + a] == mesh.tetrahedra[t][a]);
  const auto types = appended_array(dir / "tets.vtu", "types");
  CHECK(types == std::string(12, char(10)));
  const auto offsets = appended_array(dir / "tets.vtu", "offsets");
  REQUIRE(offsets.size() == 12 * 8);
  std::int64_t last = 0;
  std::memcpy(&last, offsets.data() + 11 * 8, 8);
  CHECK(last == 48);
  std::filesystem::remove_all(dir);
}

TEST_CASE("a VTU block size near 2^64 is refused, not wrapped past the truncation check") {
  VtuFixture f;
  REQUIRE(refusal(f.dir / "good.vtu") == "");
  // The damage block starts at offset 0 with its UInt64 byte count: 48.
  std::uint64_t bytes = 0;
  std::memcpy(&bytes, f.good.data() + f.data(), 8);
  REQUIRE(bytes == 48);
  // 0 - 8 x floor((data + 8) / 8): data + 8 + this wraps to less than 8, which passed the old
  // check `data + offset + 8 + bytes > file size`.
  const std::uint64_t wraps = std::uint64_t(0) - 8 * ((f.data() + 8) / 8);
  for (const std::uint64_t huge : {wraps, ~std::uint64_t(0) - 7, std::uint64_t(1) << 63, std::uint64_t(f.good.size())}) {
    const auto e = f.error(f.with_u64(f.data(), huge));
    INFO(e);
    CHECK(e.find("x.vtu") != std::string::npos);
    CHECK(e.find("truncated VTU: DataArray 'damage' at offset 0 declares " + std::to_string(huge) + " bytes") != std::string::npos);
  }
  // A count that fits but is not whole values.
  CHECK(f.error(f.with_u64(f.data(), 47)).find("DataArray 'damage': 47 bytes is not a whole number of 8-byte values") != std::string::npos);
}

TEST_CASE("VTU offsets and counts past the appended data are refused, naming the attribute") {
  VtuFixture f;
  const auto offset = [&](const std::string& value) {
    return f.error(replaced(f.good, "Name=\"damage\" NumberOfComponents=\"1\" format=\"appended\" offset=\"0\"",
                            "Name=\"damage\" NumberOfComponents=\"1\" format=\"appended\" offset=\"" + value + "\""));
  };
  CHECK(offset("18446744073709551615").find("DataArray 'damage': offset = 18446744073709551615 is out of range") != std::string::npos);
  CHECK(offset("18446744073709551616").find("offset = '18446744073709551616' is not a whole number") != std::string::npos);
  CHECK(offset("-8").find("offset = '-8' is not a whole number") != std::string::npos);
  // In range of the data, but no room for the 8-byte count after it.
  const auto size = f.good.size() - f.data();
  CHECK(offset(std::to_string(size - 4)).find("has no room for its 8-byte size") != std::string::npos);
  const auto cells = f.error(replaced(f.good, "NumberOfCells=\"6\"", "NumberOfCells=\"1000000000000000\""));
  CHECK(cells.find("Piece: NumberOfCells = 1000000000000000 is out of range: at most") != std::string::npos);
  const auto points = f.error(replaced(f.good, "NumberOfPoints=\"6\"", "NumberOfPoints=\"7\""));
  CHECK(points.find("Piece NumberOfPoints = 7, but the Points array holds 6") != std::string::npos);
  const auto comps = f.error(replaced(f.good, "Name=\"damage\" NumberOfComponents=\"1\"", "Name=\"damage\" NumberOfComponents=\"4\""));
  CHECK(comps.find("DataArray 'damage': 6 values are not whole tuples of 4 components") != std::string::npos);
  const auto many = f.error(replaced(f.good, "Name=\"damage\" NumberOfComponents=\"1\"", "Name=\"damage\" NumberOfComponents=\"2147483648\""));
  CHECK(many.find("NumberOfComponents = 2147483648 is out of range: at most 9") != std::string::npos);
  const auto pair = f.error(replaced(f.good, "Name=\"damage\" NumberOfComponents=\"1\"", "Name=\"damage\" NumberOfComponents=\"2\""));
  CHECK(pair.find("point array 'damage' has 6 values; 6 points x 2 components need 12") != std::string::npos);
}

TEST_CASE("VTU connectivity must index the points") {
  VtuFixture f;
  const auto conn = f.good.find("offset=\"", f.good.find("Name=\"connectivity\""));
  REQUIRE(conn != std::string::npos);
  const auto value = f.good.substr(conn + 8, f.good.find('"', conn + 8) - conn - 8);
  const std::size_t first = f.data() + std::stoull(value) + 8;  // after its byte count
  CHECK(f.error(f.with_u64(first + 8, 6)).find("connectivity[1] = 6 is not a point index in [0, 6)") != std::string::npos);
  CHECK(f.error(f.with_u64(first, ~std::uint64_t(0))).find("connectivity[0] = -1") != std::string::npos);
}

TEST_CASE("a .pvtu lists distinct .vtu pieces, and a .pvd finite times") {
  VtuFixture f;
  const auto pvtu = [&](const std::string& sources) {
    spit(f.dir / "p.pvtu", "<VTKFile type=\"PUnstructuredGrid\">\n<PUnstructuredGrid>\n" + sources + "</PUnstructuredGrid>\n</VTKFile>\n");
    return refusal(f.dir / "p.pvtu");
  };
  CHECK(pvtu("<Piece Source=\"good.vtu\"/>\n") == "");
  // Itself (endless recursion before), a device (endless read), the same piece twice.
  CHECK(pvtu("<Piece Source=\"p.pvtu\"/>\n").find("Piece Source = 'p.pvtu': expected the name of a .vtu file") != std::string::npos);
  CHECK(pvtu("<Piece Source=\"/dev/zero\"/>\n").find("Piece Source = '/dev/zero'") != std::string::npos);
  CHECK(pvtu("<Piece Source=\"good.vtu\"/>\n<Piece Source=\"good.vtu\"/>\n").find("is listed twice") != std::string::npos);
  CHECK(refusal("/dev/zero").find("not a regular file") != std::string::npos);
  const auto pvd = [&](const std::string& time) {
    spit(f.dir / "s.pvd", "<VTKFile type=\"Collection\">\n<Collection>\n<DataSet timestep=\"" + time + "\" part=\"0\" file=\"good.vtu\"/>\n</Collection>\n</VTKFile>\n");
    return refusal(f.dir / "s.pvd", true);
  };
  CHECK(pvd("2.5e-06") == "");
  CHECK(pvd("1e999").find("DataSet 0: timestep = '1e999' is not a finite number") != std::string::npos);
  CHECK(pvd("nan").find("timestep = 'nan'") != std::string::npos);
  CHECK(pvd("").find("timestep = ''") != std::string::npos);
}
