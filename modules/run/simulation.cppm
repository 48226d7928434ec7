module;
#include <unistd.h>

export module peridot.run:simulation;
import peridot.std;
import peridot.problem;
import peridot.observe;
import peridot.live;
import peridot.quadrature;
import :loop;
import :checkpointing;
import :explicit_stepper;
import :implicit_steppers;
import :static_steppers;
import :distributed;
import :parts;

export namespace peridot {

// Another rank refused the deck or failed while setting up; this rank's own part was fine.
// code: the worst exit status among the ranks (2 for input, 1 otherwise).
struct OtherRankFailed : std::runtime_error {
  int code;
  explicit OtherRankFailed(int c) : std::runtime_error("another rank failed"), code(c) {}
};

// A deck made runnable and run through the one loop:
//   deck text --parse--> Problem --compose()--> Simulation --run()--> outputs
// The constructor composes (compose(), or on N MPI ranks setup_slab for explicit decks) and
// checks everything that can be checked before a file is written: bad input throws DeckError
// and leaves no file. run() drives the flavour's stepper with the deck's observers and any
// added with add_observer. Collective on N ranks: every rank makes it and calls run().
class Simulation {
 public:
  explicit Simulation(Problem problem, RunOptions options = {});
  // A user observer every `every` steps and at the last one: a part observer
  // (observe(const PartSample&)) on every rank, reading its part; an Observer
  // (observe(const Sample&)) on rank 0, reading the whole body, which rank 0 then gathers on
  // N ranks.
  template <class T>
    requires Observer<T> || PartObserver<T>
  Simulation& add_observer(T observer, std::size_t every = 1) {
    if constexpr (PartObserver<T>) parts_.emplace_back(std::move(observer), every);
    else users_.emplace_back(std::move(observer), every);
    return *this;
  }
  RunOutcome run();
  const Problem& problem() const { return problem_; }
  // The body this rank steps (on N ranks: its part), as composed: points, bonds, weights.
  const Body& body() const;
  // What `peridot check` reports of the composed problem: points, bonds and their bytes, the
  // memory estimate, and the flavour's set-up (weights, solver, time step). Warnings (a dt
  // above the stable estimate) go to `warnings`.
  std::vector<std::string> check_report(std::vector<std::string>& warnings) const;

 private:
  template <class S>
  RunOutcome go(S& stepper);
  std::filesystem::path output_directory() const {
    return options_.out_dir ? *options_.out_dir : std::filesystem::path(problem_.output.directory);
  }

  Problem problem_;
  RunOptions options_;
  std::vector<AnyObserver> users_;
  std::vector<AnyPartObserver> parts_;
  std::optional<Composed> composed_;  // the one-rank set-up (on N ranks explicit: rank 0's whole body)
  std::optional<Setup> part_;         // N ranks, explicit: this rank's part
  std::optional<Checkpoint> restart_;
  double setup_seconds_ = 0;
};

// Runs a problem to its end: Simulation(problem, options).run().
RunOutcome run(const Problem& problem, const RunOptions& options = {});

}  // namespace peridot

namespace peridot {

namespace {

// A model without pair forces has no stress tensor: asking for it is an input error, before any file.
template <class Model>
void require_stress(const Problem& p, const Model&) {
  if constexpr (!PairForceModel<Model>)
    if (const auto key = Observers::stress_request(p.output); !key.empty())
      throw DeckError(fmt::format("{}: material.model reports no pair forces, so it has no stress tensor", key));
}

int failure_code(const std::exception& e) { return is_input_error(e) ? 2 : 1; }

// Quasi-static Newton on N ranks: each rank assembles the tangent rows of its part and PETSc
// solves them, so solver.linear_solver auto means petsc there; a one-process solver is refused,
// and so is the finite-difference tangent, which perturbs the whole body point by point. Whether the run solves on
// PETSc; its options are checked before any file is written.
bool solve_quasi_static_on_ranks(QuasiStaticOptions& o, int ranks) {
  if (ranks > 1 && o.tangent == QsTangent::finite_difference)
    throw DeckError(fmt::format("solver.tangent = 'finite_difference' runs on one process; on {} MPI ranks use analytic", ranks));
  if (ranks > 1 && o.linear_solver == QsLinearSolver::automatic) o.linear_solver = QsLinearSolver::petsc;
  if (ranks > 1 && o.linear_solver != QsLinearSolver::petsc)
    throw DeckError(fmt::format("solver.linear_solver = '{}' solves on one process and cannot run on {} MPI ranks; allowed there: petsc, auto",
                                o.linear_solver == QsLinearSolver::cholmod ? "cholmod" : o.linear_solver == QsLinearSolver::umfpack ? "umfpack" : "cg",
                                ranks));
  if (o.linear_solver != QsLinearSolver::petsc) return false;
  if (o.nonlinear == QsNonlinear::ceres && ranks > 1)
    throw DeckError(fmt::format("solver.nonlinear = 'ceres' solves on one process; on {} MPI ranks use newton", ranks));
  check_petsc_options(o.petsc);
  return true;
}

// The quasi-static options' limits on the unknowns of the whole body, from the parts (a sum
// over the ranks' owned free components): every rank reaches the same verdict, rank 0 says why.
void check_unknowns_on_ranks(const Problem& p, const Setup& part) {
  std::uint64_t free = free_components(fixed_components(part.body, part.boundaries), part.slab.owned, part.body.dim());
  parallel::sum_over_ranks(free);
  QuasiStaticOptions o = p.quasi_static.options;
  o.condition_number = p.output.condition_number;
  try {
    check_quasi_static_size(std::size_t(free), o);
  } catch (const std::invalid_argument& e) {
    if (parallel::rank() != 0) throw OtherRankFailed(2);
    throw DeckError(e.what());
  }
}

// Static OSB on N ranks, as quasi-static above: its saddle-point system goes to MUMPS through PETSc
// unless the deck named a one-process solver, which is refused there.
bool solve_osb_on_ranks(const Problem& p, OsbStaticSetup& s, int ranks) {
  auto& o = s.options;
  if (ranks > 1 && !p.statics.linear_solver_named) o.solver = LinearSolver::petsc;
  if (ranks > 1 && o.solver != LinearSolver::petsc)
    throw DeckError(fmt::format("solver.linear_solver = '{}' solves on one process and cannot run on {} MPI ranks; allowed there: petsc "
                                "(or leave the key out)",
                                o.solver == LinearSolver::sparse_lu ? "sparse_lu" : "umfpack", ranks));
  if (o.solver != LinearSolver::petsc) return false;
  check_petsc_options(o.petsc);
  return true;
}

// Static LPS on PETSc under mpirun builds its parts per rank (setup_static_part), whose
// observers on rank 0 hold no point: every rank draws its points into the PNGs, the damage
// fraction comes reduced and DDS snapshots read the points gathered for them (TrackedPoints).
bool static_lps_on_ranks(const Problem& p, int ranks) {
  return ranks >= 2 && p.solver_kind == SolverKind::static_linear && p.material.model == ModelKind::lps &&
         p.statics.linear_solver == LinearSolver::petsc;
}

// Static OSB under mpirun builds its parts per rank (setup_osb_static_part) and writes its VTU,
// PNG, fragment counts and DDS snapshots' points from them. A deck that names
// a one-process solver is composed whole, for solve_osb_on_ranks to refuse.
bool osb_on_parts(const Problem& p, int ranks) {
  if (ranks < 2 || p.solver_kind != SolverKind::static_linear || p.material.model != ModelKind::osb) return false;
  return !p.statics.linear_solver_named || p.statics.linear_solver == LinearSolver::petsc;
}

}  // namespace

Simulation::Simulation(Problem problem, RunOptions options) : problem_(std::move(problem)), options_(std::move(options)) {
  // A library program under mpirun runs the deck on its ranks, as `peridot run` does, rather
  // than once per rank.
  if (parallel::launched_by_mpirun()) parallel::start();
  const auto& p = problem_;
  const int rank = parallel::rank(), ranks = parallel::ranks();
  std::exception_ptr failed;
  int code = 0;
  const auto t0 = std::chrono::steady_clock::now();
  try {
    if (options_.restart && !capabilities(p.solver_kind).restart)
      throw DeckError(fmt::format("--restart: solver.type = '{}' cannot restart; only explicit runs write and read checkpoints",
                                  seam_names(Seam::solver)[std::size_t(p.solver_kind)]));
    bool composed_here = true;
    // A checkpoint, in parts or whole, restarts a run whose rank 0 holds no bond: each rank
    // reads its own points. Only a stencil checkpoint of the old padded-grid layout goes
    // through rank 0's whole body.
    bool lean_restart = false;
    if (ranks > 1 && distributable(p)) {
      if (p.solver_kind == SolverKind::quasi_static) solve_quasi_static_on_ranks(problem_.quasi_static.options, ranks);
      else if (!parallel::command_line_options().empty())
        throw DeckError(fmt::format("PETSc options ({}) given, but explicit and Newmark runs do not solve on PETSc", parallel::command_line_options()));
      // Every rank its part; rank 0 also the whole body, which its observers report from.
      std::optional<Setup> whole;
      if (options_.restart && !root_gathers_bonds(p, false)) try {
          int parts = 0;
          const Checkpoint header = read_checkpoint_attributes(*options_.restart, parts);
          lean_restart = parts > 0 || !(uses_stencil(p) && header.bond_layout.empty());
        } catch (const std::runtime_error& e) {
          throw DeckError(fmt::format("restart: {}", e.what()));
        }
      part_ = setup_slab(p, rank, ranks, &whole, options_.restart && !lean_restart);
      // Every rank has its share of a mesh: none keeps it whole (33 B per node on rank 0).
      problem_.mesh.release_whole();
      if (p.solver_kind == SolverKind::quasi_static) check_unknowns_on_ranks(p, *part_);
      if (lean_restart) restart_ = read_restart_part(*options_.restart, p, *part_);
      composed_here = rank == 0;
      if (whole) composed_ = std::move(*whole);
    }
    if (composed_here) {
      if (!composed_ && static_lps_on_ranks(p, ranks)) composed_ = setup_static_part(p, rank, ranks);
      if (!composed_ && osb_on_parts(p, ranks)) composed_ = setup_osb_static_part(p, rank, ranks);
      if (!composed_) composed_ = compose(p);
      if (const auto* s = std::get_if<Setup>(&*composed_)) std::visit([&](const auto& m) { require_stress(p, m); }, s->model);
      if (const auto* s = std::get_if<NewmarkSetup>(&*composed_)) require_stress(p, s->model);
      if (options_.restart && !lean_restart) restart_ = read_restart(*options_.restart, p, std::get<Setup>(*composed_));
      const auto* st = std::get_if<StaticSetup>(&*composed_);
      bool on_petsc = st && st->options.solver == LinearSolver::petsc;
      if (st) check_petsc_options(*st);
      if (auto* q = std::get_if<QuasiStaticSetup>(&*composed_)) on_petsc = solve_quasi_static_on_ranks(q->solver.options, ranks);
      if (auto* o = std::get_if<OsbStaticSetup>(&*composed_)) on_petsc = solve_osb_on_ranks(p, *o, ranks);
      if (!on_petsc && !part_ && !parallel::command_line_options().empty())
        throw DeckError(fmt::format("PETSc options ({}) given, but this deck does not solve on PETSc (static and quasi-static decks with "
                                    "solver.linear_solver: petsc do)",
                                    parallel::command_line_options()));
      // A run that neither cuts its body nor solves on PETSc is a one-rank program: on N ranks
      // each would run the whole deck and write the same files.
      if (ranks > 1 && !on_petsc && !part_)
        throw DeckError(fmt::format("this deck cannot run on {} MPI ranks: explicit and Newmark decks run distributed, static and "
                                    "quasi-static decks with solver.linear_solver: petsc solve on PETSc; run it without mpirun",
                                    ranks));
    }
  } catch (const std::exception& e) {
    failed = std::current_exception();
    code = failure_code(e);
  }
  // On N ranks all stop when one failed (rank 0 alone reads a checkpoint and composes the whole
  // body), with the worst code: 2 when any rank's input was bad, else 1.
  const int worst = parallel::max_over_ranks(code);
  if (failed) std::rethrow_exception(failed);
  if (worst != 0) throw OtherRankFailed(worst);
  setup_seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (options_.live.run_id.empty()) options_.live.run_id = fmt::format("{}-{}", p.name, getpid());
}

RunOutcome Simulation::run() {
  if (part_) {
    Setup* whole = parallel::rank() == 0 ? &std::get<Setup>(*composed_) : nullptr;
    if (problem_.solver_kind == SolverKind::newmark) {
      DistributedStepper<Lps, NewmarkSolver<Lps>> s(problem_, *part_, whole, std::nullopt, !users_.empty(), options_.live.snapshot_max_points);
      return go(s);
    }
    if (problem_.solver_kind == SolverKind::quasi_static) {
      DistributedStepper<Rnp, QuasiStaticSolver<Rnp>> s(problem_, *part_, whole, std::nullopt, !users_.empty(), options_.live.snapshot_max_points);
      return go(s);
    }
    return std::visit(
        [&](const auto& m) {
          using Model = std::decay_t<decltype(m)>;
          DistributedStepper<Model> s(problem_, *part_, whole, std::move(restart_), !users_.empty(), options_.live.snapshot_max_points);
          return go(s);
        },
        part_->model);
  }
  return std::visit(
      [&](auto& setup) {
        using S = std::decay_t<decltype(setup)>;
        if constexpr (std::is_same_v<S, Setup>) {
          return std::visit(
              [&](const auto& model) {
                ExplicitStepper s(problem_, setup, model, std::move(restart_));
                return go(s);
              },
              setup.model);
        } else if constexpr (std::is_same_v<S, StaticSetup>) {
          StaticLpsStepper s(problem_, setup, setup_seconds_, options_.live.snapshot_max_points, !users_.empty());
          return go(s);
        } else if constexpr (std::is_same_v<S, OsbStaticSetup>) {
          OsbStaticStepper s(problem_, setup, options_.live.snapshot_max_points, !users_.empty());
          return go(s);
        } else if constexpr (std::is_same_v<S, NewmarkSetup>) {
          NewmarkStepper s(problem_, setup);
          return go(s);
        } else {
          QuasiStaticStepper s(problem_, setup);
          return go(s);
        }
      },
      *composed_);
}

template <class S>
RunOutcome Simulation::go(S& s) {
  const bool root = parallel::rank() == 0;
  const auto dir = output_directory();
  const auto& print = options_.print;
  if (root && print) {
    for (const auto& line : s.describe()) print(line);
    if (options_.restart) print(fmt::format("  restart from {} at step {}, t = {:.4e} s", options_.restart->string(), s.step(), s.time()));
  }
  if (root && options_.warn)
    if (const auto* e = std::get_if<Setup>(&*composed_); e && e->time_step.above_estimate())
      options_.warn(fmt::format("solver.dt = {:.4e} s exceeds the stable estimate {:.4e} s; the run may diverge", e->time_step.dt,
                                e->time_step.estimate));
  // The observers' view of the deck: outputs a stepper writes itself are not theirs.
  Problem reporting = problem_;
  if constexpr (requires { s.writes_vtu(); })
    if (s.writes_vtu()) reporting.output.vtu_every = 0;
  if constexpr (requires { s.writes_png(); })
    if (s.writes_png()) reporting.output.png_every = 0;
  // The user's observers and the stepper's own (the quasi-static load-step CSV), on every rank
  // for their cadences; they observe where the deck's observers do (rank 0).
  std::vector<AnyObserver> extra = users_;
  if constexpr (requires { s.observers(dir); })
    for (auto& o : s.observers(dir)) extra.push_back(std::move(o));
  std::optional<Observers> observers;
  parallel::together("observers and output directory", [&] {
    if (!root) return;
    // A stepper whose model defines its own damage or stress offers it; the others use the bonds'.
    Observers::DamageFunction damage;
    Observers::StressFunction stress;
    if constexpr (requires { s.damage_function(); }) damage = s.damage_function();
    if constexpr (requires { s.stress_function(); }) stress = s.stress_function();
    observers.emplace(reporting, s.body(), dir, options_.live, std::move(damage), std::move(stress), s.step());
    for (const auto& u : extra) observers->add(u);
    for (const auto& u : parts_) observers->add_cadence(u.every());
    if constexpr (requires { s.abscissa(); }) observers->set_abscissa(s.abscissa());
    // Checkpoints, the stepper's own files and its observers' go there too.
    bool own_files = problem_.output.checkpoint_every > 0;
    if constexpr (requires { s.observers(dir); }) own_files = true;
    if constexpr (requires { s.open_outputs(dir); }) own_files = true;
    if (own_files) std::filesystem::create_directories(dir);
  });
  // Files every rank writes itself (N ranks: VTU pieces), once the directory exists.
  if constexpr (requires { s.open_outputs(dir); }) s.open_outputs(dir);
  const Loop loop{.output = problem_.output,
                  .observers = observers ? &*observers : nullptr,
                  .users = &extra,
                  .parts = &parts_,
                  .reductions = {.sum = [](ExactSum& e) { exact_sums_over_ranks({&e}); },
                                 .max = [](double x) {
                                   parallel::max_over_ranks(std::span(&x, 1));
                                   return x;
                                 },
                                 .min = [](double x) { return parallel::min_over_ranks(x); }},
                  .checkpoint_file = dir / problem_.output.checkpoint_file,
                  .progress = options_.progress,
                  .max_steps = options_.max_steps,
                  .print = print};
  RunOutcome out;
  try {
    out = drive(s, loop);
  } catch (const LoadPathFailure&) {
    // Every rank stopped here together: rank 0 says why, the others end quietly.
    if (!root) throw OtherRankFailed(1);
    throw;
  } catch (const std::exception& e) {
    // The other ranks wait in the next collective: end them all.
    if (parallel::ranks() > 1) parallel::abort_from("stepping", e);
    throw;
  }
  if (out.interrupted && parallel::ranks() > 1) out.signal = parallel::max_over_ranks(out.signal);
  if (root) {
    if constexpr (requires { s.final_outputs(dir); })
      if (!out.interrupted)
        for (const auto& line : s.final_outputs(dir))
          if (print) print(line);
    if constexpr (requires { s.warnings(); })
      if (options_.warn)
        for (const auto& w : s.warnings()) options_.warn(w);
  }
  return out;
}

const Body& Simulation::body() const {
  if (part_) return part_->body;
  return std::visit([](const auto& setup) -> const Body& { return setup.body; }, *composed_);
}

std::vector<std::string> Simulation::check_report(std::vector<std::string>& warnings) const {
  std::vector<std::string> lines;
  std::visit(
      [&](const auto& s) {
        using S = std::decay_t<decltype(s)>;
        const double bytes = double(s.body.bond_bytes()), mib = 1024.0 * 1024.0;
        const std::size_t directed = s.body.directed_bonds();
        const char* layout = s.body.layout_storage();
        lines.push_back(fmt::format("  {} points, {} directed bonds ({:.1f} per point), {:.1f} bytes per bond ({}), {:.1f} MiB of bonds",
                                    s.body.size(), directed, double(directed) / double(std::max<std::size_t>(s.body.size(), 1)),
                                    directed ? bytes / double(directed) : 0.0, layout, bytes / mib));
        lines.push_back(fmt::format("  about {:.0f} bytes per point for positions, volumes and fields ({:.1f} MiB); run estimate {:.1f} MiB",
                                    bytes_per_point, bytes_per_point * double(s.body.size()) / mib,
                                    (bytes + bytes_per_point * double(s.body.size())) / mib));
        if constexpr (std::is_same_v<S, StaticSetup>) {
          lines.push_back(fmt::format("  {}", peridot::summary(s.quadrature)));
          if (s.options.solver == LinearSolver::petsc)
            lines.push_back(fmt::format("  linear solve on PETSc: {}{}",
                                        s.body.size() * 3 < std::size_t(s.options.petsc.direct_below) ? "LU (MUMPS)" : "GMRES + BoomerAMG",
                                        s.options.petsc.options.empty() ? "" : ", then solver.petsc_options '" + s.options.petsc.options + "'"));
        } else if constexpr (std::is_same_v<S, OsbStaticSetup>) {
          lines.push_back(fmt::format("  OSB: {} fictitious layers; {} real unknowns (u, v, theta)", s.layers,
                                      3 * std::size_t(std::count(s.body.points.role.begin(), s.body.points.role.end(), Role::interior))));
        } else if constexpr (std::is_same_v<S, NewmarkSetup>) {
          lines.push_back(fmt::format("  {}", peridot::summary(s.quadrature)));
          lines.push_back(fmt::format("  implicit Newmark: dt = {:.4e} s to t = {:.4e} s; s0 = {:.4e}", s.options.dt, s.options.end_time, s.model.s0));
        } else if constexpr (std::is_same_v<S, QuasiStaticSetup>) {
          lines.push_back(fmt::format("  RNP: C = {:.6g}, beta = {:.6g}; {}", s.model.C, s.model.beta, load_path_text(s.solver.options)));
        } else {
          lines.push_back(fmt::format("  dt = {:.4e} s (stable estimate {:.4e} s), {} steps", s.time_step.dt, s.time_step.estimate, s.time_step.steps));
          if (s.time_step.above_estimate()) warnings.push_back("solver.dt exceeds the stable estimate");
        }
      },
      *composed_);
  return lines;
}

RunOutcome run(const Problem& problem, const RunOptions& options) { return Simulation(problem, options).run(); }

}  // namespace peridot
