// peridot-bench-static: timings of the static LPS pipeline on the manufactured-solution deck
// (seed 000 Sec. 5.2, Dirichlet): GMLS weights per 1e5 points, assembly and solve with each
// linear solver, and the peak resident memory, for N x N cells. PETSc options on the command
// line (-ksp_type ..., -pc_type ...) reach the PETSc solve; under mpirun every rank runs it and
// rank 0 prints. Peak memory is the process's, so time one solver per process for its figure.
#include <sys/resource.h>

#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>
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
    case LinearSolver::petsc: return "petsc";
    case LinearSolver::umfpack: return "umfpack";
    case LinearSolver::sparse_lu: return "sparse_lu";
    default: return "bicgstab_ilut";
  }
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<int> cells{64, 128, 256};
  std::vector<std::string> names{"petsc", "umfpack", "sparse_lu", "bicgstab"};
  CLI::App app{"peridot-bench-static: static LPS weights, assembly and solve per linear solver, and peak memory"};
  app.add_option("cells", cells, "N x N cells (default 64 128 256)")->check(CLI::Range(4, 4096));
  app.add_option("--solver", names, "linear solvers to time, in order (default petsc umfpack sparse_lu bicgstab)")
      ->check(CLI::IsMember({"petsc", "umfpack", "sparse_lu", "bicgstab"}));
  auto split = parallel::split_petsc_arguments(argc, argv);
  try {
    app.parse(int(split.peridot.size()), split.peridot.data());
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  parallel::set_command_line_options(split.petsc);
  std::vector<LinearSolver> solvers;
  for (const auto& s : names)
    solvers.push_back(s == "petsc" ? LinearSolver::petsc : s == "umfpack" ? LinearSolver::umfpack : s == "sparse_lu" ? LinearSolver::sparse_lu : LinearSolver::bicgstab_ilut);
  // Under mpirun, start MPI first so that only rank 0 prints.
  if (std::getenv("OMPI_COMM_WORLD_SIZE") || std::getenv("PMI_SIZE")) parallel::start();
  const bool printer = parallel::rank() == 0;
  try {
    const Problem base = read_deck(std::string(PERIDOT_SOURCE_DIR) + "/data/decks/lps/sine_dirichlet.yaml");
    if (printer)
      fmt::print("{:>5} {:>9} {:>9} {:>12} {:>10} {:>24} {:>6} {:>10} {:>10} {:>12} {:>10} {:>9} {:>10}\n", "N", "points", "unknowns", "weights[s]",
                 "per 1e5", "solver", "iters", "assembly", "solve", "error u", "residual", "peak MB", "vs first");
    for (int n : cells) {
      Problem p = base;
      p.lattice.spacing = std::numbers::pi / n;
      p.horizon = 3.5 * p.lattice.spacing;
      const auto s = setup_static(p);
      // The first solver's solution, for max |u - u_first| / max |u_first| of the others.
      std::optional<StaticResult> first;
      for (auto solver : solvers) {
        StaticOptions o = s.options;
        o.solver = solver;
        o.tolerance = 1e-10;
        if (solver == LinearSolver::sparse_lu && n > 128) {
          if (printer) fmt::print("{:>5} {:>9} {:>9} {:>12} {:>10} {:>24} skipped (Eigen SparseLU above N = 128 takes minutes)\n", n, "", "", "", "", name(solver));
          continue;
        }
        const auto r = solve_static_lps(s.body, s.model, s.problem, o);
        const auto e = static_errors(s, r);
        // Peak memory over ranks would need a reduction; rank 0's is printed, and says so.
        std::string label = name(solver);
        if (solver == LinearSolver::petsc)
          label = fmt::format("{}/{}{}{}", r.petsc.ksp, r.petsc.pc, r.petsc.factor_package.empty() ? "" : "/", r.petsc.factor_package) +
                  (r.petsc.ranks > 1 ? fmt::format(" x{}", r.petsc.ranks) : "");
        std::string versus = "";
        if (first) {
          double d = 0, scale = 0;
          for (int c = 0; c < 2; ++c)
            for (std::size_t i = 0; i < r.u[c].size(); ++i)
              d = std::max(d, std::abs(r.u[c][i] - first->u[c][i])), scale = std::max(scale, std::abs(first->u[c][i]));
          versus = fmt::format("{:.2e}", d / scale);
        }
        if (printer)
          fmt::print("{:>5} {:>9} {:>9} {:>12.3f} {:>10.3f} {:>24} {:>6} {:>10.3f} {:>10.3f} {:>12.4e} {:>10.2e} {:>9.0f} {:>10}\n", n, s.body.size(), r.unknowns,
                     s.quadrature.seconds, s.quadrature.seconds * 1e5 / double(s.quadrature.points), label, r.iterations, r.assembly_seconds,
                     r.solve_seconds, e.u, r.residual, peak_rss_mb(), versus);
        if (!first) first = r;
        std::fflush(stdout);
      }
    }
  } catch (const std::exception& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return 1;
  }
  return 0;
}
