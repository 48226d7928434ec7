// Gmsh and OpenCV's imgcodecs (with GDAL behind it) are opened on first use, not linked: each
// would otherwise put ~100 shared libraries into every Peridot process at start-up. The
// process's own memory map is the independent witness of what was loaded.
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>
#include "../support/mapped.hpp"
import peridot.io;
import peridot.render;

using namespace peridot;

TEST_CASE("a process maps Gmsh only once it reads a mesh, and reads it right", "[io][gmsh]") {
  REQUIRE_FALSE(mapped("libgmsh"));
  const auto mesh = read_gmsh_mesh(std::filesystem::path(PERIDOT_SOURCE_DIR) / "tests/io/meshes/square.geo", 0.25);
  CHECK(mapped("libgmsh"));
  // The unit square: the triangles tile its area exactly.
  double area = 0;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) area += mesh.area(t);
  CHECK(area == Approx(1.0).epsilon(1e-12));
  CHECK(mesh.triangles.size() >= 32);
}

TEST_CASE("a process maps OpenCV's image codecs only once it writes a PNG", "[render]") {
  REQUIRE_FALSE(mapped("libopencv_imgcodecs"));
  REQUIRE_FALSE(mapped("libgdal"));
  const std::vector<double> x{0, 1, 0, 1}, y{0, 0, 1, 1}, d{0, 0.5, 1, 0.25};
  RenderField field;
  field.x = {x, y, {}};
  field.values = d;
  RenderOptions options;
  options.width = 64;
  const auto png = render_png_bytes(field, options);
  CHECK(mapped("libopencv_imgcodecs"));
  // The PNG signature (RFC 2083, 3.1).
  const std::vector<unsigned char> signature{0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  REQUIRE(png.size() > signature.size());
  CHECK(std::vector<unsigned char>(png.begin(), png.begin() + 8) == signature);
}
