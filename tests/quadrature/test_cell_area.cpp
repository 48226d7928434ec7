#include <catch2/catch.hpp>

#include <array>
#include <cmath>
#include <cstddef>
#include <numbers>
import peridot.quadrature;
import peridot.models;

using namespace peridot;

namespace {

constexpr double pi = std::numbers::pi;

// Area of disk(0, R) inside the square by the midpoint rule on an n x n sub-grid: independent of
// the closed form (no chord integrals, no breakpoints).
double sub_grid_area(double cx, double cy, double half, double R, int n) {
  const double d = 2 * half / n;
  long inside = 0;
  for (int a = 0; a < n; ++a)
    for (int b = 0; b < n; ++b) {
      const double x = cx - half + (a + 0.5) * d, y = cy - half + (b + 0.5) * d;
      inside += x * x + y * y <= R * R;
    }
  return double(inside) * d * d;
}

// An odd number of cells on each side, so one node sits at the origin, at least 2 delta + 2 h
// from every edge.
Body centred_lattice(double h, double mbar) {
  const int half = int(std::ceil(2 * mbar)) + 3;
  const double a = (half + 0.5) * h;
  Body b;
  b.points = lattice(rectangle({-a, -a, 0}, {a, a, 0}), {.spacing = h});
  b.bonds = cell_area_bonds(b.points, mbar * h);
  return b;
}

std::size_t centre_node(const PointCloud& pc) {
  std::size_t best = 0;
  for (std::size_t i = 0; i < pc.size(); ++i)
    if (std::hypot(pc.x[0][i], pc.x[1][i]) < std::hypot(pc.x[0][best], pc.x[1][best])) best = i;
  return best;
}

}  // namespace

TEST_CASE("disk square area is exact for squares fully in or out") {
  CHECK(disk_square_area(0.2, 0.1, 0.1, 1.0) == Approx(0.04).epsilon(1e-14));
  CHECK(disk_square_area(-0.6, 0.7, 0.05, 1.0) == Approx(0.01).epsilon(1e-14));
  CHECK(disk_square_area(2.0, 0.0, 0.1, 1.0) == 0.0);
  CHECK(disk_square_area(0.8, 0.8, 0.2, 1.0) > 0.0);
  CHECK(disk_square_area(0.9, 0.9, 0.1, 1.0) == 0.0);  // corner (0.8, 0.8) is outside
  CHECK(disk_square_area(0.0, 0.0, 1.0, 1.0) == Approx(pi).epsilon(1e-14));
  CHECK(disk_square_area(0.0, 0.0, 3.7, 2.0) == Approx(4 * pi).epsilon(1e-14));
}

TEST_CASE("four squares meeting at a point inside the disk cover it exactly") {
  const double R = 1.3, H = 1.5;
  for (auto [x0, y0] : {std::array{0.0, 0.0}, std::array{0.3, -0.45}, std::array{-1.1, 0.2}, std::array{0.9, 0.9}}) {
    double sum = 0;
    for (double sx : {-1.0, 1.0})
      for (double sy : {-1.0, 1.0}) sum += disk_square_area(x0 + sx * H, y0 + sy * H, H, R);
    CHECK(sum == Approx(pi * R * R).epsilon(1e-13));
  }
  // Symmetric quarters are each a quarter disk.
  CHECK(disk_square_area(0.75, 0.75, 0.75, 1.5) == Approx(pi * 1.5 * 1.5 / 4).epsilon(1e-14));
  CHECK(disk_square_area(-2.0, 2.0, 2.0, 1.5) == Approx(pi * 1.5 * 1.5 / 4).epsilon(1e-14));
}

TEST_CASE("disk square area agrees with a fine sub-grid count to 1e-4") {
  // Cut through one side, through a corner, through two opposite sides, around the disk's top,
  // lattice cells at m = 3 straddling the circle, and cells whose top or bottom side is tangent
  // to it (m = 3.5).
  const std::array<std::array<double, 4>, 8> cases{{{0.9, 0.3, 0.25, 1.0},
                                                    {0.7, 0.7, 0.1, 1.0},
                                                    {0.0, 0.95, 0.1, 1.0},
                                                    {0.97, 0.0, 0.2, 1.0},
                                                    {2.0, 2.0, 0.5, 3.0},
                                                    {3.0, 0.0, 0.5, 3.0},
                                                    {0.0, 3.0, 0.5, 3.5},
                                                    {0.0, -3.0, 0.5, 3.5}}};
  for (const auto& c : cases) {
    const double exact = disk_square_area(c[0], c[1], c[2], c[3]);
    const double cell = 4 * c[2] * c[2];
    CHECK(exact > 0.0);
    CHECK(exact < cell);
    CHECK(std::abs(exact - sub_grid_area(c[0], c[1], c[2], c[3], 1500)) < 1e-4 * cell);
  }
}

TEST_CASE("cell area families have 44 68 100 136 356 members") {
  const std::array<std::pair<double, std::size_t>, 5> expected{{{3, 44}, {4, 68}, {5, 100}, {6, 136}, {10, 356}}};
  for (auto [mbar, count] : expected) {
    const auto b = centred_lattice(0.01, mbar);
    const auto i = centre_node(b.points);
    CHECK(std::hypot(b.points.x[0][i], b.points.x[1][i]) < 1e-9);
    CHECK(b.bonds.count(i) == count);
    // Partial cells only at the rim; every weight is beta V with 0 < beta <= 1.
    for (auto k = b.bonds.begin(i); k < b.bonds.end(i); ++k) {
      CHECK(b.bonds.weight[k] > 0.0);
      CHECK(b.bonds.weight[k] <= b.points.volume[i] * (1 + 1e-12));
    }
  }
}

TEST_CASE("discrete full weighted volume is eq. (44) of seed 004 over exact cell fractions, just below the continuum value") {
  // Seed 004 eq. (44) with the Gaussian influence of eq. (15) and beta the fraction of each cell
  // inside the disk (Sec. 4.2): m / h^4 = sum over lattice offsets (a, b) of
  // exp(-(a^2 + b^2) / mbar^2) (a^2 + b^2) beta_ab. The table holds that sum (8 figures), which
  // the loop below also forms from disk_square_area, checked against a sub-grid count above.
  // Eq. (13) over the disk gives pi delta^4 (1 - 2/e) (67.241174 h^4 at mbar = 3); the lattice
  // sum lies below it by a gap that falls like mbar^-3 (0.13 % at mbar = 3, 0.0025 % at 10).
  const std::array<std::pair<double, double>, 5> expected{
      {{3, 67.155051}, {4, 212.394885}, {5, 518.679433}, {6, 1075.713499}, {10, 8301.172635}}};
  const double h = 0.01;
  for (auto [mbar, m_ref] : expected) {
    INFO("mbar = " << mbar);
    Body b = centred_lattice(h, mbar);
    auto osb = Osb::make(1e9, 0.2, Kinematics::plane_stress, mbar * h);
    osb.weigh(b);
    const double m = osb.m[centre_node(b.points)] / std::pow(h, 4);
    CHECK(m == Approx(m_ref).epsilon(1e-8));
    double sum = 0;
    const int reach = int(std::ceil(mbar)) + 1;
    for (int a = -reach; a <= reach; ++a)
      for (int c = -reach; c <= reach; ++c) {
        const double r2 = double(a * a + c * c);
        sum += std::exp(-r2 / (mbar * mbar)) * r2 * disk_square_area(a, c, 0.5, mbar);
      }
    CHECK(sum == Approx(m_ref).epsilon(1e-8));
    const double gap = 1 - m / (pi * std::pow(mbar, 4) * (1 - 2 / std::numbers::e));
    CHECK(gap > 0);
    CHECK(gap < 0.04 / (mbar * mbar * mbar));
  }
}
