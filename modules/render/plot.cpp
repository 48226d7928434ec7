// The history plot (plot.cppm), drawn with OpenCV: kept out of the interface, so importers
// of peridot.render need no OpenCV header.
module;
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
module peridot.render;
import peridot.std;
import :canvas;
import :png_writer;

namespace peridot {

namespace {

using namespace draw;

// Tab10's first colours, in BGR: distinct on white and for the common colour blindnesses.
const cv::Scalar line_colours[] = {{180, 119, 31}, {14, 127, 255}, {44, 160, 44}, {40, 39, 214}, {189, 103, 148}};

struct Range {
  double lo = 0, hi = 1;
};

Range range_of(std::span<const double> v) {
  Range r{INFINITY, -INFINITY};
  for (double a : v)
    if (std::isfinite(a)) r.lo = std::min(r.lo, a), r.hi = std::max(r.hi, a);
  if (!(r.lo <= r.hi)) return {0, 1};
  if (r.hi - r.lo <= 1e-300 + 1e-12 * std::abs(r.hi)) r.lo -= 0.5 * std::max(1.0, std::abs(r.lo)), r.hi += 0.5 * std::max(1.0, std::abs(r.hi));
  return r;
}

}  // namespace

void plot_png(const std::filesystem::path& file, std::span<const double> x, std::span<const PlotPanel> panels, const PlotOptions& o) {
  for (const auto& p : panels)
    for (const auto& l : p.lines)
      if (l.y.size() != x.size())
        throw std::invalid_argument(fmt::format("plot: line '{}' has {} values for {} abscissae", l.name, l.y.size(), x.size()));
  const int margin_l = 110, margin_r = 30, title_h = 70, axis_h = 60, gap = 30;
  const int W = std::max(400, o.width), ph = std::max(120, o.panel_height);
  const int H = title_h + int(panels.size()) * (ph + gap) + axis_h;
  cv::Mat img(H, W, CV_8UC3, background);
  const Font title_font{cv::FONT_HERSHEY_SIMPLEX, 0.8, 2}, label{cv::FONT_HERSHEY_SIMPLEX, 0.5, 1};
  text(img, o.title, {margin_l, 32}, fit(o.title, title_font, W - margin_l - margin_r), ink);
  const Range xr = range_of(x);
  const int plot_w = W - margin_l - margin_r;
  const auto col = [&](double v) { return margin_l + int(std::lround((v - xr.lo) / (xr.hi - xr.lo) * plot_w)); };
  const double x_step = nice_step(xr.hi - xr.lo, 6);
  for (std::size_t k = 0; k < panels.size(); ++k) {
    const auto& panel = panels[k];
    const int top = title_h + int(k) * (ph + gap), bottom = top + ph;
    std::vector<double> all;
    for (const auto& l : panel.lines) all.insert(all.end(), l.y.begin(), l.y.end());
    const Range yr = range_of(all);
    const auto row = [&](double v) { return bottom - int(std::lround((v - yr.lo) / (yr.hi - yr.lo) * ph)); };
    cv::rectangle(img, {margin_l, top}, {margin_l + plot_w, bottom}, muted, 1);
    // Ticks: a few round numbers on each axis, with light grid lines.
    const double y_step = nice_step(yr.hi - yr.lo, 4);
    for (double v = std::ceil(yr.lo / y_step) * y_step; v <= yr.hi + 1e-9 * y_step; v += y_step) {
      const int r = row(v);
      cv::line(img, {margin_l, r}, {margin_l + plot_w, r}, {230, 230, 230}, 1);
      const std::string t = number(v, y_step);
      text(img, t, {margin_l - 8 - text_size(t, label).width, r + 5}, label, ink);
    }
    for (double v = std::ceil(xr.lo / x_step) * x_step; v <= xr.hi + 1e-9 * x_step; v += x_step) {
      const int c = col(v);
      cv::line(img, {c, top}, {c, bottom}, {230, 230, 230}, 1);
      if (k + 1 == panels.size()) {
        const std::string t = number(v, x_step);
        text(img, t, {c - text_size(t, label).width / 2, bottom + 20}, label, ink);
      }
    }
    // The y label above the panel, the legend after it.
    int at = margin_l;
    text(img, panel.y_label, {at, top - 8}, label, ink);
    at += text_size(panel.y_label, label).width + 24;
    for (std::size_t j = 0; j < panel.lines.size(); ++j) {
      const auto& line = panel.lines[j];
      const auto colour = line_colours[j % std::size(line_colours)];
      if (panel.lines.size() > 1) {
        cv::line(img, {at, top - 12}, {at + 20, top - 12}, colour, 2, cv::LINE_AA);
        text(img, line.name, {at + 26, top - 8}, label, ink);
        at += 26 + text_size(line.name, label).width + 24;
      }
      std::vector<cv::Point> pts;
      const auto flush = [&] {
        if (pts.size() > 1) cv::polylines(img, pts, false, colour, 2, cv::LINE_AA);
        else if (pts.size() == 1) cv::circle(img, pts[0], 2, colour, cv::FILLED, cv::LINE_AA);
        pts.clear();
      };
      for (std::size_t i = 0; i < x.size(); ++i) {
        if (!std::isfinite(x[i]) || !std::isfinite(line.y[i])) {
          flush();
          continue;
        }
        pts.push_back({col(x[i]), row(line.y[i])});
      }
      flush();
    }
  }
  const int last_bottom = title_h + int(panels.size()) * (ph + gap) - gap;
  text(img, o.x_label, {margin_l + plot_w / 2 - text_size(o.x_label, label).width / 2, last_bottom + 45}, label, ink);
  write_atomically(file, encode_png(img));
}

}  // namespace peridot
