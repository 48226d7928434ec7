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

// The drawn body as colour levels over the plot area, row-major from (plot_x, plot_y): each
// pixel the largest level of the squares covering it (what painting them in ascending order,
// the largest value in front, shows), NaN's level below every colour and `empty` below that.
struct Scene {
  static constexpr std::int16_t empty = nan_level - 1;
  RenderLayout layout;
  std::vector<std::int16_t> pixels;  // on the root part only
};

Scene build_scene(const RenderField& field, const RenderOptions& options, const RenderParts& parts = {});

}  // namespace peridot

namespace peridot {

namespace {

constexpr int min_pixels = 16, max_pixels = 16384;

[[noreturn]] void bad(const std::string& what) { throw std::invalid_argument("render: " + what); }

void validate(const RenderField& f, const RenderOptions& o, bool one_part) {
  if (f.dim != 2 && f.dim != 3) bad(fmt::format("field.dim = {} must be 2 or 3", f.dim));
  const std::size_t n = f.x[0].size();
  if (n == 0 && one_part) bad("field.x is empty: there are no points to draw");
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

// The finite data range of a part, as {-min, max}: damage always spans [0, 1].
std::array<double, 2> data_range(const RenderField& f) {
  if (f.field_name == "damage") return {-0.0, 1};  // -(-0.0): vmin is +0
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (double v : f.values)
    if (std::isfinite(v)) lo = std::min(lo, v), hi = std::max(hi, v);
  return {-lo, hi};
}

// Default colour range: [0, 1] for damage, else the finite data range (widened when flat).
std::array<double, 2> colour_range(std::array<double, 2> data, const RenderOptions& o) {
  double lo = -data[0], hi = data[1];
  if (!(lo <= hi)) lo = 0, hi = 1;  // no finite value at all
  if (o.vmin) lo = *o.vmin;
  if (o.vmax) hi = *o.vmax;
  if (!(lo < hi)) {  // flat data, or one bound given beyond the data
    const double pad = std::max(0.5 * std::abs(o.vmin ? lo : hi), 0.5);
    if (o.vmin) hi = lo + pad;
    else lo = hi - pad;
  }
  return {lo, hi};
}

// Every part throws when one does: the others would wait in the next reduction.
void validate_together(const RenderField& f, const RenderOptions& o, const RenderParts& parts) {
  if (parts.one()) return validate(f, o, true);
  std::string mine;
  try {
    validate(f, o, false);
  } catch (const std::invalid_argument& e) {
    mine = e.what();
  }
  std::array<double, 1> failed{mine.empty() ? 0.0 : 1.0};
  parts.max(failed);
  if (!mine.empty()) throw std::invalid_argument(mine);
  if (failed[0] > 0) bad("another part of the field is invalid (its process reports why)");
}

}  // namespace

Scene build_scene(const RenderField& f, const RenderOptions& o, const RenderParts& parts) {
  validate_together(f, o, parts);
  if (!parts.one() && !(f.spacing > 0 && o.point_size > 0))
    throw std::logic_error("render: a field in parts needs field.spacing and options.point_size (estimate_spacing_samples)");
  // One part reduces over itself.
  const auto sum = [&](std::span<double> v) {
    if (!parts.one()) parts.sum(v);
  };
  const auto max = [&](std::span<double> v) {
    if (!parts.one()) parts.max(v);
  };
  Scene s;
  RenderLayout& L = s.layout;
  const std::size_t n = f.x[0].size();
  const bool three_d = f.dim == 3;
  L.axes = three_d ? std::array<int, 2>{o.axis == 0 ? 1 : 0, o.axis == 2 ? 1 : 2} : std::array<int, 2>{0, 1};
  // The squares' default size comes from the cloud itself, so that perturbed clouds look solid too.
  const PointSpacing est = f.spacing > 0 && o.point_size > 0 ? PointSpacing{} : estimate_spacing(f.x, f.dim);
  L.spacing = f.spacing > 0 ? f.spacing : est.spacing;
  L.point_size = o.point_size > 0 ? o.point_size : est.solid_size;

  // The extent along the slice axis and the data range, over every part ({-min, max} pairs).
  const bool slice = three_d && o.view3d == RenderOptions::View3D::slice;
  std::array<double, 4> extent{-std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
  if (slice)
    for (std::size_t i = 0; i < n; ++i) extent[0] = std::max(extent[0], -f.x[o.axis][i]), extent[1] = std::max(extent[1], f.x[o.axis][i]);
  const auto data = data_range(f);
  extent[2] = data[0], extent[3] = data[1];
  max(extent);

  // Which points: all of them, or a slab one spacing thick around the slice plane.
  std::vector<std::uint32_t> order;
  order.reserve(n);
  if (slice) {
    L.slice_position = o.slice_position.value_or(0.5 * (-extent[0] + extent[1]));
    const double half = 0.5 * L.spacing * (1 + 1e-9);  // tolerance: lattice layers sit exactly h/2 off a mid-plane
    for (std::size_t i = 0; i < n; ++i)
      if (std::abs(f.x[o.axis][i] - L.slice_position) <= half) order.push_back(std::uint32_t(i));
  } else {
    order.resize(n);
    std::iota(order.begin(), order.end(), 0u);
  }

  // Frame: reference and deformed positions both fit, so a moving body moves in the image.
  const double mag = o.deformed ? o.magnification : 0.0;
  auto coord = [&](int plane_axis, std::uint32_t i) {
    const int k = L.axes[plane_axis];
    return f.x[k][i] + (mag != 0 ? mag * f.u[k][i] : 0.0);
  };
  const auto range = colour_range({extent[2], extent[3]}, o);
  L.vmin = range[0];
  L.vmax = range[1];
  // {-lo, hi} in the plane, then whether a drawn value is NaN.
  std::array<double, 5> frame{-std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(),
                              -std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(), 0};
  std::vector<std::int16_t> level(order.size());
  for (std::size_t k = 0; k < order.size(); ++k) {
    const auto i = order[k];
    for (int a = 0; a < 2; ++a) {
      const double ref = f.x[L.axes[a]][i], cur = coord(a, i);
      frame[std::size_t(a)] = std::max({frame[std::size_t(a)], -ref, -cur});
      frame[std::size_t(2 + a)] = std::max({frame[std::size_t(2 + a)], ref, cur});
    }
    level[k] = std::int16_t(colour_level(f.values[i], L.vmin, L.vmax));
    if (level[k] == nan_level) frame[4] = 1;
  }
  max(frame);
  std::array<double, 1> drawn{double(order.size())};
  sum(drawn);
  L.drawn = std::size_t(drawn[0]);
  L.has_nan = frame[4] > 0;
  if (L.drawn == 0 && !slice) bad("field.x is empty in every part: there are no points to draw");
  if (L.drawn == 0)
    bad(fmt::format("options.slice_position = {} m holds no points: the body spans [{}, {}] m along axis {}", L.slice_position, -extent[0],
                    extent[1], o.axis));
  std::array<double, 2> lo{-frame[0] - 0.5 * L.point_size, -frame[1] - 0.5 * L.point_size},
      hi{frame[2] + 0.5 * L.point_size, frame[3] + 0.5 * L.point_size};
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

  // Squares of side h tile a lattice: each covers [c - h/2, c + h/2) rounded to whole pixels.
  // Round-off can put a shared edge on either side of a .5 tie, so the edges are pushed out
  // by a hair: neighbours then overlap by a pixel at worst, never leave a gap.
  s.pixels.assign(std::size_t(L.plot_w) * std::size_t(L.plot_h), Scene::empty);
  const double side = std::max(1.0, L.point_size * L.pixels_per_metre), half = 0.5 * side, grow = 0.02;
  for (std::size_t k = 0; k < order.size(); ++k) {
    const auto p = L.to_pixel(coord(0, order[k]), coord(1, order[k]));
    int c0 = int(std::lround(p[0] - half - grow)), r0 = int(std::lround(p[1] - half - grow));
    int c1 = std::max(c0 + 1, int(std::lround(p[0] + half + grow)));
    int r1 = std::max(r0 + 1, int(std::lround(p[1] + half + grow)));
    c0 = std::max(c0, L.plot_x) - L.plot_x, r0 = std::max(r0, L.plot_y) - L.plot_y;
    c1 = std::min(c1, L.plot_x + L.plot_w) - L.plot_x, r1 = std::min(r1, L.plot_y + L.plot_h) - L.plot_y;
    for (int r = r0; r < r1; ++r) {
      std::int16_t* row = s.pixels.data() + std::size_t(r) * std::size_t(L.plot_w);
      for (int c = c0; c < c1; ++c) row[c] = std::max(row[c], level[k]);
    }
  }
  if (!parts.one()) {
    parts.max_to_root(s.pixels);
    if (!parts.root) s.pixels = {};
  }
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
