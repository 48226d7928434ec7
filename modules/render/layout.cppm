module;
#include <stdint.h>  // UINT32_MAX
export module peridot.render:layout;
import peridot.std;
import :options;
import :spacing;

export namespace peridot {

// Where everything lands in the image. Exposed so callers (and tests) can map model
// coordinates to pixels and find the plot, colorbar and title areas.
struct RenderLayout {
  int width = 0, height = 0;                    // image size [px]
  int plot_x = 0, plot_y = 0, plot_w = 0, plot_h = 0;  // area that holds the body [px]
  int bar_x = 0, bar_y = 0, bar_w = 0, bar_h = 0;      // colorbar [px]
  double scale = 1;                             // text and stroke scale (1 at 1200 px wide)
  double pixels_per_metre = 0;                  // same along both image axes
  std::array<int, 2> axes{0, 1};                // model axes drawn rightwards and upwards
  std::array<double, 2> corner{0, 0};           // model coordinates at the body area's left and top edges
  std::array<double, 2> offset{0, 0};           // body area's left and top edges [px, continuous]
  double spacing = 0;                           // point spacing h [m], given or estimated
  double point_size = 0;                        // drawn square side [m]: given, or solid_size of estimate_spacing
  double vmin = 0, vmax = 1;                    // colour range
  double slice_position = 0;                    // 3D slice only [m]
  std::size_t drawn = 0;                        // points drawn (3D slices keep a subset)
  bool has_nan = false;                         // some drawn value is NaN (drawn grey)

  // Continuous pixel coordinates (column, row) of in-plane model coordinates (a, b);
  // pixel (c, r) covers [c, c + 1) x [r, r + 1).
  std::array<double, 2> to_pixel(double a, double b) const {
    return {offset[0] + (a - corner[0]) * pixels_per_metre, offset[1] + (corner[1] - b) * pixels_per_metre};
  }
};

// Validates the field and options (throwing std::invalid_argument naming the culprit and
// its allowed range) and computes the layout render_png would use.
RenderLayout render_layout(const RenderField& field, const RenderOptions& options = {});

}  // namespace peridot

namespace peridot {

// Colormap entry of a value: 0 (vmin) .. 255 (vmax), saturating outside; NaN has its own.
constexpr int colour_levels = 256, nan_level = -1;
int colour_level(double v, double vmin, double vmax);

// The points to draw, in pixel coordinates, in drawing order: ascending colour with NaN
// first, so the largest value ends up in front (what a 3D projection shows).
struct Scene {
  RenderLayout layout;
  std::vector<std::uint32_t> order;  // indices into the field
  std::vector<double> col, row;      // pixel centre of order[k]
  std::vector<std::int16_t> level;   // colour_level of order[k]
};

Scene build_scene(const RenderField& field, const RenderOptions& options);

}  // namespace peridot

namespace peridot {

namespace {

constexpr int min_pixels = 16, max_pixels = 16384;

[[noreturn]] void bad(const std::string& what) { throw std::invalid_argument("render: " + what); }

void validate(const RenderField& f, const RenderOptions& o) {
  if (f.dim != 2 && f.dim != 3) bad(fmt::format("field.dim = {} must be 2 or 3", f.dim));
  const std::size_t n = f.x[0].size();
  if (n == 0) bad("field.x is empty: there are no points to draw");
  if (n > std::size_t(UINT32_MAX)) bad(fmt::format("field has {} points; at most {} can be drawn", n, UINT32_MAX));
  const char* names = "xyz";
  for (int k = 0; k < 3; ++k) {
    const bool needed = k < f.dim;
    if (f.x[k].size() != n && (needed || !f.x[k].empty()))
      bad(fmt::format("field.x[{}] ({}) has {} entries but field.x[0] has {}", k, names[k], f.x[k].size(), n));
  }
  const bool has_u = !f.u[0].empty() || !f.u[1].empty() || !f.u[2].empty();
  for (int k = 0; k < 3 && has_u; ++k)
    if (f.u[k].size() != n && (k < f.dim || !f.u[k].empty()))
      bad(fmt::format("field.u[{}] has {} entries but there are {} points (leave all of u empty for none)", k,
                      f.u[k].size(), n));
  if (f.values.size() != n) bad(fmt::format("field.values ({}) has {} entries but there are {} points", f.field_name, f.values.size(), n));
  if (!(f.spacing >= 0) || !std::isfinite(f.spacing)) bad(fmt::format("field.spacing = {} must be finite and >= 0 (0: estimate)", f.spacing));

  if (o.width < min_pixels || o.width > max_pixels)
    bad(fmt::format("options.width = {} px must be in [{}, {}]", o.width, min_pixels, max_pixels));
  if (o.height != 0 && (o.height < min_pixels || o.height > max_pixels))
    bad(fmt::format("options.height = {} px must be 0 (from the aspect ratio) or in [{}, {}]", o.height, min_pixels, max_pixels));
  if (!(o.magnification >= 0) || !std::isfinite(o.magnification))
    bad(fmt::format("options.magnification = {} must be finite and >= 0", o.magnification));
  if (o.deformed && !has_u) bad("options.deformed needs displacements, but field.u is empty");
  if (o.vmin && !std::isfinite(*o.vmin)) bad(fmt::format("options.vmin = {} must be finite", *o.vmin));
  if (o.vmax && !std::isfinite(*o.vmax)) bad(fmt::format("options.vmax = {} must be finite", *o.vmax));
  if (o.vmin && o.vmax && !(*o.vmin < *o.vmax))
    bad(fmt::format("options.vmin = {} must be less than options.vmax = {}", *o.vmin, *o.vmax));
  if (o.axis < 0 || o.axis > 2) bad(fmt::format("options.axis = {} must be 0, 1 or 2 (x, y, z)", o.axis));
  if (f.dim == 2 && o.axis != 2) bad(fmt::format("options.axis = {}: a 2D field is always seen along z (axis 2)", o.axis));
  if (o.slice_position && !std::isfinite(*o.slice_position))
    bad(fmt::format("options.slice_position = {} must be finite", *o.slice_position));
  if (!(o.point_size >= 0) || !std::isfinite(o.point_size))
    bad(fmt::format("options.point_size = {} m must be finite and >= 0 (0: the point spacing)", o.point_size));
  if (o.view3d != RenderOptions::View3D::slice && o.view3d != RenderOptions::View3D::projection)
    bad("options.view3d must be slice or projection");

  for (int k = 0; k < f.dim; ++k)
    for (std::size_t i = 0; i < n; ++i) {
      if (!std::isfinite(f.x[k][i]))
        bad(fmt::format("field.x[{}][{}] = {}: positions must be finite", k, i, f.x[k][i]));
      if (o.deformed && !std::isfinite(f.u[k][i]))
        bad(fmt::format("field.u[{}][{}] = {}: displacements must be finite to draw the deformed body", k, i, f.u[k][i]));
    }
}

// Default colour range: [0, 1] for damage, else the finite data range (widened when flat).
std::array<double, 2> colour_range(const RenderField& f, const RenderOptions& o) {
  double lo = 0, hi = 1;
  if (f.field_name != "damage") {
    lo = std::numeric_limits<double>::infinity(), hi = -std::numeric_limits<double>::infinity();
    for (double v : f.values)
      if (std::isfinite(v)) lo = std::min(lo, v), hi = std::max(hi, v);
    if (!(lo <= hi)) lo = 0, hi = 1;  // no finite value at all
  }
  if (o.vmin) lo = *o.vmin;
  if (o.vmax) hi = *o.vmax;
  if (!(lo < hi)) {  // flat data, or one bound given beyond the data
    const double pad = std::max(0.5 * std::abs(o.vmin ? lo : hi), 0.5);
    if (o.vmin) hi = lo + pad;
    else lo = hi - pad;
  }
  return {lo, hi};
}

}  // namespace

Scene build_scene(const RenderField& f, const RenderOptions& o) {
  validate(f, o);
  Scene s;
  RenderLayout& L = s.layout;
  const std::size_t n = f.x[0].size();
  const bool three_d = f.dim == 3;
  L.axes = three_d ? std::array<int, 2>{o.axis == 0 ? 1 : 0, o.axis == 2 ? 1 : 2} : std::array<int, 2>{0, 1};
  // The squares' default size comes from the cloud itself, so that perturbed clouds look solid too.
  const PointSpacing est = f.spacing > 0 && o.point_size > 0 ? PointSpacing{} : estimate_spacing(f.x, f.dim);
  L.spacing = f.spacing > 0 ? f.spacing : est.spacing;
  L.point_size = o.point_size > 0 ? o.point_size : est.solid_size;

  // Which points: all of them, or a slab one spacing thick around the slice plane.
  const bool slice = three_d && o.view3d == RenderOptions::View3D::slice;
  s.order.reserve(n);
  if (slice) {
    const auto [mn, mx] = std::minmax_element(f.x[o.axis].begin(), f.x[o.axis].end());
    L.slice_position = o.slice_position.value_or(0.5 * (*mn + *mx));
    const double half = 0.5 * L.spacing * (1 + 1e-9);  // tolerance: lattice layers sit exactly h/2 off a mid-plane
    for (std::size_t i = 0; i < n; ++i)
      if (std::abs(f.x[o.axis][i] - L.slice_position) <= half) s.order.push_back(std::uint32_t(i));
    if (s.order.empty())
      bad(fmt::format("options.slice_position = {} m holds no points: the body spans [{}, {}] m along axis {}",
                      L.slice_position, *mn, *mx, o.axis));
  } else {
    s.order.resize(n);
    std::iota(s.order.begin(), s.order.end(), 0u);
  }
  L.drawn = s.order.size();

  // Frame: reference and deformed positions both fit, so a moving body moves in the image.
  const double mag = o.deformed ? o.magnification : 0.0;
  auto coord = [&](int plane_axis, std::uint32_t i) {
    const int k = L.axes[plane_axis];
    return f.x[k][i] + (mag != 0 ? mag * f.u[k][i] : 0.0);
  };
  std::array<double, 2> lo{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity()}, hi{-std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
  for (auto i : s.order)
    for (int a = 0; a < 2; ++a) {
      const double ref = f.x[L.axes[a]][i], cur = coord(a, i);
      lo[a] = std::min({lo[a], ref, cur});
      hi[a] = std::max({hi[a], ref, cur});
    }
  for (int a = 0; a < 2; ++a) lo[a] -= 0.5 * L.point_size, hi[a] += 0.5 * L.point_size;
  const double ex = hi[0] - lo[0], ey = hi[1] - lo[1];

  // Bands around the plot scale with the width so that text keeps its proportions; below
  // 1200 px they shrink more slowly so that small snapshots stay legible.
  const double sc = o.width >= 1200 ? o.width / 1200.0 : std::sqrt(o.width / 1200.0);
  L.scale = sc;
  L.width = o.width;
  const int pad = std::max(1, int(std::lround(24 * sc)));
  const int top = int(std::lround(84 * sc)), bottom = int(std::lround(64 * sc)), right = int(std::lround(210 * sc));
  const int min_plot_h = int(std::lround(260 * sc));
  L.plot_x = pad;
  L.plot_y = top;
  L.plot_w = std::max(1, o.width - pad - right);
  double ppm = L.plot_w / ex;
  if (o.height == 0) {
    L.plot_h = std::max(min_plot_h, int(std::ceil(ey * ppm - 1e-9)));
    L.height = std::min(max_pixels, top + L.plot_h + bottom);
  } else {
    L.height = o.height;
  }
  L.plot_h = std::max(1, L.height - top - bottom);
  ppm = std::min(ppm, L.plot_h / ey);
  L.pixels_per_metre = ppm;
  L.corner = {lo[0], hi[1]};
  L.offset = {L.plot_x + 0.5 * (L.plot_w - ex * ppm), L.plot_y + 0.5 * (L.plot_h - ey * ppm)};

  // Colorbar beside the plot, leaving room above for the field name and below for NaN.
  L.bar_w = std::max(1, int(std::lround(28 * sc)));
  L.bar_x = L.plot_x + L.plot_w + int(std::lround(40 * sc));
  const int label_room = int(std::lround(42 * sc)), nan_room = int(std::lround(40 * sc));
  L.bar_h = std::max(1, std::min(L.plot_h - label_room - nan_room, int(std::lround(640 * sc))));
  L.bar_y = L.plot_y + label_room + std::max(0, (L.plot_h - label_room - nan_room - L.bar_h) / 2);

  const auto range = colour_range(f, o);
  L.vmin = range[0];
  L.vmax = range[1];

  // Counting sort by colour level, NaN first: O(n), and points of one colour keep their
  // index order, so images are deterministic.
  {
    std::array<std::size_t, colour_levels + 2> start{};
    std::vector<std::int16_t> lv(s.order.size());
    for (std::size_t k = 0; k < lv.size(); ++k) {
      lv[k] = std::int16_t(colour_level(f.values[s.order[k]], L.vmin, L.vmax));
      ++start[std::size_t(lv[k] + 2)];
    }
    for (std::size_t b = 1; b < start.size(); ++b) start[b] += start[b - 1];
    std::vector<std::uint32_t> sorted(s.order.size());
    s.level.resize(s.order.size());
    for (std::size_t k = 0; k < lv.size(); ++k) {
      const std::size_t at = start[std::size_t(lv[k] + 1)]++;
      sorted[at] = s.order[k];
      s.level[at] = lv[k];
    }
    s.order.swap(sorted);
  }
  s.col.resize(s.order.size());
  s.row.resize(s.order.size());
  for (std::size_t k = 0; k < s.order.size(); ++k) {
    const auto p = L.to_pixel(coord(0, s.order[k]), coord(1, s.order[k]));
    s.col[k] = p[0];
    s.row[k] = p[1];
  }
  L.has_nan = s.level.front() == nan_level;  // NaN sorts first
  return s;
}

int colour_level(double v, double vmin, double vmax) {
  if (std::isnan(v)) return nan_level;
  const double t = std::clamp((v - vmin) / (vmax - vmin), 0.0, 1.0);
  return int(std::lround(t * (colour_levels - 1)));
}

RenderLayout render_layout(const RenderField& field, const RenderOptions& options) {
  return build_scene(field, options).layout;
}

}  // namespace peridot
