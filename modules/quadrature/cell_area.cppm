export module peridot.quadrature:cell_area;
import peridot.std;
import peridot.discretization;

export namespace peridot {

// Area of the intersection of the disk |x| <= R (centred at the origin) with the square of
// half-width `half` centred at (cx, cy), in closed form: the integral over x of the chord
// length clipped to [cy - half, cy + half], piecewise between the points where the clipping
// changes, each piece by the antiderivative of sqrt(R^2 - x^2).
double disk_square_area(double cx, double cy, double half, double R);

// Bonds of a 2D lattice cloud with the exact partial-volume factors of seed 004 Sec. 4.2:
// the family of i is every point whose cell (edge h, centred on it) overlaps the disk of
// radius `horizon` around x_i with positive area, and the weight of partner j is
// beta_ij V_j, beta_ij the fraction of j's cell inside the disk. The quadrature point stays
// at the node. Bonds listed in `cracks` are never created.
BondList cell_area_bonds(const PointCloud& points, double horizon, const std::vector<Crack>& cracks = {});

}  // namespace peridot

namespace peridot {

namespace {

// Antiderivative of sqrt(R^2 - x^2) on [-R, R].
double chord_integral(double x, double R) {
  const double t = std::clamp(x / R, -1.0, 1.0);
  return 0.5 * R * R * (t * std::sqrt(std::max(0.0, 1 - t * t)) + std::asin(t));
}

}  // namespace

double disk_square_area(double cx, double cy, double half, double R) {
  const double x1 = std::max(cx - half, -R), x2 = std::min(cx + half, R);
  const double y1 = cy - half, y2 = cy + half;
  if (!(x2 > x1)) return 0.0;
  // Breakpoints: where the circle's upper or lower branch meets y1 or y2.
  std::array<double, 6> pts{};
  std::size_t np = 0;
  pts[np++] = x1;
  pts[np++] = x2;
  for (double y : {y1, y2})
    if (std::abs(y) < R) {
      const double s = std::sqrt(R * R - y * y);
      for (double x : {-s, s})
        if (x > x1 && x < x2) pts[np++] = x;
    }
  std::sort(pts.begin(), pts.begin() + long(np));
  double area = 0;
  for (std::size_t k = 0; k + 1 < np; ++k) {
    const double a = pts[k], b = pts[k + 1];
    if (!(b > a)) continue;
    // On (a, b) the clipped chord [max(y1, -s), min(y2, s)] has one form; pick it at the middle.
    // Ties go to the circle: a side at |y| = R touches it only at x = 0, which is no breakpoint.
    const double m = 0.5 * (a + b), s = std::sqrt(std::max(0.0, R * R - m * m));
    const bool top_is_circle = s <= y2, bottom_is_circle = -s >= y1;
    if ((top_is_circle ? s : y2) <= (bottom_is_circle ? -s : y1)) continue;
    const double S = chord_integral(b, R) - chord_integral(a, R);
    area += (top_is_circle ? S : y2 * (b - a)) - (bottom_is_circle ? -S : y1 * (b - a));
  }
  return std::max(area, 0.0);
}

BondList cell_area_bonds(const PointCloud& pc, double horizon, const std::vector<Crack>& cracks) {
  if (pc.dim != 2) throw std::invalid_argument("cell-area quadrature: only 2D lattices");
  const double h = pc.spacing;
  if (!(h > 0) || !(horizon > 0)) throw std::invalid_argument("cell-area quadrature: need a lattice spacing and a horizon > 0");
  // Every cell that can touch the disk: centre within delta + h / sqrt(2).
  auto all = build_bonds(pc, {.horizon = horizon + 0.5 * std::sqrt(2.0) * h, .cracks = cracks});
  BondList bl;
  bl.horizon = horizon;
  bl.offset.assign(pc.size() + 1, 0);
  for (std::size_t i = 0; i < pc.size(); ++i) {
    for (auto b = all.begin(i); b < all.end(i); ++b) {
      const double beta = disk_square_area(all.xi[0][b], all.xi[1][b], 0.5 * h, horizon) / (h * h);
      if (!(beta > 0)) continue;
      bl.neighbor.push_back(all.neighbor[b]);
      for (int k = 0; k < 3; ++k) bl.xi[k].push_back(all.xi[k][b]);
      bl.length.push_back(all.length[b]);
      bl.weight.push_back(beta * pc.volume[std::size_t(all.neighbor[b])]);
      bl.intact.push_back(all.intact[b]);
    }
    bl.offset[i + 1] = std::int64_t(bl.neighbor.size());
  }
  return bl;
}

}  // namespace peridot
