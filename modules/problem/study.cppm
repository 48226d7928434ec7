export module peridot.problem:study;
import peridot.std;
import peridot.io;
import peridot.implicit;
import peridot.deck;
import :static_setup;

export namespace peridot {

// One static LPS solve with its timings and errors against the reference solution.
struct StaticRun {
  StaticSetup setup;
  StaticResult result;
  StaticErrors errors;
  double setup_seconds = 0;
};

StaticRun run_static(const Problem& problem);

// One level of a refinement study. On perturbed grids with several clouds the errors are the
// root mean square over the clouds and the rest describes the first cloud.
struct StudyLevel {
  int cells = 0;
  double h = 0, delta = 0;
  std::size_t points = 0, unknowns = 0;
  StaticErrors errors;
  double residual = 0;
  double weights_seconds = 0, assembly_seconds = 0, solve_seconds = 0;
};

struct StudyOptions {
  std::vector<int> cells{16, 32, 64};  // cells across the body's x extent, coarse to fine
  int clouds = 1;                      // perturbed grids: independent random clouds per level
  // A level whose relative linear residual exceeds this is an error, not a data point.
  // UMFPACK and SparseLU reach 4e-16 to 8e-16 on the shipped decks at N = 16; BiCGSTAB
  // stops at its own tolerance, 1e-12 by default.
  double max_residual = 1e-11;
};

// Refuses, as a DeckError and before any file is written, a study that can't run: a deck that
// is not static LPS (the study measures errors against its reference solution), fewer than two
// levels, levels not from coarse to fine, several clouds of an unperturbed grid, or a finest
// level that would not fit in memory. Names the options as the command line spells them.
void check_study(const Problem& base, const StudyOptions& options);

// Refines a static problem: h = width / cells with delta / h kept, each level solved from
// scratch. `on_level` (may be empty) sees each level as it finishes.
std::vector<StudyLevel> refine(const Problem& base, const StudyOptions& options,
                               const std::function<void(const StudyLevel&)>& on_level = {});

// Observed order between two levels, and the slope of the least-squares line through
// (log h, log e) over all levels.
double pairwise_order(const StudyLevel& coarse, const StudyLevel& fine, bool theta);
double fitted_order(const std::vector<StudyLevel>& levels, bool theta);

// cells, h, delta, points, unknowns, errors, pairwise orders and timings, one row a level.
void write_study_csv(const std::filesystem::path& file, const std::vector<StudyLevel>& levels);

}  // namespace peridot

namespace peridot {

StaticRun run_static(const Problem& p) {
  const auto t0 = std::chrono::steady_clock::now();
  StaticRun run{setup_static(p), {}, {}, 0};
  run.setup_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  run.result = solve_static_lps(run.setup.body, run.setup.model, run.setup.problem, run.setup.options);
  run.errors = static_errors(run.setup, run.result);
  return run;
}

void check_study(const Problem& base, const StudyOptions& o) {
  // A study is defined by a reference solution, which only static LPS decks carry.
  if (const auto& row = combination_of(base); row.solver != SolverKind::static_linear || row.model != ModelKind::lps)
    throw DeckError(fmt::format("{}: a convergence study needs a static LPS deck (solver.type: static, material.model: lps)", base.name));
  if (o.cells.size() < 2) throw DeckError("--cells: give at least two resolutions");
  for (std::size_t k = 1; k < o.cells.size(); ++k)
    if (o.cells[k] <= o.cells[k - 1])
      throw DeckError(fmt::format("--cells: resolutions must increase, coarse to fine ({} after {})", o.cells[k], o.cells[k - 1]));
  if (o.clouds > 1 && !(base.lattice.perturbation > 0))
    throw DeckError("--clouds: several clouds need a perturbed deck (discretization.perturbation > 0)");
  // The finest level must fit in memory.
  Problem finest = base;
  const auto box = base.body.bounds();
  finest.lattice.spacing = (box.hi[0] - box.lo[0]) / o.cells.back();
  finest.horizon = base.horizon / base.lattice.spacing * finest.lattice.spacing;
  require_lattice_fits(box, finest.lattice.spacing, finest.dim, finest.statics.band_factor * finest.horizon);
}

std::vector<StudyLevel> refine(const Problem& base, const StudyOptions& o, const std::function<void(const StudyLevel&)>& on_level) {
  if (o.cells.empty()) throw std::invalid_argument("refinement study: give at least one resolution");
  const double factor = base.horizon / base.lattice.spacing;
  const auto box = base.body.bounds();
  const double width = box.hi[0] - box.lo[0];
  const int clouds = base.lattice.perturbation > 0 ? std::max(1, o.clouds) : 1;
  std::vector<StudyLevel> levels;
  for (int n : o.cells) {
    Problem p = base;
    p.lattice.spacing = width / n;
    p.horizon = factor * p.lattice.spacing;
    StudyLevel l;
    double su = 0, st = 0;
    for (int k = 0; k < clouds; ++k) {
      p.lattice.seed = base.lattice.seed + std::uint64_t(k);
      const auto r = run_static(p);
      if (!(r.result.residual <= o.max_residual))
        throw std::runtime_error(fmt::format("refinement study: at {} cells the linear solve's relative residual is {:.3e} (> {:.0e})", n,
                                             r.result.residual, o.max_residual));
      su += r.errors.u * r.errors.u, st += r.errors.theta * r.errors.theta;
      if (k == 0)
        l = {n, p.lattice.spacing, p.horizon, r.setup.body.size(), r.result.unknowns, r.errors, r.result.residual,
             r.setup.quadrature.seconds, r.result.assembly_seconds, r.result.solve_seconds};
    }
    l.errors.u = std::sqrt(su / clouds);
    l.errors.theta = std::sqrt(st / clouds);
    levels.push_back(l);
    if (on_level) on_level(l);
  }
  return levels;
}

double pairwise_order(const StudyLevel& a, const StudyLevel& b, bool theta) {
  const double ea = theta ? a.errors.theta : a.errors.u, eb = theta ? b.errors.theta : b.errors.u;
  return std::log(ea / eb) / std::log(a.h / b.h);
}

double fitted_order(const std::vector<StudyLevel>& levels, bool theta) {
  const double n = double(levels.size());
  double mh = 0, me = 0;
  for (const auto& l : levels) mh += std::log(l.h) / n, me += std::log(theta ? l.errors.theta : l.errors.u) / n;
  double num = 0, den = 0;
  for (const auto& l : levels) {
    const double dh = std::log(l.h) - mh;
    num += dh * (std::log(theta ? l.errors.theta : l.errors.u) - me);
    den += dh * dh;
  }
  return num / den;
}

void write_study_csv(const std::filesystem::path& file, const std::vector<StudyLevel>& levels) {
  // Built whole, then written atomically: a full disk never leaves half a table.
  std::string csv = "cells,h,delta,points,unknowns,error_u,error_theta,order_u,order_theta,residual,weights_s,assembly_s,solve_s\n";
  for (std::size_t k = 0; k < levels.size(); ++k) {
    const auto& l = levels[k];
    const double ou = k ? pairwise_order(levels[k - 1], l, false) : std::numeric_limits<double>::quiet_NaN(), ot = k ? pairwise_order(levels[k - 1], l, true) : std::numeric_limits<double>::quiet_NaN();
    csv += fmt::format("{},{:.9e},{:.9e},{},{},{:.9e},{:.9e},{:.6f},{:.6f},{:.3e},{:.4f},{:.4f},{:.4f}\n", l.cells, l.h, l.delta, l.points,
                       l.unknowns, l.errors.u, l.errors.theta, ou, ot, l.residual, l.weights_seconds, l.assembly_seconds, l.solve_seconds);
  }
  write_file_atomically(file, {csv});
}

}  // namespace peridot
