export module peridot.render:spacing;
import peridot.std;

export namespace peridot {

// Length scales of a point cloud given as coordinate arrays (the first `dim` are used).
struct PointSpacing {
  double spacing = 1;     // median nearest-neighbour distance [m]: exact for lattices
  double solid_size = 1;  // side of squares that cover the body without gaps [m]
};

// Samples up to ~2000 points and finds their two nearest neighbours with a cell grid.
// On a lattice every point has two neighbours at the spacing, so solid_size = spacing.
// Perturbed clouds have a nearest neighbour closer than the second; squares then must
// grow to close the gaps, by a factor fitted to cover every pixel of randomly perturbed
// lattices (perturbations up to 0.45 h): 1 + 5 s + 14 s^2, s = 1 - median(d1 / d2).
// A single point, or coincident points only, gives 1 m.
PointSpacing estimate_spacing(const std::array<std::span<const double>, 3>& x, int dim);

// The same estimate for a cloud held in parts (N ranks), in three steps:
//   1. the sampled points are those whose (global) index is a multiple of spacing_sample_stride;
//   2. each part finds, for its sampled points, the distances to their nearest and second
//      nearest distinct points among the points it holds (nearest_distances, exact whatever
//      the cells): a part that holds each sample's neighbours (its ghosts a horizon deep) finds
//      the one-part distances;
//   3. spacing_from_nearest of every part's pairs together, in any order, is estimate_spacing.
std::size_t spacing_sample_stride(std::size_t points);
std::vector<double> nearest_distances(const std::array<std::span<const double>, 3>& x, int dim, std::span<const std::size_t> queries);
PointSpacing spacing_from_nearest(std::span<const double> pairs);

}  // namespace peridot

namespace peridot {

PointSpacing estimate_spacing(const std::array<std::span<const double>, 3>& x, int dim) {
  const std::size_t n = x[0].size();
  if (n < 2) return {};
  std::vector<std::size_t> sample;
  const std::size_t stride = spacing_sample_stride(n);
  for (std::size_t i = 0; i < n; i += stride) sample.push_back(i);
  return spacing_from_nearest(nearest_distances(x, dim, sample));
}

std::vector<double> nearest_distances(const std::array<std::span<const double>, 3>& x, int dim, std::span<const std::size_t> queries) {
  const std::size_t n = x[0].size();
  std::vector<double> out(2 * queries.size(), std::numeric_limits<double>::infinity());
  if (n == 0) return out;
  std::array<double, 3> lo{0, 0, 0}, ext{0, 0, 0};
  double filled = 1;  // measure of the bounding box over its non-degenerate axes
  int axes = 0;
  for (int k = 0; k < dim; ++k) {
    const auto [mn, mx] = std::minmax_element(x[k].begin(), x[k].end());
    lo[k] = *mn;
    ext[k] = *mx - *mn;
    if (ext[k] > 0) {
      filled *= ext[k];
      ++axes;
    }
  }
  if (axes == 0) return out;  // every point coincides: no length scale at all
  // Cell size from the bounding box: never smaller than the spacing of a filled shape, so a
  // 3^d cell neighbourhood mostly holds each point's two nearest neighbours.
  double cell = std::pow(filled / double(n), 1.0 / axes);
  std::array<std::int64_t, 3> cells{1, 1, 1};
  for (;;) {
    std::int64_t total = 1;
    for (int k = 0; k < dim; ++k) {
      cells[k] = ext[k] > 0 ? std::int64_t(ext[k] / cell) + 1 : 1;
      total *= cells[k];
    }
    if (total <= std::int64_t(4 * n) + 64) break;
    cell *= 1.5;  // keeps the grid O(n) for sparse, elongated clouds
  }
  auto cell_of = [&](std::size_t i) {
    std::array<std::int64_t, 3> c{0, 0, 0};
    for (int k = 0; k < dim; ++k) c[k] = std::min<std::int64_t>(cells[k] - 1, std::int64_t((x[k][i] - lo[k]) / cell));
    return c;
  };
  auto flat = [&](const std::array<std::int64_t, 3>& c) { return (c[2] * cells[1] + c[1]) * cells[0] + c[0]; };
  // Counting sort of the points into cells (CSR).
  std::vector<std::uint32_t> start(std::size_t(cells[0] * cells[1] * cells[2]) + 1, 0);
  std::vector<std::uint32_t> cell_index(n);
  for (std::size_t i = 0; i < n; ++i) {
    cell_index[i] = std::uint32_t(flat(cell_of(i)));
    ++start[cell_index[i] + 1];
  }
  for (std::size_t c = 1; c < start.size(); ++c) start[c] += start[c - 1];
  std::vector<std::uint32_t> members(n);
  {
    std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
    for (std::size_t i = 0; i < n; ++i) members[fill[cell_index[i]]++] = std::uint32_t(i);
  }
  // Rings of cells around the query's until the second nearest is nearer than any point
  // outside them (r cells away at least): exact, so any part holding the neighbours agrees.
  for (std::size_t q = 0; q < queries.size(); ++q) {
    const std::size_t i = queries[q];
    const auto c = cell_of(i);
    double d1 = std::numeric_limits<double>::infinity(), d2 = d1;  // squared, d1 <= d2
    for (std::int64_t r = 1;; ++r) {
      std::array<std::int64_t, 3> lo_c{0, 0, 0}, hi_c{0, 0, 0};
      bool whole = true;
      for (int k = 0; k < dim; ++k) {
        lo_c[k] = std::max<std::int64_t>(0, c[k] - r);
        hi_c[k] = std::min<std::int64_t>(cells[k] - 1, c[k] + r);
        whole = whole && lo_c[k] == 0 && hi_c[k] == cells[k] - 1;
      }
      for (auto cz = lo_c[2]; cz <= hi_c[2]; ++cz)
        for (auto cy = lo_c[1]; cy <= hi_c[1]; ++cy)
          for (auto cx = lo_c[0]; cx <= hi_c[0]; ++cx) {
            const std::int64_t ring = std::max({std::abs(cx - c[0]), std::abs(cy - c[1]), std::abs(cz - c[2])});
            if (r > 1 && ring < r) continue;  // scanned in an inner ring
            const auto f = flat({cx, cy, cz});
            for (auto m = start[f]; m < start[f + 1]; ++m) {
              const std::size_t j = members[m];
              double d = 0;
              for (int k = 0; k < dim; ++k) d += (x[k][j] - x[k][i]) * (x[k][j] - x[k][i]);
              if (d == 0) continue;  // duplicates carry no length scale
              if (d < d1) d2 = d1, d1 = d;
              else if (d < d2) d2 = d;
            }
          }
      if (whole || d2 <= double(r) * double(r) * cell * cell) break;
    }
    out[2 * q] = std::sqrt(d1);
    out[2 * q + 1] = std::sqrt(d2);
  }
  return out;
}

std::size_t spacing_sample_stride(std::size_t points) { return std::max<std::size_t>(1, points / 2000); }

PointSpacing spacing_from_nearest(std::span<const double> pairs) {
  std::vector<double> nearest, ratio;
  nearest.reserve(pairs.size() / 2);
  ratio.reserve(pairs.size() / 2);
  for (std::size_t q = 0; q + 1 < pairs.size(); q += 2) {
    if (std::isfinite(pairs[q])) nearest.push_back(pairs[q]);
    if (std::isfinite(pairs[q + 1])) ratio.push_back(pairs[q] / pairs[q + 1]);
  }
  if (nearest.empty()) return {};
  auto median = [](std::vector<double>& v) {
    auto mid = v.begin() + std::ptrdiff_t(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    return *mid;
  };
  const double h = median(nearest);
  const double s = ratio.empty() ? 0.0 : 1.0 - median(ratio);
  return {h, h * (1 + 5 * s + 14 * s * s)};
}

}  // namespace peridot
