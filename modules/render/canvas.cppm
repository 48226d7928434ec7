module;
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
module peridot.render:canvas;
import peridot.std;
import :options;
import :layout;
import :colormap;

namespace peridot {

// Paints a scene into a BGR image: the points, a colorbar, a title and a scale bar.
cv::Mat paint(const Scene& scene, const RenderField& field, const RenderOptions& options);

}  // namespace peridot

namespace peridot {

// Drawing helpers shared with the history plot (:plot); module linkage, not exported.
namespace draw {

inline const cv::Scalar background{255, 255, 255}, ink{40, 40, 40}, muted{110, 110, 110};

// Hershey fonts are vector fonts compiled into OpenCV: text needs no display or font files.
struct Font {
  int face;
  double scale;
  int thickness;
};

cv::Size text_size(const std::string& s, const Font& f, int* baseline = nullptr) {
  int b = 0;
  auto size = cv::getTextSize(s, f.face, f.scale, f.thickness, &b);
  if (baseline) *baseline = b;
  return size;
}

void text(cv::Mat& img, const std::string& s, cv::Point org, const Font& f, const cv::Scalar& colour) {
  cv::putText(img, s, org, f.face, f.scale, colour, f.thickness, cv::LINE_AA);
}

// Shrinks a font until the text fits in `width` pixels.
Font fit(const std::string& s, Font f, int width) {
  const int w = text_size(s, f).width;
  if (w > width && w > 0) f.scale *= double(width) / w;
  return f;
}

// 1, 2 or 5 times a power of ten, giving about `count` intervals over `span`.
double nice_step(double span, int count) {
  const double raw = span / count, p = std::pow(10.0, std::floor(std::log10(raw))), m = raw / p;
  return (m < 1.5 ? 1 : m < 3.5 ? 2 : m < 7.5 ? 5 : 10) * p;
}

// Fixed decimals that resolve `step` for ordinary magnitudes, else 3 significant digits.
std::string number(double v, double step, int extra_digits = 0) {
  if (std::abs(v) < 1e-9 * step) v = 0;  // no "-0.0"
  if (step >= 1e-4 && std::max(std::abs(v), step) < 1e6) {
    const int decimals = std::max(0, int(std::ceil(-std::log10(step) - 1e-9))) + extra_digits;
    return fmt::format("{:.{}f}", v, decimals);
  }
  return fmt::format("{:.{}g}", v, 3 + extra_digits);
}

}  // namespace draw

namespace {

using namespace draw;

std::string time_text(double t) { return fmt::format("{:.4g}", t); }

// Length with a unit that keeps the number between 1 and 1000 (ASCII "um": Hershey has no mu).
std::string length_text(double metres) {
  const double a = std::abs(metres);
  if (a >= 1000) return fmt::format("{:g} km", metres / 1000);
  if (a >= 1) return fmt::format("{:g} m", metres);
  if (a >= 1e-3) return fmt::format("{:g} mm", metres * 1e3);
  if (a >= 1e-6) return fmt::format("{:g} um", metres * 1e6);
  if (a == 0) return "0 m";  // a mid-plane at the origin, not "0 nm"
  return fmt::format("{:g} nm", metres * 1e9);
}

void draw_points(cv::Mat& img, const Scene& s, const Colormap& cmap) {
  const RenderLayout& L = s.layout;
  for (int r = 0; r < L.plot_h; ++r) {
    const std::int16_t* level = s.pixels.data() + std::size_t(r) * std::size_t(L.plot_w);
    auto* row = img.ptr<cv::Vec3b>(L.plot_y + r) + L.plot_x;
    for (int c = 0; c < L.plot_w; ++c)
      if (level[c] != Scene::empty) row[c] = cmap.level(level[c]);
  }
}

void draw_colorbar(cv::Mat& img, const RenderLayout& L, const RenderField& f, const Colormap& cmap) {
  const double sc = L.scale;
  for (int r = 0; r < L.bar_h; ++r) {
    const cv::Vec3b colour = cmap.at(L.bar_h > 1 ? 1.0 - double(r) / (L.bar_h - 1) : 1.0);  // vmax on the top row, vmin on the bottom one
    auto* row = img.ptr<cv::Vec3b>(L.bar_y + r);
    std::fill(row + std::min(L.bar_x, L.width), row + std::min(L.bar_x + L.bar_w, L.width), colour);
  }
  const int line = std::max(1, int(std::lround(1.2 * sc)));
  cv::rectangle(img, {L.bar_x - 1, L.bar_y - 1}, {L.bar_x + L.bar_w, L.bar_y + L.bar_h}, ink, line);

  // Large or tiny numbers share one power of ten, written after the field name.
  const double big = std::max(std::abs(L.vmin), std::abs(L.vmax));
  const int exponent = big >= 1e4 || big < 1e-2 ? int(std::floor(std::log10(big))) : 0;
  const double unit = std::pow(10.0, exponent), vmin = L.vmin / unit, vmax = L.vmax / unit;
  const std::string name = exponent != 0 ? fmt::format("{}  x1e{}", f.field_name, exponent) : f.field_name;
  const Font name_font{cv::FONT_HERSHEY_SIMPLEX, 0.62 * sc, std::max(1, int(std::lround(1.4 * sc)))};
  const int room = L.width - L.bar_x - int(std::lround(8 * sc));
  text(img, name, {L.bar_x, L.bar_y - int(std::lround(20 * sc))}, fit(name, name_font, std::max(1, room)), ink);

  // Ticks at round numbers, plus the range ends whenever they are not round themselves,
  // so the colour range is always labelled.
  const Font tick_font{cv::FONT_HERSHEY_SIMPLEX, 0.52 * sc, std::max(1, int(std::lround(1.1 * sc)))};
  const double span = vmax - vmin, step = nice_step(span, 5);
  const auto row_of = [&](double v) { return L.bar_y + (vmax - v) / span * (L.bar_h - 1); };
  struct Tick {
    double value;
    int digits;
  };
  std::vector<Tick> ticks;
  const double min_gap = 0.09 * span;  // keeps labels from overlapping
  for (auto k = std::ceil(vmin / step - 1e-9); k * step <= vmax + 1e-9 * step; k += 1) {
    const double v = k * step;  // a multiple, not a running sum: no drift in the labels
    const bool at_end = std::abs(v - vmin) < 1e-9 * step || std::abs(v - vmax) < 1e-9 * step;
    if (at_end || (v - vmin > min_gap && vmax - v > min_gap)) ticks.push_back({v, 0});
  }
  if (ticks.empty() || std::abs(ticks.front().value - vmin) > 1e-9 * step) ticks.insert(ticks.begin(), {vmin, 1});
  if (std::abs(ticks.back().value - vmax) > 1e-9 * step) ticks.push_back({vmax, 1});
  const int tick_len = std::max(2, int(std::lround(6 * sc)));
  for (const auto& t : ticks) {
    const int y = std::clamp(int(std::lround(row_of(t.value))), L.bar_y, L.bar_y + L.bar_h - 1);
    cv::line(img, {L.bar_x + L.bar_w, y}, {L.bar_x + L.bar_w + tick_len, y}, ink, line);
    const std::string label = number(t.value, step, t.digits);
    const Font tf = fit(label, tick_font, std::max(1, L.width - (L.bar_x + L.bar_w + 2 * tick_len) - 2));
    const auto size = text_size(label, tf);
    text(img, label, {L.bar_x + L.bar_w + 2 * tick_len, y + size.height / 2}, tf, ink);
  }

  if (L.has_nan) {  // a swatch that explains the grey
    const int side = L.bar_w, y = L.bar_y + L.bar_h + int(std::lround(14 * sc));
    cv::rectangle(img, {L.bar_x, y}, {L.bar_x + side - 1, y + side / 2}, cv::Scalar(Colormap::nan_colour), cv::FILLED);
    const auto size = text_size("NaN", tick_font);
    text(img, "NaN", {L.bar_x + L.bar_w + 2 * tick_len, y + side / 4 + size.height / 2}, tick_font, ink);
  }
}

std::string subtitle(const RenderLayout& L, const RenderField& f, const RenderOptions& o) {
  const char* names = "xyz";
  std::string s;
  if (f.dim == 3) {
    s = o.view3d == RenderOptions::View3D::slice
            ? fmt::format("slice {} = {}, ", names[o.axis], length_text(L.slice_position))
            : fmt::format("projection along {} (largest value in front), ", names[o.axis]);
  }
  s += o.deformed ? fmt::format("deformed configuration, displacements x {:g}", o.magnification)
                  : std::string("reference configuration");
  s += fmt::format(", {} points", L.drawn);
  return s;
}

void draw_titles(cv::Mat& img, const RenderLayout& L, const RenderField& f, const RenderOptions& o) {
  const double sc = L.scale;
  const int x = L.plot_x, room = std::max(1, L.width - 2 * x);
  const std::string title =
      !o.title.empty()        ? o.title
      : f.time_label.empty() ? fmt::format("{}   t = {} s   step {}", f.field_name, time_text(f.time), f.step)
                             : fmt::format("{}   {} {}   step {}", f.field_name, f.time_label, time_text(f.time), f.step);
  const Font tf = fit(title, {cv::FONT_HERSHEY_DUPLEX, 0.95 * sc, std::max(1, int(std::lround(1.6 * sc)))}, room);
  text(img, title, {x, int(std::lround(40 * sc))}, tf, ink);
  const std::string sub = subtitle(L, f, o);
  const Font sf = fit(sub, {cv::FONT_HERSHEY_SIMPLEX, 0.55 * sc, std::max(1, int(std::lround(1.1 * sc)))}, room);
  text(img, sub, {x, int(std::lround(70 * sc))}, sf, muted);
}

// A bar of round length, about a fifth of the plot, under its lower left corner.
void draw_scale_bar(cv::Mat& img, const RenderLayout& L) {
  const double sc = L.scale;
  const double metres = nice_step(L.plot_w / L.pixels_per_metre, 5);
  const int len = int(std::lround(metres * L.pixels_per_metre));
  const int x0 = L.plot_x, y = L.plot_y + L.plot_h + int(std::lround(30 * sc));
  const int line = std::max(1, int(std::lround(2 * sc))), tick = std::max(2, int(std::lround(6 * sc)));
  cv::line(img, {x0, y}, {x0 + len, y}, ink, line);
  cv::line(img, {x0, y - tick}, {x0, y + tick}, ink, line);
  cv::line(img, {x0 + len, y - tick}, {x0 + len, y + tick}, ink, line);
  const Font font{cv::FONT_HERSHEY_SIMPLEX, 0.52 * sc, std::max(1, int(std::lround(1.1 * sc)))};
  const std::string label = length_text(metres);
  text(img, label, {x0 + len + int(std::lround(12 * sc)), y + text_size(label, font).height / 2}, font, ink);
}

}  // namespace

cv::Mat paint(const Scene& scene, const RenderField& field, const RenderOptions& options) {
  const RenderLayout& L = scene.layout;
  cv::Mat img(L.height, L.width, CV_8UC3, background);
  const Colormap cmap;
  draw_points(img, scene, cmap);
  draw_colorbar(img, L, field, cmap);
  draw_titles(img, L, field, options);
  draw_scale_bar(img, L);
  return img;
}

}  // namespace peridot
