#include <omp.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <type_traits>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>
#include <fmt/core.h>

#include "commands.hpp"
#include "embedded_deck.hpp"
#include "guarded.hpp"
#include "observers.hpp"
#include "progress.hpp"
#include "newmark_run.hpp"
#include "osb_static_run.hpp"
#include "quasi_static_run.hpp"
#include "restart.hpp"
#include "slab_run.hpp"
import peridot.problem;

namespace {

using namespace peridot;

void print_model(const Pmb& pmb) { fmt::print("  PMB: c = {:.6g}, s0 = {:.6g}\n", pmb.c, pmb.s0); }
void print_model(const Osb& m) {
  fmt::print("  OSB: c_theta = {:.6g}, k_theta = {:.6g} Pa, k_e = {:.6g} Pa{}\n", m.c_theta, m.k_theta, m.k_e,
             m.critical_stretch > 0 ? fmt::format(", bonds break at s_c = {:.4e}", m.critical_stretch) : "");
}
void print_model(const Rnp& m) {
  fmt::print("  RNP: C = {:.6g}, beta = {:.6g}, r_c = {:.6g}, small-strain micromodulus {:.6g}{}\n", m.C, m.beta, m.critical_r(), m.micromodulus(),
             m.break_factor > 0 ? fmt::format(", bonds break at {:g} r_c", m.break_factor) : "");
}

void print_setup(const Problem& p, const Setup& s, const Lps& model) {
  print_lps_setup(p, s.body, model);
  fmt::print("  velocity Verlet: stable time step estimate {:.4e} s (power iteration); using dt = {:.4e} s for {} steps to t = {:.4e} s\n",
             s.time_step.estimate, s.time_step.dt, s.time_step.steps, p.solver.end_time);
  if (s.time_step.above_estimate())
    fmt::print(stderr, "warning: solver.dt = {:.4e} s exceeds the stable estimate {:.4e} s; the run may diverge\n", s.time_step.dt,
               s.time_step.estimate);
}

template <class Model>
void print_setup(const Problem& p, const Setup& s, const Model& model) {
  fmt::print("peridot: {} ({}D, {})\n", p.name, p.dim, to_string(p.material.kinematics));
  fmt::print("  points {}  bonds {} (directed {}{})  h = {:.4g} m  delta = {:.4g} m\n", s.body.size(), s.body.directed_bonds() / 2,
             s.body.directed_bonds(), s.body.on_stencil() ? ", on a lattice stencil" : "", p.lattice.spacing, p.horizon);
  print_model(model);
  fmt::print("  stable time step estimate {:.4e} s; using dt = {:.4e} s for {} steps to t = {:.4e} s\n", s.time_step.estimate,
             s.time_step.dt, s.time_step.steps, p.solver.end_time);
  if (s.time_step.above_estimate())
    fmt::print(stderr, "warning: solver.dt = {:.4e} s exceeds the stable estimate {:.4e} s; the run may diverge\n", s.time_step.dt,
               s.time_step.estimate);
}

// A model without pair forces has no stress tensor: asking for it is an input error, before any file.
template <class Model>
void require_stress(const Problem& p, const Model&) {
  if constexpr (!PairForceModel<Model>)
    if (const auto key = Observers::stress_request(p.output); !key.empty())
      throw DeckError(fmt::format("{}: material.model reports no pair forces, so it has no stress tensor", key));
}

// The run's checkpoint after this step, when output.checkpoint asks for one: every `every` steps
// and at the last step. Written atomically (a .tmp renamed over the previous one).
template <class Solver>
void checkpoint_if_due(const Problem& p, const Setup& s, const State& state, const Solver& solver, const std::filesystem::path& dir,
                       bool last, Progress& progress, bool quiet) {
  const auto every = p.output.checkpoint_every;
  if (!every || (state.step % every != 0 && !last)) return;
  const auto c = solver.counters();
  const auto file = dir / p.output.checkpoint_file;
  write_checkpoint(file, make_checkpoint(p, s, state, c.external_work, c.broken));
  if (!quiet) {
    progress.clear();
    fmt::print("  checkpoint: step {}, t = {:.4e} s -> {}\n", state.step, state.time, file.string());
  }
}

template <ForceModel Model>
int simulate(const Problem& p, Setup& s, const Model& model, const RunArgs& args, std::optional<Checkpoint>& restart) {
  const auto dir = std::filesystem::path(args.out_dir ? *args.out_dir : p.output.directory.string());
  State state(s.body.size());
  typename ExplicitSolver<Model>::Counters counters;
  if (restart) {
    counters = {restart->external_work, std::size_t(restart->broken)};
    restore_run(*restart, s.body, state);
    restart.reset();
    // Before the solver copies the model: a model that caches data of the bond mask (LPS's
    // shape tensors) rebuilds it from the restored mask, as its incremental updates would.
    if constexpr (requires { model.prepare(s.body); }) model.prepare(s.body);
  }
  const std::size_t first_step = state.step;
  ExplicitSolver<Model> solver(s.body, model, s.boundaries, s.time_step, p.solver.scheme);
  if (first_step > 0) solver.restore(state, counters);
  else solver.initialize(state);
  // Observers read the solver's copy of the model: it is the one whose caches follow fracture.
  const Model& live = solver.model();
  // A model with its own damage measure (RNP: Z = max |S| / S_c, unbounded, cracked at Z >= 1)
  // reports it; others report the broken-bond fraction.
  Observers::DamageFunction damage_of;
  if constexpr (requires(std::vector<double>& d) { live.damage(s.body, state.u, d); })
    damage_of = [&](const VectorField& u, std::vector<double>& d) { live.damage(s.body, u, d); };
  // The stress tau of seed 004 Sec. 4.3, computed only on steps whose outputs ask for it.
  Observers::StressFunction stress_of;
  if constexpr (PairForceModel<Model>)
    stress_of = [&](const VectorField& u, StressField& tau) { tau = stress_field(live, s.body, u); };
  Observers observers(p, s.body, dir, live_options(args, p.name),
                      std::move(damage_of), std::move(stress_of), first_step);
  Progress progress(s.time_step.steps, !args.quiet, first_step);
  const auto t0 = std::chrono::steady_clock::now();
  const auto wall = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
  const auto strain = [&] { return live.strain_energy(s.body, state.u); };
  try {
    observers.observe(state, solver.external_work(), solver.broken_bonds(), strain, first_step == s.time_step.steps, 0.0);
    for (std::size_t k = first_step; k < s.time_step.steps; ++k) {
      solver.step(state);
      const bool last = k + 1 == s.time_step.steps;
      observers.observe(state, solver.external_work(), solver.broken_bonds(), strain, last, wall());
      checkpoint_if_due(p, s, state, solver, dir, last, progress, args.quiet);
      progress.update(state.step, state.time, solver.broken_bonds());
    }
  } catch (const std::exception& e) {
    progress.finish();
    observers.finish(false, e.what());
    throw;
  }
  progress.finish();
  observers.finish(true, "");
  if (!args.quiet) {
    observers.print_done(state, wall(), solver.broken_bonds());
  }
  return exit_ok;
}

void write_static_vtu(const std::filesystem::path& dir, const Problem& p, const StaticRun& run) {
  const auto& pc = run.setup.body.points;
  std::vector<double> ux(pc.size()), uy(pc.size()), theta0(pc.size()), role(pc.size());
  for (std::size_t i = 0; i < pc.size(); ++i) {
    const auto u0 = run.setup.reference.displacement(pc.position(i));
    ux[i] = u0[0];
    uy[i] = u0[1];
    theta0[i] = pc.role[i] == Role::ghost ? 0.0 : run.setup.reference.dilatation(pc.position(i));
    role[i] = double(static_cast<int>(pc.role[i]));
  }
  const NamedField fields[] = {
      {"displacement", 3, {run.result.u[0], run.result.u[1], {}}},
      {"dilatation", 1, {run.result.theta, {}, {}}},
      {"reference_displacement", 3, {ux, uy, {}}},
      {"reference_dilatation", 1, {theta0, {}, {}}},
      {"role", 1, {role, {}, {}}},
  };
  write_vtu(dir / (p.name + ".vtu"), pc, fields);
}

int simulate_static(const Problem& p, StaticSetup&& setup, double setup_seconds, const RunArgs& args) {
  StaticRun r{std::move(setup), {}, {}, setup_seconds};
  // The assembly and the solve are collective on N ranks: a rank that fails ends them all.
  r.result = parallel::or_abort("static solve", [&] { return solve_static_lps(r.setup.body, r.setup.model, r.setup.problem, r.setup.options); });
  // Every rank holds the whole solution; rank 0 reports and writes.
  if (parallel::rank() != 0) return exit_ok;
  r.errors = static_errors(r.setup, r.result);
  if (!args.quiet) {
    fmt::print("peridot: {} (static LPS, {} points, h = {:.4g} m, delta = {:.4g} m)\n", p.name, r.setup.body.size(), p.lattice.spacing,
               p.horizon);
    fmt::print("  {}\n", summary(r.setup.quadrature));
    fmt::print("  unknowns {}  nonzeros {}  setup {:.3f} s (weights {:.3f} s)  assembly {:.3f} s  solve {:.3f} s  residual {:.2e}\n",
               r.result.unknowns, r.result.nonzeros, r.setup_seconds, r.setup.quadrature.seconds, r.result.assembly_seconds,
               r.result.solve_seconds, r.result.residual);
    if (r.setup.options.solver == LinearSolver::petsc) {
      const auto& k = r.result.petsc;
      // The solve time above includes the set-up: a factorisation, or BoomerAMG's hierarchy.
      fmt::print("  PETSc on {} rank{}: {} / {}{}{}, set-up {:.3f} s, {} iteration{} {:.3f} s\n", k.ranks, k.ranks == 1 ? "" : "s", k.ksp,
                 k.pc, k.factor_package.empty() ? "" : " / ", k.factor_package, k.setup_seconds, k.iterations, k.iterations == 1 ? "" : "s",
                 k.solve_seconds);
    }
    fmt::print("  L2 error vs {}: u {:.6e} (relative {:.3e}), theta {:.6e} (relative {:.3e})\n", r.setup.reference.name, r.errors.u,
               r.errors.u_relative, r.errors.theta, r.errors.theta_relative);
  }
  for (const auto& name : r.result.petsc.unused_options) fmt::print(stderr, "warning: PETSc option {} was never read (misspelt?)\n", name);
  if (p.output.vtu_every) {
    const auto dir = std::filesystem::path(args.out_dir ? *args.out_dir : p.output.directory.string());
    std::filesystem::create_directories(dir);
    write_static_vtu(dir, p, r);
    if (!args.quiet) fmt::print("  output: {}\n", (dir / (p.name + ".vtu")).string());
  }
  return exit_ok;
}

}  // namespace

int run_command(const RunArgs& args) {
  if (args.threads > 0) omp_set_num_threads(args.threads);
  // Under mpirun, by default the ranks on a node share its cores instead of each taking all.
  else if (parallel::ranks() > 1) {
    const char* local = std::getenv("OMPI_COMM_WORLD_LOCAL_SIZE");
    const int on_node = local ? std::max(1, std::atoi(local)) : parallel::ranks();
    omp_set_num_threads(std::max(1, omp_get_num_procs() / on_node));
  }
  Problem problem;
  std::optional<Composed> composed;
  std::optional<Checkpoint> restart;
  std::optional<Setup> slab;  // this rank's share of an explicit run on N ranks
  const int rank = parallel::rank(), ranks = parallel::ranks();
  double setup_seconds = 0;
  // Everything up to a composed, allocated problem is input: failures exit 2 with no file written.
  const int input = guarded([&] {
    problem = args.deck ? read_deck(*args.deck) : parse_deck(embedded_default_deck, "embedded default deck");
    if (args.restart && problem.solver_kind != SolverKind::explicit_dynamics)
      throw DeckError(fmt::format("--restart: solver.type = '{}' cannot restart; only explicit runs write and read checkpoints",
                                  seam_names(Seam::solver)[std::size_t(problem.solver_kind)]));
    const auto t0 = std::chrono::steady_clock::now();
    if (ranks > 1 && problem.solver_kind == SolverKind::explicit_dynamics) {
      if (!parallel::command_line_options().empty())
        throw DeckError(fmt::format("PETSc options ({}) given, but explicit runs do not solve on PETSc", parallel::command_line_options()));
      // Every rank its part; rank 0 also the whole body, which its observers report from.
      std::optional<Setup> whole;
      slab = setup_slab(problem, rank, ranks, &whole);
      if (rank != 0) return int(exit_ok);
      if (whole) composed = std::move(*whole);
    }
    if (!composed) composed = compose(problem);
    if (const auto* s = std::get_if<Setup>(&*composed)) std::visit([&](const auto& m) { require_stress(problem, m); }, s->model);
    if (const auto* s = std::get_if<NewmarkSetup>(&*composed)) require_stress(problem, s->model);
    if (args.restart) restart = read_restart(*args.restart, problem, std::get<Setup>(*composed));
    const auto* st = std::get_if<StaticSetup>(&*composed);
    const bool on_petsc = st && st->options.solver == LinearSolver::petsc;
    if (st) check_petsc_options(*st);
    if (!on_petsc && !parallel::command_line_options().empty())
      throw DeckError(fmt::format("PETSc options ({}) given, but this deck does not solve on PETSc (static LPS decks with solver.linear_solver: petsc do)",
                                  parallel::command_line_options()));
    // Newmark, quasi-static and static OSB runs are still one-rank programs: on N ranks each
    // would run the whole deck and write the same files.
    if (parallel::ranks() > 1 && !on_petsc && !slab)
      throw DeckError(fmt::format("this deck cannot run on {} MPI ranks yet: explicit decks and static LPS decks with "
                                  "solver.linear_solver: petsc run distributed, the Newmark, quasi-static and static OSB solvers do not; "
                                  "run it without mpirun",
                                  parallel::ranks()));
    setup_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return int(exit_ok);
  });
  // On N ranks all stop when one failed (rank 0 alone reads a checkpoint and composes the whole
  // body), with the worst code: 2 when any rank's input was bad, else 1.
  if (const int worst = parallel::max_over_ranks(input); worst != exit_ok) return worst;
  if (slab) {
    const int code = guarded([&] {
      Setup* whole = rank == 0 ? &std::get<Setup>(*composed) : nullptr;
      if (whole && !args.quiet) {
        std::visit([&](const auto& m) { print_setup(problem, *whole, m); }, whole->model);
        if (slab->slab.axis >= 0) fmt::print("  MPI: {} ranks, each a slab of lattice layers across {}\n", ranks, "xyz"[slab->slab.axis]);
        else fmt::print("  MPI: {} ranks, parts by recursive coordinate bisection\n", ranks);
        if (restart) fmt::print("  restart from {} at step {}, t = {:.4e} s\n", *args.restart, restart->step, restart->time);
      }
      return simulate_slab(problem, *slab, whole, args, restart);
    });
    return code == exit_input_error ? exit_runtime_error : code;
  }
  // Past set-up, every failure is a failed run.
  const int code = guarded([&] {
    return std::visit(
        [&](auto& s) -> int {
          if constexpr (std::is_same_v<std::decay_t<decltype(s)>, StaticSetup>) {
            return simulate_static(problem, std::move(s), setup_seconds, args);
          } else if constexpr (std::is_same_v<std::decay_t<decltype(s)>, OsbStaticSetup>) {
            return simulate_osb_static(problem, s, args);
          } else if constexpr (std::is_same_v<std::decay_t<decltype(s)>, NewmarkSetup>) {
            return simulate_newmark(problem, s, args);
          } else if constexpr (std::is_same_v<std::decay_t<decltype(s)>, QuasiStaticSetup>) {
            return simulate_quasi_static(problem, s, args);
          } else {
            return std::visit(
                [&](const auto& model) {
                  if (!args.quiet) print_setup(problem, s, model);
                  if (!args.quiet && restart) fmt::print("  restart from {} at step {}, t = {:.4e} s\n", *args.restart, restart->step, restart->time);
                  return simulate(problem, s, model, args, restart);
                },
                s.model);
          }
        },
        *composed);
  });
  return code == exit_input_error ? exit_runtime_error : code;
}
