// 3D outputs chosen in the deck, run through the library: PNG views (output.png.view, axis,
// slice_at) and the crack front (output.crack_front).
#include <catch2/catch.hpp>

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <map>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>
#include <fmt/core.h>
import peridot.run;
import peridot.render;
import peridot.live;

using namespace peridot;
namespace fs = std::filesystem;

namespace {

fs::path temp(const std::string& name) { return fs::temp_directory_path() / ("peridot_png_views_" + std::to_string(getpid()) + "_" + name); }

// A CSV's data rows as numbers (the header skipped).
std::vector<std::vector<double>> csv_rows(const fs::path& file) {
  std::vector<std::vector<double>> rows;
  std::ifstream in(file);
  std::string line;
  std::getline(in, line);
  while (std::getline(in, line)) {
    auto& v = rows.emplace_back();
    std::stringstream row(line);
    for (std::string cell; std::getline(row, cell, ',');) v.push_back(std::stod(cell));
  }
  return rows;
}

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

namespace {

// The block run with these output.png keys: the PNG of its start, and the damage of its VTU at
// the same step (the second path: drawn by peridot.render with options the test names).
struct Drawn {
  std::vector<unsigned char> png;
  SavedField saved;
};

Drawn run_block(const fs::path& dir, const std::string& png_keys) {
  fs::remove_all(dir);
  REQUIRE(run(parse_deck(block(dir, png_keys), "block.yaml")).exit_status() == 0);
  Drawn d{bytes_of(dir / "block_0000000.png"), read_saved_field(dir / "block_0000000.vtu", "damage")};
  REQUIRE(!d.png.empty());
  d.saved.field.spacing = 5.0e-4;
  fs::remove_all(dir);
  return d;
}

RenderOptions width_240() {
  RenderOptions o;
  o.width = 240;
  return o;
}

}  // namespace

TEST_CASE("output.png.view: projection draws the largest damage through the thickness, as the renderer draws the run's VTU") {
  const Drawn d = run_block(temp("projection"), "view: projection, axis: z");
  // Equal bytes: the deck's keys reached the renderer, and nothing else differs.
  RenderOptions projection = width_240();
  projection.view3d = RenderOptions::View3D::projection;
  projection.axis = 2;
  CHECK((render_png_bytes(d.saved.field, projection) == d.png));  // not decomposed: a failure would print every byte
  // The default view is the mid-plane slice: another picture of the same damage.
  CHECK(render_png_bytes(d.saved.field, width_240()) != d.png);
}

TEST_CASE("output.png.slice_at places the slice: the renderer's slice at that plane is the run's PNG") {
  const Drawn d = run_block(temp("slice"), "axis: z, slice_at: 0.00025");
  RenderOptions at = width_240();
  at.slice_position = 0.00025;
  CHECK((render_png_bytes(d.saved.field, at) == d.png));
  CHECK(render_png_bytes(d.saved.field, width_240()) != d.png);
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

TEST_CASE("output.crack_front writes a row per sample: the pre-crack's front in the lower layers, ending near its edge at x = 5 mm") {
  const fs::path dir = temp("front");
  fs::remove_all(dir);
  auto text = block(dir, "view: projection");
  // Threshold 0.2: a point of the second layer keeps more than half its bonds (those upward).
  text += "  crack_front: {every: 1000, axis: z, direction: [1, 0, 0], origin: [0, 0.005, 0], threshold: 0.2}\n";
  std::vector<std::string> report;
  RunOptions options;
  options.print = [&](const std::string& line) { report.push_back(line); };
  REQUIRE(Simulation(parse_deck(text, "block.yaml"), options).run().exit_status() == 0);
  std::ifstream csv(dir / "block_crack_front.csv");
  REQUIRE(csv.good());
  std::string header, first;
  std::getline(csv, header);
  std::getline(csv, first);
  CHECK(header == "step,time_s,cracked_slices,slices,length_m,mean_advance_m,max_advance_m,mean_speed_m_per_s,max_speed_m_per_s,branched_slices");
  std::vector<double> v;
  std::stringstream row(first);
  for (std::string cell; std::getline(row, cell, ',');) v.push_back(std::stod(cell));
  REQUIRE(v.size() == 10);
  CHECK(v[0] == 0);  // the start
  CHECK(v[9] == 0);  // a straight pre-crack has not branched
  CHECK(v[3] == 8);  // 4 mm / 0.5 mm layers
  // The pre-crack cuts the two layers below z = 1 mm: cracked there, not through the thickness.
  CHECK(v[2] >= 2);
  CHECK(v[2] <= 4);
  // Its front lies at the pre-crack's edge, within a horizon (1.5 mm) of x = 5 mm.
  CHECK(v[6] >= 0.005 - 0.0015);
  CHECK(v[6] <= 0.005 + 0.0015);
  bool summarised = false;
  for (const auto& line : report) summarised = summarised || line.find("crack front:") != std::string::npos;
  CHECK(summarised);

  // The front as points: one row per cracked slice, each at the pre-crack's edge (x = 5 mm,
  // within a horizon), on its plane y = 5 mm (within a spacing) and inside its own layer.
  {
    std::ifstream points(dir / "block_crack_front_points.csv");
    std::string head;
    std::getline(points, head);
    CHECK(head == "step,time_s,slice,x_m,y_m,z_m");
  }
  std::size_t at_start = 0;
  for (const auto& p : csv_rows(dir / "block_crack_front_points.csv")) {
    REQUIRE(p.size() == 6);
    if (p[0] != 0) continue;
    ++at_start;
    INFO("slice " << p[2]);
    CHECK(p[3] >= 0.005 - 0.0015);
    CHECK(p[3] <= 0.005 + 0.0015);
    CHECK(std::abs(p[4] - 0.005) <= 5e-4);
    CHECK(std::abs(p[5] - (p[2] + 0.5) * 5e-4) < 1e-9);  // the layer's points sit at its centre
    CHECK(p[5] < 0.001 + 5e-4);                           // below the pre-crack's top, within a layer
  }
  CHECK(double(at_start) == v[2]);  // as many points as cracked slices
  fs::remove_all(dir);
}

namespace {

// The block deck with a crack front and DDS every 1000 steps (the start and the end), published
// on a partition of this process's own; returns the summaries a subscriber in this process got.
std::vector<RunSummarySample> run_publishing(const fs::path& dir, bool front) {
  auto text = block(dir, "view: projection");
  if (front) text += "  crack_front: {every: 1000, axis: z, direction: [1, 0, 0], origin: [0, 0.005, 0], threshold: 0.2}\n";
  text += "  dds: {every: 1000}\n";
  RunOptions options;
  options.live.run_id = fmt::format("front-{}-{}", front, getpid());
  options.live.partition = options.live.run_id;
  options.live.config_uri = fmt::format("file://{}/data/dds/loopback.xml", PERIDOT_SOURCE_DIR);
  LiveSubscriber sub(options.live);
  REQUIRE(Simulation(parse_deck(text, "block.yaml"), options).run().exit_status() == 0);
  std::vector<RunSummarySample> got;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while ((got.empty() || got.back().status == RunStatus::running) && std::chrono::steady_clock::now() < deadline)
    for (auto& s : sub.wait_summaries(std::chrono::milliseconds(500))) got.push_back(std::move(s));
  return got;
}

}  // namespace

TEST_CASE("the 3D crack front reaches DDS as its CSV rows have it, and is NaN on DDS for a run that tracks none") {
  const fs::path dir = temp("front_dds");
  fs::remove_all(dir);
  const auto got = run_publishing(dir, true);
  // The front CSV, written from the tracker's sample by its own formatting: step -> columns.
  std::map<std::size_t, std::vector<double>> rows;
  std::ifstream csv(dir / "block_crack_front.csv");
  std::string line;
  std::getline(csv, line);
  while (std::getline(csv, line)) {
    std::vector<double> v;
    std::stringstream row(line);
    for (std::string cell; std::getline(row, cell, ',');) v.push_back(std::stod(cell));
    rows[std::size_t(v[0])] = v;
  }
  REQUIRE(rows.size() == 2);
  const auto points = csv_rows(dir / "block_crack_front_points.csv");
  REQUIRE_FALSE(points.empty());
  std::size_t matched = 0;
  for (const auto& s : got) {
    const auto it = rows.find(s.record.step);
    if (s.status != RunStatus::running || it == rows.end()) continue;
    const auto& v = it->second;  // length, mean and max advance, mean and max speed, branched: columns 4-9
    INFO("step " << s.record.step);
    CHECK(s.record.front_length == Approx(v[4]).epsilon(1e-6));
    CHECK(s.record.front_mean_advance == Approx(v[5]).epsilon(1e-6));
    CHECK(s.record.front_max_advance == Approx(v[6]).epsilon(1e-6));
    CHECK(s.record.front_max_speed == Approx(v[8]).epsilon(1e-6).margin(1e-9));
    CHECK(s.record.front_branched_slices == long(v[9]));
    // The front's points, slice by slice, as the points CSV has them; NaN for the slices it
    // has no row for.
    REQUIRE(s.front_points.size() == 3 * std::size_t(v[3]));
    std::vector<bool> listed(std::size_t(v[3]), false);
    for (const auto& p : points) {
      if (std::size_t(p[0]) != s.record.step) continue;
      const auto k = std::size_t(p[2]);
      REQUIRE(k < listed.size());
      listed[k] = true;
      for (int c = 0; c < 3; ++c) CHECK(s.front_points[3 * k + std::size_t(c)] == Approx(p[3 + std::size_t(c)]).epsilon(1e-8).margin(1e-12));
    }
    std::size_t nan_slices = 0;
    for (std::size_t k = 0; k < listed.size(); ++k) nan_slices += !listed[k] && std::isnan(s.front_points[3 * k]);
    CHECK(nan_slices + std::size_t(v[2]) == listed.size());
    ++matched;
  }
  CHECK(matched == 2);
  CHECK(rows.begin()->second[6] > 0.004);  // a real front: the pre-crack's edge near x = 5 mm
  fs::remove_all(dir);

  const fs::path plain = temp("no_front_dds");
  fs::remove_all(plain);
  const auto none = run_publishing(plain, false);
  REQUIRE_FALSE(none.empty());
  for (const auto& s : none) {
    CHECK(std::isnan(s.record.front_length));
    CHECK(std::isnan(s.record.front_max_speed));
    CHECK(s.record.front_branched_slices == -1);
    CHECK(s.front_points.empty());
  }
  fs::remove_all(plain);
}
