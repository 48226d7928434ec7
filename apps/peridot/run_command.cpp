// peridot run: arguments into RunOptions, the deck into a Simulation, its report onto the terminal.
#include <omp.h>
#include <sched.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <string>
#include <fmt/core.h>

#include "commands.hpp"
#include "embedded_deck.hpp"
#include "guarded.hpp"
import peridot.run;

int run_command(const RunArgs& args) {
  using namespace peridot;
  if (args.threads > 0) omp_set_num_threads(args.threads);
  // Under mpirun, by default the ranks on a node share its cores instead of each taking all.
  else if (parallel::ranks() > 1) {
    const char* local = std::getenv("OMPI_COMM_WORLD_LOCAL_SIZE");
    const int on_node = local ? std::max(1, std::atoi(local)) : parallel::ranks();
    omp_set_num_threads(std::max(1, omp_get_num_procs() / on_node));
  }
  // SIGINT and SIGTERM end the run after the current step, with its outputs whole.
  const StopOnSignals stop_on_signals;
  RunOptions options;
  if (args.out_dir) options.out_dir = *args.out_dir;
  if (args.run_id) options.live.run_id = *args.run_id;
  options.live.domain_id = args.dds_domain;
  options.live.partition = args.dds_partition;
  if (args.restart) options.restart = *args.restart;
  options.max_steps = args.max_steps;
  options.progress = !args.quiet;
  if (!args.quiet) options.print = [](const std::string& line) { fmt::print("{}\n", line), std::fflush(stdout); };
  options.warn = [](const std::string& line) { fmt::print(stderr, "warning: {}\n", line); };
  // SuiteSparse (for Ceres and UMFPACK) and PETSc's SuperLU_DIST load GCC's OpenMP runtime
  // beside clang's. With OMP_PROC_BIND set, GCC's pins the process to its first place while the
  // libraries load, before main, and clang's then places every thread inside that one place:
  // a 2-thread run measured here used one core. The original mask is gone by now, so say so.
  if (const char* bind = std::getenv("OMP_PROC_BIND"); bind && std::string(bind) != "false") {
    cpu_set_t mask;
    CPU_ZERO(&mask);
    if (sched_getaffinity(0, sizeof mask, &mask) == 0 && CPU_COUNT(&mask) < omp_get_max_threads())
      options.warn(fmt::format("{} OpenMP threads share {} core(s): with OMP_PROC_BIND={} the GCC OpenMP runtime that SuiteSparse and "
                               "PETSc load pins the process to one place before Peridot starts; unset OMP_PROC_BIND (and OMP_PLACES)",
                               omp_get_max_threads(), CPU_COUNT(&mask), bind));
  }

  // Everything up to a composed, allocated problem is input: failures exit 2 with no file written.
  std::optional<Simulation> simulation;
  const int input = guarded([&] {
    Problem problem = args.deck ? read_deck(*args.deck) : parse_deck(embedded_default_deck, "embedded default deck");
    simulation.emplace(std::move(problem), options);
    return int(exit_ok);
  });
  if (input != exit_ok) return input;
  // Past set-up, every failure is a failed run.
  const int code = guarded([&] { return simulation->run().exit_status(); });
  return code == exit_input_error ? exit_runtime_error : code;
}
