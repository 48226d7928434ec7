#include <catch2/catch.hpp>
#include <unistd.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <array>
#include <barrier>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <span>
#include <string>
#include <thread>
#include <vector>
#include "../support/same.hpp"
import peridot.render;
import peridot.models;

using namespace peridot;
namespace fs = std::filesystem;

namespace {

// Where tests leave their images, for a person to look at.
fs::path out_dir() {
  const fs::path d = fs::path(PERIDOT_BINARY_DIR) / "tests" / "render" / "images";
  fs::create_directories(d);
  return d;
}

// A point cloud with a nodal field, owning the arrays a RenderField views.
struct Sample {
  PointCloud pc;
  std::vector<double> values;
  VectorField u;
  RenderField field(std::string name = "damage") const {
    RenderField f;
    f.dim = pc.dim;
    f.x = {pc.x[0], pc.x[1], pc.x[2]};
    if (!u[0].empty()) f.u = {u[0], u[1], u[2]};
    f.values = values;
    f.field_name = std::move(name);
    f.time = 1.25e-5;
    f.step = 125;
    return f;
  }
};

Sample plate(double w, double h, double spacing) {
  Sample s;
  s.pc = lattice(rectangle({0, 0, 0}, {w, h, 0}), {.spacing = spacing});
  s.values.assign(s.pc.size(), 0.0);
  return s;
}

cv::Mat decode(const std::vector<unsigned char>& png) {
  cv::Mat img = cv::imdecode(png, cv::IMREAD_COLOR);
  REQUIRE_FALSE(img.empty());
  return img;
}

cv::Vec3b pixel(const cv::Mat& img, const RenderLayout& L, double a, double b) {
  const auto p = L.to_pixel(a, b);
  return img.at<cv::Vec3b>(int(std::floor(p[1])), int(std::floor(p[0])));
}

int colour_distance(cv::Vec3b a, cv::Vec3b b) {
  return std::abs(a[0] - b[0]) + std::abs(a[1] - b[1]) + std::abs(a[2] - b[2]);
}

bool is_background(cv::Vec3b c) { return c == cv::Vec3b(255, 255, 255); }

// Bounding box of the non-background pixels inside the plot area, found by scanning the image.
cv::Rect drawn_body(const cv::Mat& img, const RenderLayout& L) {
  int x0 = img.cols, y0 = img.rows, x1 = -1, y1 = -1;
  for (int r = L.plot_y; r < L.plot_y + L.plot_h; ++r)
    for (int c = L.plot_x; c < L.plot_x + L.plot_w; ++c)
      if (!is_background(img.at<cv::Vec3b>(r, c))) {
        x0 = std::min(x0, c), x1 = std::max(x1, c);
        y0 = std::min(y0, r), y1 = std::max(y1, r);
      }
  REQUIRE(x1 >= x0);
  return {x0, y0, x1 - x0 + 1, y1 - y0 + 1};
}

// Colours the colorbar shows at its top (vmax) and bottom (vmin).
cv::Vec3b bar_top(const cv::Mat& img, const RenderLayout& L) { return img.at<cv::Vec3b>(L.bar_y, L.bar_x + L.bar_w / 2); }
cv::Vec3b bar_bottom(const cv::Mat& img, const RenderLayout& L) {
  return img.at<cv::Vec3b>(L.bar_y + L.bar_h - 1, L.bar_x + L.bar_w / 2);
}

}  // namespace

TEST_CASE("the PNG decodes with OpenCV at the requested width and the height the aspect ratio gives") {
  const auto s = plate(0.2, 0.1, 0.002);
  const fs::path file = out_dir() / "size_640x0.png";
  const RenderOptions auto_height{.width = 640};
  render_png(file, s.field(), auto_height);
  const cv::Mat img = cv::imread(file.string(), cv::IMREAD_COLOR);
  REQUIRE_FALSE(img.empty());
  REQUIRE(img.cols == 640);
  REQUIRE(img.rows == render_layout(s.field(), auto_height).height);
  // A 2:1 plate: the plot is half as tall as wide, plus bands for title and scale bar.
  const auto L = render_layout(s.field(), auto_height);
  REQUIRE(std::abs(L.plot_h - L.plot_w / 2) <= 1);
  REQUIRE(img.rows < img.cols);

  const fs::path fixed = out_dir() / "size_640x480.png";
  render_png(fixed, s.field(), {.width = 640, .height = 480});
  const cv::Mat img2 = cv::imread(fixed.string(), cv::IMREAD_COLOR);
  REQUIRE(img2.cols == 640);
  REQUIRE(img2.rows == 480);
}

TEST_CASE("a damaged block is drawn in the colorbar's top colour and intact material in its bottom colour") {
  auto s = plate(0.2, 0.1, 0.002);
  for (std::size_t i = 0; i < s.pc.size(); ++i) {
    const auto p = s.pc.position(i);
    if (p[0] > 0.08 && p[0] < 0.12 && p[1] > 0.04 && p[1] < 0.06) s.values[i] = 1.0;
  }
  const RenderOptions o{.width = 800};
  const cv::Mat img = decode(render_png_bytes(s.field(), o));
  const auto L = render_layout(s.field(), o);
  const auto damaged = pixel(img, L, 0.10, 0.05), intact = pixel(img, L, 0.03, 0.03);
  REQUIRE(colour_distance(damaged, intact) > 150);
  REQUIRE(colour_distance(damaged, bar_top(img, L)) <= 3);
  REQUIRE(colour_distance(intact, bar_bottom(img, L)) <= 3);
  // Every corner of the block, just inside it, is damaged colour; just outside, intact.
  for (double x : {0.0815, 0.1185})
    for (double y : {0.0415, 0.0585}) REQUIRE(colour_distance(pixel(img, L, x, y), damaged) <= 3);
  REQUIRE(colour_distance(pixel(img, L, 0.0785, 0.05), intact) <= 3);
  REQUIRE(colour_distance(pixel(img, L, 0.10, 0.0615), intact) <= 3);
}

TEST_CASE("the drawn body is solid and keeps the plate's aspect ratio with the same pixels per metre in x and y") {
  const auto s = plate(0.2, 0.1, 0.002);
  // Widths chosen so that a spacing covers a fractional number of pixels.
  for (const RenderOptions& o : {RenderOptions{.width = 900}, RenderOptions{.width = 1237, .height = 300},
                                 RenderOptions{.width = 500, .height = 900}}) {
    const cv::Mat img = decode(render_png_bytes(s.field(), o));
    const cv::Rect body = drawn_body(img, render_layout(s.field(), o));
    CAPTURE(o.width, o.height, body.width, body.height);
    REQUIRE(std::abs(body.width - 2 * body.height) <= 3);
    // Solid: squares of side h leave no background pixel inside the body.
    int holes = 0;
    for (int r = body.y; r < body.y + body.height; ++r)
      for (int c = body.x; c < body.x + body.width; ++c) holes += is_background(img.at<cv::Vec3b>(r, c));
    REQUIRE(holes == 0);
  }
}

TEST_CASE("deformed mode draws x + magnification * u") {
  auto s = plate(0.2, 0.1, 0.002);
  s.u = zero_field(s.pc.size());
  SECTION("a translation moves the drawn body by magnification times the displacement") {
    for (auto& v : s.u[1]) v = 0.05;  // half the plate's height, doubled by the magnification
    const RenderOptions ref{.width = 800}, def{.width = 800, .deformed = true, .magnification = 2};
    const cv::Mat a = decode(render_png_bytes(s.field(), ref)), b = decode(render_png_bytes(s.field(), def));
    const auto La = render_layout(s.field(), ref), Lb = render_layout(s.field(), def);
    REQUIRE_FALSE(is_background(pixel(a, La, 0.1, 0.05)));
    REQUIRE(is_background(pixel(b, Lb, 0.1, 0.03)));       // where the body was
    REQUIRE_FALSE(is_background(pixel(b, Lb, 0.1, 0.13)));  // where it is now
    const cv::Rect ba = drawn_body(a, La), bb = drawn_body(b, Lb);
    // The frame fits the reference and the deformed body: twice the plate's height.
    REQUIRE(std::abs(bb.width - 2 * bb.height) <= 3);
    REQUIRE(bb.height <= Lb.plot_h / 2 + 2);
    REQUIRE(std::abs(double(ba.width) / ba.height - double(bb.width) / bb.height) < 0.05);
  }
  SECTION("a uniform stretch widens the drawn body by 1 + magnification * strain") {
    for (std::size_t i = 0; i < s.pc.size(); ++i) s.u[0][i] = 0.25 * s.pc.x[0][i];
    const RenderOptions def{.width = 800, .deformed = true, .magnification = 4};  // stretch 1 + 4 * 0.25 = 2
    const cv::Mat img = decode(render_png_bytes(s.field(), def));
    const cv::Rect body = drawn_body(img, render_layout(s.field(), def));
    CAPTURE(body.width, body.height);
    REQUIRE(std::abs(body.width - 4 * body.height) <= 6);
  }
  SECTION("magnification 0 draws the reference configuration") {
    for (std::size_t i = 0; i < s.pc.size(); ++i) s.u[0][i] = 0.25 * s.pc.x[0][i];
    const RenderOptions ref{.width = 600}, def{.width = 600, .deformed = true, .magnification = 0};
    const cv::Mat a = decode(render_png_bytes(s.field(), ref)), b = decode(render_png_bytes(s.field(), def));
    const auto L = render_layout(s.field(), ref);
    const cv::Rect plot(L.plot_x, L.plot_y, L.plot_w, L.plot_h);
    REQUIRE(cv::norm(a(plot), b(plot), cv::NORM_L1) == 0);
  }
}

TEST_CASE("a 3D body renders as a slice through the chosen plane or as a projection with the largest value in front") {
  Sample s;
  s.pc = lattice(box({0, 0, 0}, {0.1, 0.05, 0.04}), {.spacing = 0.005});
  s.values.resize(s.pc.size());
  for (std::size_t i = 0; i < s.pc.size(); ++i) s.values[i] = s.pc.x[2][i] > 0.02 ? 1.0 : 0.0;  // upper half damaged
  const RenderField f = s.field();

  const RenderOptions low{.width = 600, .slice_position = 0.0075}, high{.width = 600, .slice_position = 0.0325};
  const cv::Mat a = decode(render_png_bytes(f, low)), b = decode(render_png_bytes(f, high));
  const auto La = render_layout(f, low), Lb = render_layout(f, high);
  REQUIRE(La.drawn == 20 * 10);  // one layer of 20 x 10 points
  REQUIRE(colour_distance(pixel(a, La, 0.05, 0.025), bar_bottom(a, La)) <= 3);
  REQUIRE(colour_distance(pixel(b, Lb, 0.05, 0.025), bar_top(b, Lb)) <= 3);
  REQUIRE(std::abs(drawn_body(a, La).width - 2 * drawn_body(a, La).height) <= 3);

  const RenderOptions proj{.width = 600, .view3d = RenderOptions::View3D::projection};
  const cv::Mat c = decode(render_png_bytes(f, proj));
  const auto Lc = render_layout(f, proj);
  REQUIRE(Lc.drawn == s.pc.size());
  REQUIRE(colour_distance(pixel(c, Lc, 0.05, 0.025), bar_top(c, Lc)) <= 3);

  // Looking along x shows the y-z plane: 0.05 x 0.04, damage in the upper half.
  const RenderOptions side{.width = 600, .axis = 0};
  const cv::Mat d = decode(render_png_bytes(f, side));
  const auto Ld = render_layout(f, side);
  REQUIRE(Ld.axes == std::array<int, 2>{1, 2});
  const cv::Rect body = drawn_body(d, Ld);
  REQUIRE(std::abs(body.width * 0.04 - body.height * 0.05) <= 4 * 0.05);
  REQUIRE(colour_distance(pixel(d, Ld, 0.025, 0.03), bar_top(d, Ld)) <= 3);
  REQUIRE(colour_distance(pixel(d, Ld, 0.025, 0.01), bar_bottom(d, Ld)) <= 3);
  render_png(out_dir() / "box_slice_x.png", f, side);
}

TEST_CASE("NaN field values are drawn in a grey that no colormap entry has") {
  auto s = plate(0.2, 0.1, 0.002);
  for (std::size_t i = 0; i < s.pc.size(); ++i)
    if (s.pc.x[0][i] > 0.15) s.values[i] = std::numeric_limits<double>::quiet_NaN();
  const RenderOptions o{.width = 600};
  const cv::Mat img = decode(render_png_bytes(s.field("stress"), o));
  const auto L = render_layout(s.field("stress"), o);
  const auto grey = pixel(img, L, 0.18, 0.05);
  REQUIRE(L.has_nan);
  REQUIRE(grey[0] == grey[1]);
  REQUIRE(grey[1] == grey[2]);
  REQUIRE_FALSE(is_background(grey));
  REQUIRE(colour_distance(grey, pixel(img, L, 0.05, 0.05)) > 60);
}

TEST_CASE("rendering works with DISPLAY unset and never loads OpenCV's GUI module", "[headless]") {
  unsetenv("DISPLAY");
  REQUIRE(std::getenv("DISPLAY") == nullptr);
  const auto s = plate(0.1, 0.1, 0.005);
  // ctest runs this case twice (once with DISPLAY removed by ctest), possibly at once: a name per process.
  const fs::path file = out_dir() / ("headless_" + std::to_string(getpid()) + ".png");
  render_png(file, s.field(), {.width = 320});
  REQUIRE(cv::imread(file.string()).cols == 320);
  fs::remove(file);
  std::ifstream maps("/proc/self/maps");
  if (maps) {
    const std::string all{std::istreambuf_iterator<char>(maps), {}};
    REQUIRE(all.find("opencv_highgui") == std::string::npos);
    REQUIRE(all.find("opencv_imgcodecs") != std::string::npos);  // the check can see OpenCV at all
  }
}

TEST_CASE("bad fields and options are rejected with messages naming the culprit and its allowed range") {
  auto s = plate(0.02, 0.01, 0.002);
  const RenderField good = s.field();
  auto message_of = [&](const RenderField& f, const RenderOptions& o) {
    try {
      (void)render_png_bytes(f, o);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    FAIL("no std::invalid_argument thrown");
    return std::string();
  };
  using Catch::Matchers::Contains;
  REQUIRE_THAT(message_of(good, {.width = 8}), Contains("width") && Contains("[16, 16384]"));
  REQUIRE_THAT(message_of(good, {.height = 20000}), Contains("height") && Contains("16384"));
  REQUIRE_THAT(message_of(good, {.magnification = -1}), Contains("magnification") && Contains(">= 0"));
  REQUIRE_THAT(message_of(good, {.vmin = 1.0, .vmax = 0.5}), Contains("vmin") && Contains("vmax"));
  REQUIRE_THAT(message_of(good, {.deformed = true}), Contains("field.u"));
  REQUIRE_THAT(message_of(good, {.point_size = -0.1}), Contains("point_size"));
  REQUIRE_THAT(message_of(good, {.axis = 0}), Contains("axis"));

  RenderField short_values = good;
  short_values.values = short_values.values.first(3);
  REQUIRE_THAT(message_of(short_values, {}), Contains("values") && Contains("damage"));

  RenderField bad_dim = good;
  bad_dim.dim = 4;
  REQUIRE_THAT(message_of(bad_dim, {}), Contains("dim") && Contains("2 or 3"));

  std::vector<double> x0(good.x[0].begin(), good.x[0].end());
  x0[5] = std::numeric_limits<double>::quiet_NaN();
  RenderField nan_position = good;
  nan_position.x[0] = x0;
  REQUIRE_THAT(message_of(nan_position, {}), Contains("x[0][5]") && Contains("finite"));

  s.u = zero_field(s.pc.size());
  s.u[1][7] = std::numeric_limits<double>::infinity();
  REQUIRE_THAT(message_of(s.field(), {.deformed = true}), Contains("u[1][7]"));
  REQUIRE_NOTHROW(render_png_bytes(s.field(), {.deformed = false}));  // u is only used when deformed

  Sample cube;
  cube.pc = lattice(box({0, 0, 0}, {0.01, 0.01, 0.01}), {.spacing = 0.002});
  cube.values.assign(cube.pc.size(), 0.0);
  REQUIRE_THAT(message_of(cube.field(), {.slice_position = 0.5}), Contains("slice_position") && Contains("spans"));
  REQUIRE_THAT(message_of(cube.field(), {.axis = 3}), Contains("axis") && Contains("0, 1 or 2"));
}

TEST_CASE("an unwritable path gives a runtime error naming it and leaves no temporary file") {
  const auto s = plate(0.02, 0.01, 0.002);
  const fs::path missing = out_dir() / "no_such_dir" / "x.png";
  REQUIRE_THROWS_WITH(render_png(missing, s.field()), Catch::Contains(missing.string()) && Catch::Contains("does not exist"));
  // A directory where the file should go: the rename fails.
  const fs::path dir = out_dir() / "a_directory.png";
  fs::create_directories(dir);
  REQUIRE_THROWS_AS(render_png(dir, s.field()), std::runtime_error);
  REQUIRE_FALSE(fs::exists(fs::path(dir.string() + ".tmp")));
}

TEST_CASE("render_png replaces the file atomically with the bytes render_png_bytes returns") {
  auto s = plate(0.04, 0.02, 0.002);
  const fs::path file = out_dir() / "atomic.png";
  render_png(file, s.field(), {.width = 200});
  s.values.assign(s.values.size(), 1.0);
  render_png(file, s.field(), {.width = 300});
  REQUIRE_FALSE(fs::exists(fs::path(file.string() + ".tmp")));
  std::ifstream in(file, std::ios::binary);
  const std::vector<unsigned char> written{std::istreambuf_iterator<char>(in), {}};
  REQUIRE(same::difference(written, render_png_bytes(s.field(), {.width = 300}), "written") == "");
}

TEST_CASE("the estimated spacing of a lattice is its spacing, and squares grow to keep a perturbed cloud solid") {
  for (double h : {0.002, 0.01}) {
    const auto pc = lattice(rectangle({0, 0, 0}, {0.3, 0.1, 0}), {.spacing = h});
    const auto e2 = estimate_spacing({pc.x[0], pc.x[1], pc.x[2]}, 2);
    REQUIRE(e2.spacing == Approx(h).epsilon(1e-9));
    REQUIRE(e2.solid_size == Approx(h).epsilon(1e-9));
    const auto slab = lattice(box({0, 0, 0}, {0.05, 0.05, 0.02}), {.spacing = h / 4});
    REQUIRE(estimate_spacing({slab.x[0], slab.x[1], slab.x[2]}, 3).spacing == Approx(h / 4).epsilon(1e-9));
  }
  // A perturbed disk drawn with the default squares: no background pixel inside it.
  Sample d;
  d.pc = lattice(disk({0, 0, 0}, 0.05), {.spacing = 0.001, .perturbation = 0.3, .seed = 7});
  d.values.assign(d.pc.size(), 0.0);
  const auto e = estimate_spacing({d.pc.x[0], d.pc.x[1], d.pc.x[2]}, 2);
  REQUIRE(e.spacing < 0.001);
  REQUIRE(e.solid_size > 0.001);
  const RenderOptions o{.width = 700};
  const cv::Mat img = decode(render_png_bytes(d.field(), o));
  const auto L = render_layout(d.field(), o);
  int holes = 0, inside = 0;
  for (int r = L.plot_y; r < L.plot_y + L.plot_h; ++r)
    for (int c = L.plot_x; c < L.plot_x + L.plot_w; ++c) {
      // Pixel centre back in metres: (col - offset) / ppm + corner.
      const double x = (c + 0.5 - L.offset[0]) / L.pixels_per_metre + L.corner[0];
      const double y = L.corner[1] - (r + 0.5 - L.offset[1]) / L.pixels_per_metre;
      if (std::hypot(x, y) < 0.048) ++inside, holes += is_background(img.at<cv::Vec3b>(r, c));
    }
  CAPTURE(inside, holes);
  REQUIRE(inside > 10000);
  REQUIRE(holes == 0);
  render_png(out_dir() / "perturbed_disk.png", d.field(), o);
}

TEST_CASE("bonds broken across a crack line show as damage along the crack, in reference and deformed views") {
  // A plate whose bonds crossing y = 0.05 for x < 0.1 are broken, as a propagated crack leaves them.
  const double h = 0.001;
  Body body;
  body.points = lattice(rectangle({0, 0, 0}, {0.2, 0.1, 0}), {.spacing = h});
  body.bonds = build_bonds(body.points, {.horizon = 3.015 * h});
  const auto& pc = body.points;
  for (std::size_t i = 0; i < pc.size(); ++i)
    for (auto b = body.bonds.begin(i); b < body.bonds.end(i); ++b) {
      const auto p = pc.position(i), q = pc.position(std::size_t(body.bonds.neighbor[b]));
      if ((p[1] - 0.05) * (q[1] - 0.05) < 0) {
        const double x_cross = p[0] + (0.05 - p[1]) / (q[1] - p[1]) * (q[0] - p[0]);
        if (x_cross < 0.1) body.bonds.intact[b] = 0;
      }
    }
  Sample s;
  s.pc = pc;
  s.values = damage(body);
  s.u = zero_field(pc.size());
  for (std::size_t i = 0; i < pc.size(); ++i)  // the crack opens: the halves rotate apart about the tip
    if (pc.x[0][i] < 0.1) s.u[1][i] = (pc.x[1][i] > 0.05 ? 1 : -1) * 2e-4 * (0.1 - pc.x[0][i]) / 0.1;

  const RenderOptions ref{.width = 1200};
  render_png(out_dir() / "cracked_plate.png", s.field(), ref);
  const cv::Mat img = decode(render_png_bytes(s.field(), ref));
  const auto L = render_layout(s.field(), ref);
  const auto on_crack = pixel(img, L, 0.0502, 0.0495), far = pixel(img, L, 0.0502, 0.02), ahead = pixel(img, L, 0.1502, 0.0495);
  REQUIRE(colour_distance(on_crack, far) > 60);
  REQUIRE(colour_distance(ahead, far) <= 3);  // no damage ahead of the tip

  const RenderOptions def{.width = 1200, .deformed = true, .magnification = 50};
  render_png(out_dir() / "cracked_plate_deformed.png", s.field(), def);
  const cv::Mat opened = decode(render_png_bytes(s.field(), def));
  const auto Ld = render_layout(s.field(), def);
  // Opening of 2 * 50 * 2e-4 * 0.5 = 0.01 m at x = 0.05: a gap of background on the crack line.
  REQUIRE(is_background(pixel(opened, Ld, 0.05, 0.05)));
  REQUIRE_FALSE(is_background(pixel(opened, Ld, 0.15, 0.05)));
}

TEST_CASE("nearest_distances finds every point's two nearest distinct neighbours, as a search over all points does, however sparse the cells") {
  // Tight clusters far apart: the cell grid sized for the bounding box puts whole clusters in
  // one cell, and a lone point's neighbours lie many cells away; a duplicate point carries no
  // distance.
  std::vector<double> x, y, z;
  std::uint64_t state = 12345;
  const auto uniform = [&] {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return double(state >> 11) * 0x1p-53;
  };
  for (int c = 0; c < 6; ++c)
    for (int k = 0; k < 40; ++k) x.push_back(c * 0.37 + 1e-3 * uniform()), y.push_back(0.1 * (c % 2) + 1e-3 * uniform()), z.push_back(0);
  x.push_back(5.0), y.push_back(5.0), z.push_back(0);  // alone
  x.push_back(x[3]), y.push_back(y[3]), z.push_back(0);  // a duplicate of point 3
  for (int d : {2, 3}) {
    if (d == 3)
      for (auto& v : z) v = uniform();
    std::vector<std::size_t> queries(x.size());
    std::iota(queries.begin(), queries.end(), std::size_t{0});
    const auto got = nearest_distances({x, y, z}, d, queries);
    int wrong = 0;
    for (std::size_t i = 0; i < x.size(); ++i) {
      std::vector<double> all;
      for (std::size_t j = 0; j < x.size(); ++j) {
        const double dd = (x[j] - x[i]) * (x[j] - x[i]) + (y[j] - y[i]) * (y[j] - y[i]) + (d == 3 ? (z[j] - z[i]) * (z[j] - z[i]) : 0.0);
        if (dd > 0) all.push_back(dd);
      }
      std::sort(all.begin(), all.end());
      wrong += got[2 * i] != std::sqrt(all[0]) || got[2 * i + 1] != std::sqrt(all[1]);
    }
    CAPTURE(d);
    REQUIRE(wrong == 0);
  }
}

namespace {

// Parts of a field drawn on threads, one per part, reducing through shared buffers: what N
// ranks do through MPI.
struct ThreadParts {
  explicit ThreadParts(int n) : n(n), sync(n), slots(std::size_t(n)), level_slots(std::size_t(n)) {}
  int n;
  std::barrier<> sync;
  std::vector<std::vector<double>> slots;
  std::vector<std::vector<std::int16_t>> level_slots;

  void reduce(int part, std::span<double> v, bool maximum) {
    slots[std::size_t(part)].assign(v.begin(), v.end());
    sync.arrive_and_wait();
    for (std::size_t k = 0; k < v.size(); ++k) {
      double r = maximum ? -std::numeric_limits<double>::infinity() : 0.0;
      for (const auto& s : slots) r = maximum ? std::max(r, s[k]) : r + s[k];
      v[k] = r;
    }
    sync.arrive_and_wait();
  }
  RenderParts of(int part) {
    RenderParts p;
    p.root = part == 0;
    p.sum = [this, part](std::span<double> v) { reduce(part, v, false); };
    p.max = [this, part](std::span<double> v) { reduce(part, v, true); };
    p.max_to_root = [this, part](std::span<std::int16_t> v) {
      level_slots[std::size_t(part)].assign(v.begin(), v.end());
      sync.arrive_and_wait();
      if (part == 0)
        for (const auto& s : level_slots)
          for (std::size_t k = 0; k < v.size(); ++k) v[k] = std::max(v[k], s[k]);
      sync.arrive_and_wait();
    };
    return p;
  }
};

// The points of `whole` whose index is `part` modulo `parts`, as their own field (arrays in `keep`).
RenderField part_of(const RenderField& whole, int part, int parts, std::vector<std::vector<double>>& keep) {
  keep.assign(8, {});
  const std::size_t n = whole.x[0].size();
  std::array<std::span<const double>, 8> from{whole.x[0], whole.x[1], whole.x[2], whole.u[0], whole.u[1], whole.u[2], whole.values, {}};
  for (std::size_t i = std::size_t(part); i < n; i += std::size_t(parts))
    for (std::size_t q = 0; q < 7; ++q)
      if (!from[q].empty()) keep[q].push_back(from[q][i]);
  RenderField f = whole;
  f.x = {keep[0], keep[1], keep[2]};
  f.u = {keep[3], keep[4], keep[5]};
  f.values = keep[6];
  return f;
}

}  // namespace

TEST_CASE("a field drawn in parts, each part drawing its own points, is the one-part image byte for byte") {
  // A perturbed 3D block with a deformation, NaN and a value range of its own: a slice, a
  // deformed slice and a projection, cut into 3 interleaved parts.
  Sample s;
  s.pc = lattice(box({0, 0, 0}, {0.04, 0.02, 0.01}), {.spacing = 0.001, .perturbation = 0.2, .seed = 3});
  for (int k = 0; k < 3; ++k) s.u[k].resize(s.pc.size());
  for (std::size_t i = 0; i < s.pc.size(); ++i) {
    s.values.push_back(i % 97 == 0 ? std::numeric_limits<double>::quiet_NaN() : std::sin(300 * s.pc.x[0][i]) * 2e-3);
    s.u[1][i] = 0.05 * s.pc.x[0][i] * s.pc.x[0][i];
  }
  const auto whole = s.field("velocity");
  const auto est = estimate_spacing(whole.x, 3);
  std::vector<RenderOptions> views{{.width = 500}, {.width = 400, .deformed = true, .magnification = 3, .axis = 0},
                                   {.width = 300, .view3d = RenderOptions::View3D::projection, .axis = 1}};
  for (auto o : views) {
    o.point_size = est.solid_size;
    RenderField one = whole;
    one.spacing = est.spacing;
    const auto expected = render_png_bytes(one, o);
    ThreadParts tp(3);
    std::vector<std::vector<unsigned char>> got(3);
    std::vector<std::thread> threads;
    for (int part = 0; part < 3; ++part)
      threads.emplace_back([&, part] {
        std::vector<std::vector<double>> keep;
        got[std::size_t(part)] = render_png_bytes(part_of(one, part, 3, keep), o, tp.of(part));
      });
    for (auto& t : threads) t.join();
    CAPTURE(o.axis, o.deformed);
    REQUIRE(got[1].empty());  // only the root gets an image
    REQUIRE(got[2].empty());
    const bool same = got[0] == expected;
    REQUIRE(same);
  }
}
