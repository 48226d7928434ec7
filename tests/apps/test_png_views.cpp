// 3D PNG views chosen in the deck (output.png.view, axis, slice_at), run through the library.
#include <catch2/catch.hpp>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>
#include <fmt/core.h>
import peridot.run;
import peridot.render;

using namespace peridot;
namespace fs = std::filesystem;

namespace {

fs::path temp(const std::string& name) { return fs::temp_directory_path() / ("peridot_png_views_" + std::to_string(getpid()) + "_" + name); }

// A 10 x 10 x 4 mm glass block (h = 0.5 mm) with a pre-crack at y = 5 mm through the lower
// quarter of its thickness only (z < 1 mm): a mid-plane slice hardly shows it, a projection
// along z shows it whole. One VTU and one PNG of the damage at the start.
std::string block(const fs::path& dir, const std::string& png) {
  return fmt::format(R"(name: block
dimension: 3
geometry:
  body:
    box: {{min: [0, 0, 0], max: [0.01, 0.01, 0.004]}}
  cracks:
    - rectangle: {{origin: [0, 0.005, -0.001], edge1: [0.005, 0, 0], edge2: [0, 0, 0.002]}}
discretization:
  spacing: 5.0e-4
  horizon_factor: 3
material:
  youngs_modulus: 72.0e9
  density: 2440
  fracture_energy: 3.8
solver:
  end_time: 1.0e-9
output:
  directory: {}
  vtu: {{every: 1000}}
  png: {{every: 1000, width: 240, {}}}
)",
                     dir.string(), png);
}

std::vector<unsigned char> bytes_of(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace

TEST_CASE("output.png.view: projection draws the largest damage through the thickness, as the renderer draws the run's VTU") {
  const fs::path dir = temp("projection");
  fs::remove_all(dir);
  REQUIRE(run(parse_deck(block(dir, "view: projection, axis: z"), "block.yaml")).exit_status() == 0);
  const auto png = bytes_of(dir / "block_0000000.png");
  REQUIRE(!png.empty());
  // Second path: the damage the run wrote to its VTU, drawn by peridot.render with the options
  // the deck names. Equal bytes: the deck's keys reached the renderer, and nothing else differs.
  SavedField saved = read_saved_field(dir / "block_0000000.vtu", "damage");
  saved.field.spacing = 5.0e-4;
  RenderOptions projection;
  projection.width = 240;
  projection.view3d = RenderOptions::View3D::projection;
  projection.axis = 2;
  CHECK(render_png_bytes(saved.field, projection) == png);
  // The default view is the mid-plane slice: another picture of the same damage.
  RenderOptions slice;
  slice.width = 240;
  CHECK(render_png_bytes(saved.field, slice) != png);
  fs::remove_all(dir);
}

TEST_CASE("output.png.slice_at places the slice: the renderer's slice at that plane is the run's PNG") {
  const fs::path dir = temp("slice");
  fs::remove_all(dir);
  REQUIRE(run(parse_deck(block(dir, "axis: z, slice_at: 0.00025"), "block.yaml")).exit_status() == 0);
  const auto png = bytes_of(dir / "block_0000000.png");
  REQUIRE(!png.empty());
  SavedField saved = read_saved_field(dir / "block_0000000.vtu", "damage");
  saved.field.spacing = 5.0e-4;
  RenderOptions at;
  at.width = 240;
  at.slice_position = 0.00025;
  CHECK(render_png_bytes(saved.field, at) == png);
  RenderOptions mid;
  mid.width = 240;
  CHECK(render_png_bytes(saved.field, mid) != png);
  fs::remove_all(dir);
}

TEST_CASE("3D view keys are input errors naming the key: in a 2D deck, a slice outside the body, a slice of a projection") {
  const fs::path dir = temp("refused");
  const auto refusal = [&](const std::string& text) -> std::string {
    try {
      (void)parse_deck(text, "block.yaml");
    } catch (const DeckError& e) {
      return e.what();
    }
    return "accepted";
  };
  const std::string flat = R"(name: plate
dimension: 2
geometry: {body: {rectangle: {min: [0, 0], max: [0.01, 0.01]}}}
discretization: {spacing: 5.0e-4, horizon_factor: 3}
material: {youngs_modulus: 72.0e9, density: 2440, fracture_energy: 3.8}
solver: {end_time: 1.0e-9}
output: {png: {every: 1, view: projection}}
)";
  const auto e2d = refusal(flat);
  INFO(e2d);
  CHECK(e2d.find("output.png.view") != std::string::npos);
  CHECK(e2d.find("dimension = 2") != std::string::npos);
  const auto outside = refusal(block(dir, "slice_at: 0.005"));
  INFO(outside);
  CHECK(outside.find("output.png.slice_at = 0.005 m") != std::string::npos);
  CHECK(outside.find("[0, 0.004] m along z") != std::string::npos);
  const auto both = refusal(block(dir, "view: projection, slice_at: 0.001"));
  INFO(both);
  CHECK(both.find("output.png.slice_at") != std::string::npos);
  CHECK_FALSE(fs::exists(dir));
}
