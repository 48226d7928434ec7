#include <catch2/catch.hpp>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <algorithm>
#include <array>
#include <map>
#include <stdexcept>
#include <utility>
#include <vector>
import peridot.discretization;
import peridot.quadrature;

using namespace peridot;

namespace {

constexpr double h = 0.01;

PointCloud plate(int nx, int ny) { return lattice(rectangle({0.1, -0.2, 0}, {0.1 + nx * h, -0.2 + ny * h, 0}), {.spacing = h}); }

// The crossings of `s` by brute force in floating point, from the real coordinates: intersect
// each bond's segment with the line, alpha = 1/2 at either end of `s` or of the bond.
std::map<std::size_t, double> brute_force(const LatticeGrid& g, const PointCloud& pc, const BondList& bl, const GridSegment& s, int direction,
                                          bool typed) {
  const double tol = 1e-9 * h;
  const int a = s.axis, o = 1 - s.axis;
  const double line = (a == 0 ? g.x0 : g.y0) + 0.5 * double(s.line) * h;
  const double centre = (a == 0 ? g.y0 : g.x0) + double(s.centre) * h;
  std::map<std::size_t, double> out;
  for (std::size_t j = 0; j < pc.size(); ++j)
    for (auto b = bl.begin(j); b < bl.end(j); ++b) {
      const double da = bl.xi[std::size_t(a)][b], dox = bl.xi[std::size_t(o)][b];
      if (std::abs(da) < tol) continue;
      if (direction * da < 0) continue;
      const double ax = std::abs(bl.xi[0][b]), ay = std::abs(bl.xi[1][b]);
      if (typed && (a == 0 ? ax < ay - tol : ay <= ax + tol)) continue;
      const double t = (line - pc.x[std::size_t(a)][j]) / da;
      if (t < -tol / h || t > 1 + tol / h) continue;
      const double dist = std::abs(pc.x[std::size_t(o)][j] + t * dox - centre);
      if (dist > 0.5 * h + tol) continue;
      const bool end = std::abs(t) * std::abs(da) < tol || std::abs(1 - t) * std::abs(da) < tol || std::abs(dist - 0.5 * h) < tol;
      out[std::size_t(b)] = end ? 0.5 : 1.0;
    }
  return out;
}

std::map<std::size_t, double> enumerated(const LatticeGrid& g, const BondList& bl, const GridSegment& s, int direction, bool typed) {
  std::map<std::size_t, double> out;
  for_each_crossing(g, bl, s, direction, typed, [&](std::size_t b, double alpha) {
    CHECK(out.count(b) == 0);  // each directed bond at most once
    out[b] = alpha;
  });
  return out;
}

// Sum of alpha per bond offset (p, q), p along the segment's normal.
std::map<std::pair<int, int>, double> alpha_per_offset(const LatticeGrid& g, const BondList& bl, const GridSegment& s, int direction,
                                                       bool typed) {
  const auto owner = [&](std::size_t b) {
    std::size_t j = 0;
    while (bl.end(j) <= std::int64_t(b)) ++j;
    return j;
  };
  std::map<std::pair<int, int>, double> sum;
  for_each_crossing(g, bl, s, direction, typed, [&](std::size_t b, double alpha) {
    const auto j = owner(b), k = std::size_t(bl.neighbor[b]);
    const int dx = g.gx[k] - g.gx[j], dy = g.gy[k] - g.gy[j];
    sum[s.axis == 0 ? std::pair{dx, dy} : std::pair{dy, dx}] += alpha;
  });
  return sum;
}

}  // namespace

TEST_CASE("lattice grid maps a lattice to integer coordinates") {
  const auto pc = plate(9, 6);
  const auto g = lattice_grid(pc);
  REQUIRE(g.gx.size() == pc.size());
  CHECK(g.h == h);
  CHECK(g.n[0] == 9);
  CHECK(g.n[1] == 6);
  for (std::size_t i = 0; i < pc.size(); ++i) {
    CHECK(std::abs(g.x0 + g.gx[i] * h - pc.x[0][i]) < 1e-12);
    CHECK(std::abs(g.y0 + g.gy[i] * h - pc.x[1][i]) < 1e-12);
    CHECK(g.at(g.gx[i], g.gy[i]) == std::int32_t(i));
  }
  CHECK(g.at(g.lo[0] - 1, g.lo[1]) == -1);
  CHECK(g.at(g.lo[0], g.lo[1] + g.n[1]) == -1);
}

TEST_CASE("lattice grid rejects off lattice points and names them") {
  auto pc = plate(5, 4);
  pc.x[0][7] += 0.3 * h;
  CHECK_THROWS_WITH(lattice_grid(pc), Catch::Contains("point 7"));
  auto twin = plate(5, 4);
  twin.x[0][3] = twin.x[0][2], twin.x[1][3] = twin.x[1][2];
  CHECK_THROWS_WITH(lattice_grid(twin), Catch::Contains("share a lattice site"));
  auto holes = plate(5, 4);
  holes.x[1][0] += 1e-9 * h;  // within tolerance: still on the lattice
  CHECK_NOTHROW(lattice_grid(holes));
}

TEST_CASE("crossings equal a floating point segment intersection test") {
  // A plate with edges and corners, so partial neighbourhoods are covered too; cell-area bonds
  // (reach delta + h / sqrt 2) and plain bonds with a non-integer horizon.
  const auto pc = plate(14, 11);
  const auto g = lattice_grid(pc);
  for (const auto& bl : {cell_area_bonds(pc, 3 * h), build_bonds(pc, {.horizon = 2.6 * h})}) {
    std::size_t total = 0, halves = 0;
    for (int axis = 0; axis < 2; ++axis)
      for (std::int64_t line = 2 * (axis == 0 ? g.lo[0] : g.lo[1]) - 3; line <= 2 * (g.lo[axis] + g.n[axis]) + 2; ++line)
        for (std::int64_t c = g.lo[1 - axis] - 1; c <= g.lo[1 - axis] + g.n[1 - axis]; c += 3) {
          const GridSegment s{axis, line, c};
          for (int direction : {-1, 0, 1})
            for (bool typed : {false, true}) {
              const auto want = brute_force(g, pc, bl, s, direction, typed);
              const auto got = enumerated(g, bl, s, direction, typed);
              REQUIRE(got == want);  // one grid segment: a few entries
              total += got.size();
              for (const auto& [b, alpha] : got) halves += alpha == 0.5;
            }
        }
    CHECK(total > 10000);
    CHECK(halves > 1000);
  }
}

TEST_CASE("every node's segment crossings, found bond by bond, equal the floating point intersection test at that node") {
  // for_each_node_crossing finds the pairs of eq. (51) from the bonds; the reference tests each
  // node's own segment (typed, either way) against every bond in floating point.
  const auto pc = plate(12, 9);
  const auto g = lattice_grid(pc);
  for (const auto& bl : {cell_area_bonds(pc, 3 * h), build_bonds(pc, {.horizon = 3.6 * h})}) {
    std::vector<std::array<std::map<std::size_t, double>, 2>> got(pc.size());
    std::size_t repeats = 0;
    for_each_node_crossing(g, bl, [&](std::size_t i, std::size_t b, double alpha, std::size_t start, int axis) {
      CHECK(bl.begin(start) <= std::int64_t(b));
      CHECK(std::int64_t(b) < bl.end(start));
      repeats += got[i][std::size_t(axis)].count(b);
      got[i][std::size_t(axis)][b] = alpha;
    });
    CHECK(repeats == 0);  // each (node, bond) pair at most once
    std::size_t total = 0, halves = 0;
    for (std::size_t i = 0; i < pc.size(); ++i)
      for (int axis = 0; axis < 2; ++axis) {
        const GridSegment s{axis, 2 * std::int64_t(axis == 0 ? g.gx[i] : g.gy[i]), axis == 0 ? g.gy[i] : g.gx[i]};
        const auto want = brute_force(g, pc, bl, s, 0, true);
        INFO("node " << i << ", axis " << axis);
        REQUIRE(got[i][std::size_t(axis)] == want);  // one node's segment: a few dozen entries
        total += want.size();
        for (const auto& [b, alpha] : want) halves += alpha == 0.5;
      }
    CHECK(total > 5000);
    CHECK(halves > 1000);
  }
}

TEST_CASE("alpha over one bond offset sums to its normal component") {
  // A segment far from the edges sees every bond of offset (p, q) cross it with total weight |p|:
  // |p| columns (cell side) or |p| + 1 columns with the end ones halved (node segment), and one
  // weighted row per column.
  const auto pc = plate(25, 25);
  const auto g = lattice_grid(pc);
  const auto bl = cell_area_bonds(pc, 3 * h);
  std::map<std::pair<int, int>, int> family;  // offsets of a bulk node, normal component first
  const auto centre = std::size_t(g.at(g.lo[0] + 12, g.lo[1] + 12));
  for (auto b = bl.begin(centre); b < bl.end(centre); ++b) {
    const auto k = std::size_t(bl.neighbor[b]);
    ++family[{g.gx[k] - g.gx[centre], g.gy[k] - g.gy[centre]}];
  }
  REQUIRE(family.size() == 44);
  for (int axis = 0; axis < 2; ++axis)
    for (std::int64_t line : {2 * std::int64_t(g.lo[axis] + 12), 2 * std::int64_t(g.lo[axis] + 12) + 1})
      for (int direction : {-1, 0, 1})
        for (bool typed : {false, true}) {
          const GridSegment s{axis, line, g.lo[1 - axis] + 12};
          const auto sum = alpha_per_offset(g, bl, s, direction, typed);
          std::size_t expected_offsets = 0;
          for (const auto& [off, count] : family) {
            const int p = axis == 0 ? off.first : off.second, q = axis == 0 ? off.second : off.first;
            const bool wanted = p != 0 && direction * p >= 0 && (!typed || (axis == 0 ? std::abs(p) >= std::abs(q) : std::abs(p) > std::abs(q)));
            const auto it = sum.find({p, q});
            if (!wanted) {
              CHECK(it == sum.end());
              continue;
            }
            ++expected_offsets;
            REQUIRE(it != sum.end());
            CHECK(it->second == double(std::abs(p)));
          }
          CHECK(sum.size() == expected_offsets);
        }
}

// N ranks build static OSB parts from boxes of sites: each part must be the whole cloud's points,
// bit for bit, in the same order, with their indices there; and a row far enough from the box's
// edge must hold the whole cloud's bonds, partner for partner, with the same weights.
TEST_CASE("a rectangle with a layer made box by box holds the whole cloud's points, indices and inner bond rows") {
  const Vec3 lo{-0.15, -0.1, 0}, hi{0.15, 0.1, 0};
  const double dx = 0.01, delta = 3 * dx;
  for (int layers : {0, 3}) {
    INFO(layers << " layers");
    const PointCloud whole = rectangle_with_layer(lo, hi, dx, layers);
    const BondList all = cell_area_bonds(whole, delta);
    const std::int64_t m0 = 30 + 2 * layers, m1 = 20 + 2 * layers;
    // Four boxes tiling the grown grid, and one grown past its edges.
    const std::vector<std::array<std::int64_t, 4>> tiles{{0, 11, 0, 7}, {11, m0, 0, 7}, {0, 11, 7, m1}, {11, m0, 7, m1}};
    std::vector<int> seen(whole.size(), 0);
    for (const auto& box : tiles) {
      std::vector<std::int64_t> ids, sites;
      const PointCloud part = rectangle_with_layer_part(lo, hi, dx, layers, box, &ids, &sites);
      REQUIRE(part.size() == ids.size());
      REQUIRE(std::size_t((box[1] - box[0]) * (box[3] - box[2])) == part.size());
      for (std::size_t q = 0; q < part.size(); ++q) {
        const auto i = std::size_t(ids[q]);
        REQUIRE(i < whole.size());
        if (q > 0) REQUIRE(ids[q] > ids[q - 1]);
        ++seen[i];
        CHECK(part.x[0][q] == whole.x[0][i]);
        CHECK(part.x[1][q] == whole.x[1][i]);
        CHECK(part.role[q] == whole.role[i]);
        CHECK(part.volume[q] == whole.volume[i]);
        CHECK(sites[q] % m0 >= box[0]);
        CHECK(sites[q] / m0 < box[3]);
      }
    }
    CHECK(std::count(seen.begin(), seen.end(), 1) == std::ptrdiff_t(whole.size()));
    // A box grown past the grid: clipped; rows four cells inside it are whole.
    std::vector<std::int64_t> ids, sites;
    const PointCloud part = rectangle_with_layer_part(lo, hi, dx, layers, {-5, 18, 3, m1 + 5}, &ids, &sites);
    const BondList mine = cell_area_bonds(part, delta);
    std::size_t rows = 0;
    for (std::size_t q = 0; q < part.size(); ++q) {
      const std::int64_t x = sites[q] % m0, y = sites[q] / m0;
      if (x >= 18 - 4 || y < 3 + 4) continue;
      ++rows;
      const auto i = std::size_t(ids[q]);
      REQUIRE(mine.count(q) == all.count(i));
      for (std::int64_t k = 0; k < std::int64_t(mine.count(q)); ++k) {
        CHECK(ids[std::size_t(mine.neighbor[std::size_t(mine.offset[q] + k)])] == all.neighbor[std::size_t(all.offset[i] + k)]);
        CHECK(mine.weight[std::size_t(mine.offset[q] + k)] == all.weight[std::size_t(all.offset[i] + k)]);
      }
    }
    CHECK(rows > 100);
  }
}
