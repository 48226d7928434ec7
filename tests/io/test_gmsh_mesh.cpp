#include <catch2/catch.hpp>
#include <omp.h>
#include <unistd.h>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <numbers>
#include <set>
#include <string>
#include <tuple>
#include <iterator>
#include <gmsh.h>
import peridot.io;

using namespace peridot;
namespace fs = std::filesystem;
using Catch::Contains;

namespace {

const fs::path meshes = fs::path(PERIDOT_SOURCE_DIR) / "tests/io/meshes";

struct TempDir {
  fs::path path = fs::temp_directory_path() / ("peridot_gmsh_" + std::to_string(getpid()));
  TempDir() {
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() { fs::remove_all(path); }
};

double total_area(const TriangleMesh& m) {
  double a = 0;
  for (std::size_t t = 0; t < m.triangles.size(); ++t) a += m.area(t);
  return a;
}

bool all_counter_clockwise(const TriangleMesh& m) {
  for (std::size_t t = 0; t < m.triangles.size(); ++t)
    if (!(m.area(t) > 0)) return false;
  return true;
}

// Gmsh itself meshes the .geo with its own sizes and writes it in the given format version.
void write_with_gmsh(const fs::path& geo, const fs::path& msh, double version) {
  gmsh::initialize(0, nullptr, false);
  gmsh::option::setNumber("General.Terminal", 0);
  gmsh::open(geo.string());
  gmsh::model::mesh::generate(2);
  gmsh::option::setNumber("Mesh.MshFileVersion", version);
  gmsh::write(msh.string());
  gmsh::finalize();
}

// The message of the std::invalid_argument that f throws (any other exception escapes).
std::string invalid_argument_message(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(no exception)";
}

}  // namespace

TEST_CASE("a unit square meshed at size 0.1 has area 1, counter-clockwise triangles and its named side groups") {
  const auto m = read_gmsh_mesh(meshes / "square.geo", 0.1);
  REQUIRE(m.triangles.size() > 100);
  CHECK(std::abs(total_area(m) - 1.0) < 1e-12);
  CHECK(all_counter_clockwise(m));
  CHECK(m.mean_edge() == Approx(0.1).epsilon(0.2));
  for (const auto* g : {"left", "right", "bottom", "top", "body"}) CHECK(m.groups.count(g) == 1);
  for (auto i : m.groups.at("left")) CHECK(m.nodes[std::size_t(i)][0] == 0.0);
  for (auto i : m.groups.at("right")) CHECK(m.nodes[std::size_t(i)][0] == 1.0);
  for (auto i : m.groups.at("bottom")) CHECK(m.nodes[std::size_t(i)][1] == 0.0);
  for (auto i : m.groups.at("top")) CHECK(m.nodes[std::size_t(i)][1] == 1.0);
  // A side of length 1 at size 0.1 has 11 nodes, its two corners included.
  CHECK(m.groups.at("left").size() == 11);
  CHECK(m.groups.at("body").size() == m.nodes.size());
  for (const auto& [name, g] : m.groups) CHECK(std::is_sorted(g.begin(), g.end()));
}

TEST_CASE("nodes no triangle uses are dropped and the others are numbered 0..n-1 with z = 0") {
  const auto m = read_gmsh_mesh(meshes / "square.geo");
  std::set<std::int32_t> used;
  for (const auto& t : m.triangles) used.insert(t.begin(), t.end());
  CHECK(used.size() == m.nodes.size());
  CHECK(*used.rbegin() == std::int32_t(m.nodes.size()) - 1);
  // The free geometry point (2, 2) is gone, and with it every node of the group "far".
  CHECK(m.bounds().hi == Vec3{1, 1, 0});
  CHECK(m.groups.at("far").empty());
  for (const auto& p : m.nodes) CHECK(p[2] == 0.0);
}

TEST_CASE("a plate with a hole has the rectangle's area less the inscribed polygon's, and no node inside the hole") {
  const double r = 0.25, exact = 2.0 - std::numbers::pi * r * r;
  const auto m = read_gmsh_mesh(meshes / "plate_hole.geo", r / 10);
  CHECK(all_counter_clockwise(m));
  // The hole is a polygon inscribed in the circle, so the mesh has slightly more material.
  const double area = total_area(m);
  CHECK(area > exact);
  CHECK(area < exact * 1.01);
  for (const auto& p : m.nodes) CHECK(std::hypot(p[0] - 1, p[1] - 0.5) > r * (1 - 1e-9));
  REQUIRE(m.groups.count("hole") == 1);
  CHECK(m.groups.at("hole").size() > 50);
  for (auto i : m.groups.at("hole"))
    CHECK(std::hypot(m.nodes[std::size_t(i)][0] - 1, m.nodes[std::size_t(i)][1] - 0.5) == Approx(r).epsilon(1e-9));
  // Unnamed groups: Physical Curve(11) is the left side, Physical Surface(12) the body.
  REQUIRE(m.groups.count("1d_group11") == 1);
  for (auto i : m.groups.at("1d_group11")) CHECK(m.nodes[std::size_t(i)][0] == 0.0);
  REQUIRE(m.groups.count("group12") == 1);
  CHECK(m.groups.at("group12").size() == m.nodes.size());
}

TEST_CASE("a surface meshed with normal -z comes out with every triangle counter-clockwise") {
  const auto m = read_gmsh_mesh(meshes / "clockwise.geo");
  REQUIRE(!m.triangles.empty());
  CHECK(all_counter_clockwise(m));
  CHECK(std::abs(total_area(m) - 1.0) < 1e-12);
}

TEST_CASE("the same mesh written by Gmsh as .msh v2.2 and v4.1 reads back identical to the .geo") {
  TempDir tmp;
  const auto geo = read_gmsh_mesh(meshes / "plate_hole.geo");
  for (double version : {2.2, 4.1}) {
    const auto msh = tmp.path / ("plate_hole_v" + std::to_string(int(version)) + ".msh");
    write_with_gmsh(meshes / "plate_hole.geo", msh, version);
    const auto m = read_gmsh_mesh(msh);
    INFO("version " << version);
    REQUIRE(m.nodes.size() == geo.nodes.size());
    CHECK(m.triangles.size() == geo.triangles.size());
    // Gmsh writes 16 significant digits, one short of a round trip.
    double moved = 0;
    for (std::size_t i = 0; i < m.nodes.size(); ++i)
      moved = std::max({moved, std::abs(m.nodes[i][0] - geo.nodes[i][0]), std::abs(m.nodes[i][1] - geo.nodes[i][1])});
    CHECK(moved < 1e-14);
    CHECK((m.triangles == geo.triangles));
    CHECK((m.groups == geo.groups));
  }
}

TEST_CASE("a smaller mesh size gives more nodes, and each read starts from Gmsh's defaults") {
  const auto file = meshes / "square.geo";
  const auto own = read_gmsh_mesh(file);
  const auto coarse = read_gmsh_mesh(file, 0.2), fine = read_gmsh_mesh(file, 0.05);
  CHECK(coarse.nodes.size() < own.nodes.size());
  CHECK(own.nodes.size() < fine.nodes.size());
  CHECK(coarse.mean_edge() == Approx(0.2).epsilon(0.2));
  CHECK(fine.mean_edge() == Approx(0.05).epsilon(0.2));
  // No size option of the previous call lingers.
  CHECK(read_gmsh_mesh(file).nodes == own.nodes);
}

TEST_CASE("a bad file or mesh size throws std::invalid_argument naming the file and the reason") {
  TempDir tmp;
  const auto message = [](const fs::path& file, double size = 0) {
    return invalid_argument_message([&] { read_gmsh_mesh(file, size); });
  };
  const auto missing = tmp.path / "missing.msh";
  CHECK_THAT(message(missing), Contains(missing.string()) && Contains("no such file"));
  const auto garbage = meshes / "garbage.msh";
  CHECK_THAT(message(garbage), Contains(garbage.string()) && Contains("Gmsh cannot read it"));
  const auto quad = meshes / "quad.msh";
  CHECK_THAT(message(quad), Contains(quad.string()) && Contains("mixed element types") && Contains("Quadrilateral") &&
                                Contains("only linear 3-node triangles are supported"));
  const auto quadratic = meshes / "second_order.geo";
  CHECK_THAT(message(quadratic), Contains(quadratic.string()) && Contains("mixed element types") && Contains("Triangle 6"));
  const auto inverted = meshes / "inverted.msh";
  CHECK_THAT(message(inverted), Contains(inverted.string()) && Contains("inverted element 12"));
  const auto square = meshes / "square.geo";
  CHECK_THAT(message(square, -0.1), Contains(square.string()) && Contains("mesh size"));
  const auto curves = meshes / "curves_only.geo";
  CHECK_THAT(message(curves), Contains(curves.string()) && Contains("no triangles"));
  const auto tilted = meshes / "tilted.geo";
  CHECK_THAT(message(tilted), Contains(tilted.string()) && Contains("not planar"));
}

TEST_CASE("a file Gmsh cannot parse leaves Gmsh able to read the next file") {
  CHECK_THROWS_AS(read_gmsh_mesh(meshes / "garbage.msh"), std::invalid_argument);
  const auto m = read_gmsh_mesh(meshes / "square.geo");
  CHECK(std::abs(total_area(m) - 1.0) < 1e-12);
}

namespace {

double total_volume(const TetMesh& m) {
  double v = 0;
  for (std::size_t t = 0; t < m.tetrahedra.size(); ++t) v += m.volume(t);
  return v;
}

bool all_positive(const TetMesh& m) {
  for (std::size_t t = 0; t < m.tetrahedra.size(); ++t)
    if (!(m.volume(t) > 0)) return false;
  return true;
}

// cube_kuhn.msh with its text edited.
fs::path edited_cube(const TempDir& tmp, const std::string& name, const std::string& from, const std::string& to) {
  std::ifstream in(meshes / "cube_kuhn.msh");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto at = text.find(from);
  REQUIRE(at != std::string::npos);
  text.replace(at, from.size(), to);
  std::ofstream(tmp.path / name) << text;
  return tmp.path / name;
}

}  // namespace

TEST_CASE("a unit cube of six tetrahedra reads as 8 nodes and volume 1, with its face and volume groups") {
  const auto m = read_gmsh_tet_mesh(meshes / "cube_kuhn.msh");
  REQUIRE(m.nodes.size() == 8);
  REQUIRE(m.tetrahedra.size() == 6);
  CHECK(all_positive(m));
  CHECK(std::abs(total_volume(m) - 1.0) < 1e-15);
  REQUIRE(m.groups.contains("left"));
  CHECK(m.groups.at("left").size() == 4);
  for (auto v : m.groups.at("left")) CHECK(m.nodes[std::size_t(v)][0] == 0.0);
  CHECK(m.groups.at("solid").size() == 8);
}

TEST_CASE("a volume whose tetrahedra all run the other way is flipped, and one odd tetrahedron is an inverted element") {
  TempDir tmp;
  // Every tetrahedron's first two nodes swapped: all negative, so the volume is flipped whole.
  std::ifstream in(meshes / "cube_kuhn.msh");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  for (const auto& [from, to] : std::map<std::string, std::string>{{" 1 2 4 8", " 2 1 4 8"}, {" 1 3 7 8", " 3 1 7 8"}, {" 1 5 6 8", " 5 1 6 8"},
                                                                  {" 1 6 2 8", " 6 1 2 8"}, {" 1 7 5 8", " 7 1 5 8"}, {" 1 4 3 8", " 4 1 3 8"}})
    text.replace(text.find(from), from.size(), to);
  std::ofstream(tmp.path / "negative.msh") << text;
  const auto m = read_gmsh_tet_mesh(tmp.path / "negative.msh");
  CHECK(all_positive(m));
  CHECK(std::abs(total_volume(m) - 1.0) < 1e-15);
  // One of six swapped: the minority orientation is the inverted one.
  const auto odd = edited_cube(tmp, "odd.msh", "5 4 2 2 1 1 5 6 8", "5 4 2 2 1 5 1 6 8");
  CHECK_THAT(invalid_argument_message([&] { read_gmsh_tet_mesh(odd); }),
             Contains(odd.string()) && Contains("inverted element 5") && Contains("other tetrahedra of volume 1"));
}

TEST_CASE("a tetrahedral .geo reads with the volume of its slab, positive tetrahedra and its named groups, also written as .msh v2.2 and v4.1") {
  TempDir tmp;
  const auto geo = read_gmsh_tet_mesh(meshes / "slab.geo");
  REQUIRE(geo.tetrahedra.size() > 100);
  CHECK(all_positive(geo));
  CHECK(std::abs(total_volume(geo) - 0.125) < 1e-14);
  for (const auto& [name, axis, side] : {std::tuple{"back", 2, 0.0}, {"front", 2, 0.25}, {"left", 0, 0.0}}) {
    INFO(name);
    REQUIRE(geo.groups.contains(name));
    for (auto v : geo.groups.at(name)) CHECK(std::abs(geo.nodes[std::size_t(v)][std::size_t(axis)] - side) < 1e-15);
  }
  CHECK(geo.groups.at("solid").size() == geo.nodes.size());
  for (double version : {2.2, 4.1}) {
    INFO("version " << version);
    const auto msh = tmp.path / ("slab_v" + std::to_string(int(version)) + ".msh");
    gmsh::initialize(0, nullptr, false);
    gmsh::option::setNumber("General.Terminal", 0);
    gmsh::open((meshes / "slab.geo").string());
    gmsh::model::mesh::generate(3);
    gmsh::option::setNumber("Mesh.MshFileVersion", version);
    gmsh::write(msh.string());
    gmsh::finalize();
    const auto m = read_gmsh_tet_mesh(msh);
    REQUIRE(m.nodes.size() == geo.nodes.size());
    CHECK((m.tetrahedra == geo.tetrahedra));
    CHECK((m.groups == geo.groups));
  }
}

TEST_CASE("write_gmsh_mesh writes the mesh read_gmsh_mesh makes of a .geo at a size, which reads back the same in 2D and 3D") {
  TempDir tmp;
  {
    const auto geo = read_gmsh_mesh(meshes / "plate_hole.geo", 0.08);
    const auto msh = tmp.path / "plate_hole.msh";
    REQUIRE(write_gmsh_mesh(meshes / "plate_hole.geo", 0.08, 2, msh) == geo.nodes.size());
    // The sizes are the deck's, not the file's (0.05): fewer nodes than the file's own mesh.
    CHECK(geo.nodes.size() < read_gmsh_mesh(meshes / "plate_hole.geo").nodes.size());
    const auto m = read_gmsh_mesh(msh);
    REQUIRE(m.nodes.size() == geo.nodes.size());
    double moved = 0;  // Gmsh writes 16 significant digits, one short of a round trip
    for (std::size_t i = 0; i < m.nodes.size(); ++i)
      moved = std::max({moved, std::abs(m.nodes[i][0] - geo.nodes[i][0]), std::abs(m.nodes[i][1] - geo.nodes[i][1])});
    CHECK(moved < 1e-14);
    CHECK((m.triangles == geo.triangles));
    CHECK((m.groups == geo.groups));
  }
  {
    const auto geo = read_gmsh_tet_mesh(meshes / "slab.geo");
    const auto msh = tmp.path / "slab.msh";
    REQUIRE(write_gmsh_mesh(meshes / "slab.geo", 0, 3, msh) == geo.nodes.size());
    const auto m = read_gmsh_tet_mesh(msh);
    REQUIRE(m.nodes.size() == geo.nodes.size());
    CHECK((m.tetrahedra == geo.tetrahedra));
    CHECK((m.groups == geo.groups));
  }
  // Nothing is written for a file that cannot be meshed; a directory that is missing is named.
  CHECK_THAT(invalid_argument_message([&] { write_gmsh_mesh(meshes / "missing.geo", 0, 2, tmp.path / "x.msh"); }), Contains("no such file"));
  CHECK_FALSE(fs::exists(tmp.path / "x.msh"));
  try {
    write_gmsh_mesh(meshes / "plate_hole.geo", 0.08, 2, tmp.path / "no_such_dir" / "x.msh");
    FAIL("no exception");
  } catch (const std::runtime_error& e) {
    CHECK_THAT(e.what(), Contains((tmp.path / "no_such_dir" / "x.msh").string()));
  }
}

TEST_CASE("a 2D file read as 3D, a 3D file read as 2D and mixed 3D elements are refused naming the file") {
  TempDir tmp;
  const auto square = meshes / "square.geo";
  CHECK_THAT(invalid_argument_message([&] { read_gmsh_tet_mesh(square); }), Contains(square.string()) && Contains("no tetrahedra"));
  const auto cube = meshes / "cube_kuhn.msh";
  CHECK_THAT(invalid_argument_message([&] { read_gmsh_mesh(cube); }),
             Contains(cube.string()) && Contains("3D elements (Tetrahedron 4)") && Contains("not a 2D one"));
  // A hexahedron (Gmsh type 5) beside the tetrahedra.
  const auto mixed = edited_cube(tmp, "mixed.msh", "8\n1 2 2", "9\n9 5 2 2 1 1 2 3 4 5 6 7 8\n1 2 2");
  CHECK_THAT(invalid_argument_message([&] { read_gmsh_tet_mesh(mixed); }),
             Contains(mixed.string()) && Contains("mixed element types") && Contains("Hexahedron 8") &&
                 Contains("only linear 4-node tetrahedra are supported"));
}

namespace {

// Gmsh meshes `geo` in `dim` and writes it as .msh `version`; save_all: every element, also
// those in no physical group (entities Peridot then names by their tags).
void write_msh(const fs::path& geo, const fs::path& msh, int dim, double version, bool save_all) {
  gmsh::initialize(0, nullptr, false);
  gmsh::option::setNumber("General.Terminal", 0);
  gmsh::open(geo.string());
  gmsh::model::mesh::generate(dim);
  gmsh::option::setNumber("Mesh.MshFileVersion", version);
  gmsh::option::setNumber("Mesh.SaveAll", save_all ? 1 : 0);
  gmsh::write(msh.string());
  gmsh::finalize();
}

// Both readers' result on one file: the mesh, or the error message.
template <class Read>
std::string outcome(const Read& read) {
  try {
    read();
    return "read";
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
}

}  // namespace

TEST_CASE("Peridot's .msh reader gives Gmsh's mesh of the same file bit for bit: v2.2 and v4.1, 2D and 3D, groups, flipped and refused files") {
  TempDir tmp;
  std::vector<fs::path> files2, files3;
  for (const std::string geo : {"square", "plate_hole", "clockwise", "tilted", "second_order"})
    for (double version : {2.2, 4.1})
      for (bool all : {false, true}) {
        files2.push_back(tmp.path / (geo + "_v" + std::to_string(int(version)) + (all ? "_all.msh" : "_groups.msh")));
        write_msh(meshes / (geo + ".geo"), files2.back(), 2, version, all);
      }
  for (double version : {2.2, 4.1})
    for (bool all : {false, true}) {
      files3.push_back(tmp.path / ("slab_v" + std::to_string(int(version)) + (all ? "_all.msh" : "_groups.msh")));
      write_msh(meshes / "slab.geo", files3.back(), 3, version, all);
    }
  for (const std::string name : {"quad.msh", "inverted.msh"}) files2.push_back(meshes / name);
  files3.push_back(meshes / "cube_kuhn.msh");
  files3.push_back(files2.front());  // a 2D file read as 3D
  std::size_t read = 0;
  // Both readers on each file: the same outcome, and where both read it, the same mesh.
  const auto compare = [&](const std::vector<fs::path>& files, const auto& read_with, const auto& elements) {
    for (const auto& f : files) {
      INFO(f.filename().string());
      const auto mine = outcome([&] { return read_with(f, MshReader::peridot); });
      const auto gmsh_s = outcome([&] { return read_with(f, MshReader::gmsh); });
      CHECK(mine == gmsh_s);
      if (mine != "read" || gmsh_s != "read") continue;
      const auto a = read_with(f, MshReader::peridot), b = read_with(f, MshReader::gmsh);
      ++read;
      CHECK((a.nodes == b.nodes));
      CHECK((elements(a) == elements(b)));
      CHECK((a.groups == b.groups));
    }
  };
  compare(files2, [](const fs::path& f, MshReader r) { return read_gmsh_mesh(f, 0, {}, r); }, [](const TriangleMesh& m) { return m.triangles; });
  compare(files3, [](const fs::path& f, MshReader r) { return read_gmsh_tet_mesh(f, 0, {}, r); }, [](const TetMesh& m) { return m.tetrahedra; });
  CHECK(read >= 14);  // the refused ones aside, every file was compared
}

// Gmsh's initialize() sets the caller's OpenMP thread count to 1: a run that meshed a .geo then
// stepped on one thread whatever --threads said.
TEST_CASE("meshing a .geo with Gmsh leaves the process's OpenMP thread count as it was") {
  const int before = omp_get_max_threads();
  omp_set_num_threads(3);
  const auto m = read_gmsh_mesh(meshes / "square.geo", 0.1);
  CHECK(!m.triangles.empty());
  CHECK(omp_get_max_threads() == 3);
  const auto t = read_gmsh_tet_mesh(meshes / "slab.geo");
  CHECK(!t.tetrahedra.empty());
  CHECK(omp_get_max_threads() == 3);
  omp_set_num_threads(before);
}
