// peridot-bench-analysis: cost of the observers (fragment counting, crack-tip tracking) on
// a 2D body with about 10^6 directed bonds, next to one PMB force pass on the same body.
//   usage: peridot-bench-analysis [repetitions]
#include <CLI/CLI.hpp>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <vector>
#include <fmt/core.h>
import peridot.analysis;

namespace {

using namespace peridot;
using Clock = std::chrono::steady_clock;

struct Timing {
  double median, min;  // [ms per call]
};

// Wall time of f() over reps calls after one warm-up call. The median and the minimum are
// robust to other load on the machine, unlike the mean.
template <class F>
Timing time_ms(int reps, F&& f) {
  f();
  std::vector<double> ms(static_cast<std::size_t>(reps));
  for (auto& m : ms) {
    const auto t0 = Clock::now();
    f();
    m = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  }
  std::sort(ms.begin(), ms.end());
  return {ms[ms.size() / 2], ms.front()};
}

void report(const char* what, Timing t) { fmt::print("  {:<24} {:8.3f} ms/call median, {:8.3f} min\n", what, t.median, t.min); }

}  // namespace

int main(int argc, char** argv) {
  int reps = 20;
  CLI::App app{"peridot-bench-analysis: fragment counting and crack-tip tracking beside one PMB force pass"};
  app.add_option("repetitions", reps, "timed calls per measurement")->check(CLI::Range(1, 100000));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  // 200 x 100 points, delta = 4 h: about 50 bonds per point.
  const double h = 1e-3, delta = 4 * h;
  Body body;
  body.points = lattice(rectangle({0, 0, 0}, {0.2, 0.1, 0}), {.spacing = h});
  body.bonds = build_bonds(body.points, {.horizon = delta, .cracks = {CrackSegment{{-0.01, 0.05, 0}, {0.05, 0.05, 0}}}});
  body.density = 2440;
  State state(body.size());
  const auto pmb = Pmb::from_elastic(72e9, 3.8, delta, Kinematics::plane_stress);

  // For the tracker: a fully damaged band ahead of the notch.
  std::vector<double> phi(body.size(), 0.0), nodal;
  for (std::size_t i = 0; i < body.size(); ++i) {
    const auto p = body.points.position(i);
    if (p[0] > 0.05 && p[0] < 0.12 && std::abs(p[1] - 0.05) < h) phi[i] = 1;
  }

  fmt::print("peridot-bench-analysis: {} points, {} directed bonds, {} OpenMP threads, {} repetitions\n", body.size(),
             body.bonds.size(), omp_get_max_threads(), reps);
  FragmentReport fragments;
  const Timing frag = time_ms(reps, [&] { fragments = count_fragments(body); });
  const Timing force = time_ms(reps, [&] { pmb.forces(body, state.u, state.f); });
  const Timing dmg = time_ms(reps, [&] { damage(body, nodal); });
  double t = 0;
  const Timing tip = time_ms(reps, [&] {
    CrackTipTracker tracker({.origin = {0.05, 0.05, 0}, .direction = Vec3{1, 0, 0}});
    tracker.update(body.points, phi, t += 1e-6);
  });

  report("count_fragments", frag);
  report("PMB force pass", force);
  report("nodal damage", dmg);
  report("CrackTipTracker::update", tip);
  fmt::print("  count_fragments / PMB force pass: {:.2f} (median), {:.2f} (min); {} fragment(s), {} debris\n",
             frag.median / force.median, frag.min / force.min, fragments.count, fragments.debris);
  return 0;
}
