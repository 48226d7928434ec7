#include <catch2/catch.hpp>
#include <unistd.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>
import peridot.render;

namespace fs = std::filesystem;

namespace {

// Pixels of the first line colour (BGR 180, 119, 31), within a small tolerance for antialiasing.
std::vector<cv::Point> line_pixels(const cv::Mat& img) {
  std::vector<cv::Point> out;
  for (int r = 0; r < img.rows; ++r)
    for (int c = 0; c < img.cols; ++c) {
      const auto p = img.at<cv::Vec3b>(r, c);
      if (std::abs(p[0] - 180) < 12 && std::abs(p[1] - 119) < 12 && std::abs(p[2] - 31) < 12) out.push_back({c, r});
    }
  return out;
}

}  // namespace

TEST_CASE("a history plot draws y = x as the diagonal of its panel and y = x^2 below it, bowing as a parabola does") {
  std::vector<double> x, line, parabola;
  for (int i = 0; i <= 100; ++i) {
    x.push_back(i * 1e-6);
    line.push_back(i * 1e-6);
    parabola.push_back(1e-4 * (i * 1e-2) * (i * 1e-2));
  }
  const fs::path file = fs::temp_directory_path() / ("peridot_plot_" + std::to_string(getpid()) + ".png");
  for (const bool linear : {true, false}) {
    const auto& y = linear ? line : parabola;
    const peridot::PlotPanel panels[] = {{"y", {{"y", y}}}};
    peridot::plot_png(file, x, panels, {.title = "test", .width = 800, .panel_height = 400});
    const cv::Mat img = cv::imread(file.string(), cv::IMREAD_COLOR);
    REQUIRE(img.cols == 800);
    const auto px = line_pixels(img);
    REQUIRE(px.size() > 300);
    // The curve spans the panel: its leftmost point is its lowest, its rightmost its highest.
    cv::Point left = px[0], right = px[0];
    for (const auto& p : px) {
      if (p.x < left.x) left = p;
      if (p.x > right.x) right = p;
    }
    CHECK(right.x - left.x > 600);
    CHECK(left.y - right.y > 350);
    // Every pixel lies within 3 px of the exact curve mapped through the end points.
    const double w = right.x - left.x, h = left.y - right.y;
    int off = 0;
    for (const auto& p : px) {
      const double s = (p.x - left.x) / w;  // x in [0, 1]
      const double expected = left.y - h * (linear ? s : s * s);
      off += std::abs(p.y - expected) > 3 + 2 * (linear ? 1.0 : 2 * s);  // steeper: a wider stroke
    }
    CHECK(off == 0);
  }
  fs::remove(file);
}

TEST_CASE("a plot line whose length differs from the abscissa's is refused naming it") {
  const std::vector<double> x{0, 1, 2};
  const peridot::PlotPanel panels[] = {{"energy", {{"kinetic", {1.0, 2.0}}}}};
  CHECK_THROWS_WITH(peridot::plot_png("unused.png", x, panels), Catch::Contains("line 'kinetic' has 2 values for 3 abscissae"));
  CHECK(!fs::exists("unused.png"));
}
