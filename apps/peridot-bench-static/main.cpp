// peridot-bench-static: timings of the static LPS pipeline on the manufactured-solution deck
// (seed 000 Sec. 5.2, Dirichlet): GMLS weights per 1e5 points, assembly and solve with each
// linear solver, and the peak resident memory, for N x N cells.
#include <sys/resource.h>

#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <numbers>
#include <string>
#include <vector>
#include <fmt/core.h>
import peridot.problem;

using namespace peridot;

namespace {

double peak_rss_mb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_maxrss) / 1024.0;
}

const char* name(LinearSolver s) {
  switch (s) {
    case LinearSolver::umfpack: return "umfpack";
    case LinearSolver::sparse_lu: return "sparse_lu";
    default: return "bicgstab_ilut";
  }
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<int> cells{64, 128, 256};
  bool direct_only = false;
  CLI::App app{"peridot-bench-static: static LPS weights, assembly and solve per linear solver, and peak memory"};
  app.add_option("cells", cells, "N x N cells (default 64 128 256)")->check(CLI::Range(4, 4096));
  app.add_flag("--direct-only", direct_only, "UMFPACK only");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  std::vector<LinearSolver> solvers{LinearSolver::umfpack, LinearSolver::sparse_lu, LinearSolver::bicgstab_ilut};
  if (direct_only) solvers = {LinearSolver::umfpack};
  try {
    const Problem base = read_deck(std::string(PERIDOT_SOURCE_DIR) + "/data/decks/lps/sine_dirichlet.yaml");
    fmt::print("{:>5} {:>9} {:>9} {:>12} {:>10} {:>14} {:>10} {:>10} {:>12} {:>9}\n", "N", "points", "unknowns", "weights[s]",
               "per 1e5", "solver", "assembly", "solve", "error u", "peak MB");
    for (int n : cells) {
      Problem p = base;
      p.lattice.spacing = std::numbers::pi / n;
      p.horizon = 3.5 * p.lattice.spacing;
      const auto s = setup_static(p);
      for (auto solver : solvers) {
        StaticOptions o = s.options;
        o.solver = solver;
        o.tolerance = 1e-10;
        if (solver == LinearSolver::sparse_lu && n > 128) {
          fmt::print("{:>5} {:>9} {:>9} {:>12} {:>10} {:>14} skipped (Eigen SparseLU above N = 128 takes minutes)\n", n, "", "", "", "", name(solver));
          continue;
        }
        const auto r = solve_static_lps(s.body, s.model, s.problem, o);
        const auto e = static_errors(s, r);
        fmt::print("{:>5} {:>9} {:>9} {:>12.3f} {:>10.3f} {:>14} {:>10.3f} {:>10.3f} {:>12.4e} {:>9.0f}\n", n, s.body.size(), r.unknowns,
                   s.quadrature.seconds, s.quadrature.seconds * 1e5 / double(s.quadrature.points), name(solver), r.assembly_seconds,
                   r.solve_seconds, e.u, peak_rss_mb());
        std::fflush(stdout);
      }
    }
  } catch (const std::exception& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return 1;
  }
  return 0;
}
