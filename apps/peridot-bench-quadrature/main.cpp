// peridot-bench-quadrature: wall time of the GMLS quadrature weights on a 2D lattice of
// side x side points with full balls (a ghost margin around them), at delta = 3.5h and 4h,
// uniform and 0.2h-perturbed, at 1 and 2 OpenMP threads, with the per-point diagnostics.
//   usage: peridot-bench-quadrature [side = 317] [repetitions = 3]
#include <CLI/CLI.hpp>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <vector>
#include <fmt/core.h>
import peridot.quadrature;

namespace {

using namespace peridot;

struct Cloud {
  PointCloud points;
  BondList bonds;
  std::vector<std::uint8_t> active;
  std::size_t active_count = 0;
};

// side^2 active points inside a margin of ceil(delta/h) + 1 cells, so every active ball is full.
Cloud make_cloud(int side, double factor, double perturbation) {
  const double h = 1.0 / side;
  const int margin = int(std::ceil(factor)) + 1;
  const double extent = (side + 2 * margin) * h;
  Cloud c;
  c.points = lattice(rectangle({0, 0, 0}, {extent, extent, 0}), {.spacing = h, .perturbation = perturbation, .seed = 2});
  c.bonds = build_bonds(c.points, {.horizon = factor * h});
  c.active.assign(c.points.size(), 0);
  for (std::size_t i = 0; i < c.points.size(); ++i) {
    bool inside = true;  // the jitter (< h/2) never moves a point across a cell edge
    for (int k = 0; k < 2; ++k) inside = inside && c.points.x[k][i] > margin * h && c.points.x[k][i] < extent - margin * h;
    c.active[i] = inside;
    c.active_count += inside;
  }
  return c;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(v.size() / 2), v.end());
  return v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  int side = 317, reps = 3;
  CLI::App app{"peridot-bench-quadrature: GMLS weights per 1e5 points, residuals and conditioning"};
  app.add_option("side", side, "points per side")->check(CLI::Range(20, 10000));
  app.add_option("repetitions", reps, "best of this many calls")->check(CLI::Range(1, 1000));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  const int max_threads = omp_get_max_threads();
  fmt::print("peridot-bench-quadrature: {0}x{0} points with full balls, best of {1} repetitions, up to {2} threads\n",
             side, reps, max_threads);
  fmt::print("{:>7} {:>6} {:>9} {:>8} {:>7} {:>12} {:>12} {:>10} {:>10} {:>10} {:>9}\n", "delta/h", "pert", "points",
             "bonds/pt", "threads", "s/call", "s/1e5 pts", "max resid", "max cond", "med cond", "negative");
  for (double factor : {3.5, 4.0})
    for (double perturbation : {0.0, 0.2}) {
      Cloud c = make_cloud(side, factor, perturbation);
      for (int threads : {1, 2}) {
        if (threads > 1 && max_threads < 2) break;
        omp_set_num_threads(threads);
        QuadratureReport rep;
        double best = 1e300;
        for (int r = 0; r < reps; ++r) {
          rep = compute_weights(c.points, c.bonds, {.active = c.active});
          best = std::min(best, rep.seconds);
        }
        std::vector<double> cond;
        for (std::size_t i = 0; i < c.points.size(); ++i)
          if (c.active[i]) cond.push_back(rep.condition[i]);
        fmt::print("{:>7.1f} {:>6.1f} {:>9} {:>8.1f} {:>7} {:>12.4f} {:>12.4f} {:>10.2e} {:>10.3g} {:>10.3g} {:>9}\n", factor,
                   perturbation, rep.points, double(rep.bonds) / double(rep.points), threads, best,
                   best * 1e5 / double(rep.points), rep.max_residual, rep.max_condition, median(cond),
                   rep.total_negative);
      }
      omp_set_num_threads(max_threads);
    }
  return 0;
}
