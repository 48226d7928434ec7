// peridot: run and check peridynamic simulation decks.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <fmt/core.h>

#include "commands.hpp"
import peridot.problem;

int main(int argc, char** argv) {
  CLI::App app{"Peridot: peridynamic fracture simulation.\n"
               "Exit codes: 0 success, 1 run failed (diverged or I/O error), 2 invalid input or usage."};
  app.require_subcommand(1);

  RunArgs run;
  auto* run_cmd = app.add_subcommand("run", "Run a deck (no deck: the embedded glass crack-branching default)");
  run_cmd->add_option("deck", run.deck, "YAML deck file");
  run_cmd->add_option("--out", run.out_dir, "Output directory (overrides output.directory)");
  run_cmd->add_option("--threads", run.threads, "OpenMP threads (0: default)")->check(CLI::Range(0, 4096));
  run_cmd->add_flag("--quiet", run.quiet, "No progress line or summary");
  run_cmd->add_option("--run-id", run.run_id, "Run id on the live DDS topics (default <name>-<pid>)");
  run_cmd->add_option("--dds-domain", run.dds_domain, "DDS domain id for live state")->check(CLI::Range(0, 230));
  run_cmd->add_option("--dds-partition", run.dds_partition, "DDS partition for live state (default: the default partition)");
  run_cmd->add_option("--restart", run.restart, "Continue an explicit run from an HDF5 checkpoint of this deck (output.checkpoint)");
  run_cmd->add_option("--max-steps", run.max_steps, "End after this many steps, load increments or solves, with the last step's outputs (a preview; 0: the deck's end)")
      ->check(CLI::Range(std::size_t(0), std::size_t(1) << 40));

  ConvergeArgs conv;
  auto* conv_cmd = app.add_subcommand("converge", "Refine a static deck and report L2 errors and observed orders (CSV)");
  conv_cmd->add_option("deck", conv.deck, "static YAML deck")->required();
  conv_cmd->add_option("--cells", conv.cells, "cells across the body's x extent, coarse to fine")->check(CLI::Range(2, 100000));
  conv_cmd->add_option("--clouds", conv.clouds, "perturbed decks: errors are the RMS over this many random clouds")->check(CLI::Range(1, 1000));
  conv_cmd->add_option("--out", conv.out_dir, "Output directory (overrides output.directory)");

  RenderArgs ren;
  auto* ren_cmd = app.add_subcommand("render", "Render saved output (.pvd series or .vtu) to PNG, headless");
  ren_cmd->add_option("input", ren.input, "out/<name>.pvd or a .vtu file")->required();
  ren_cmd->add_option("--field", ren.field, "point array to colour by (vectors: magnitude)");
  ren_cmd->add_option("--width", ren.width, "image width [px]")->check(CLI::Range(16, 16384));
  ren_cmd->add_flag("--deformed", ren.deformed, "draw the deformed configuration");
  ren_cmd->add_option("--magnification", ren.magnification, "displacement magnification")->check(CLI::Range(0.0, 1e12));
  ren_cmd->add_flag("--last", ren.last_only, "only the last step of a series");

  std::string check_deck;
  auto* check_cmd = app.add_subcommand("check", "Validate a deck and build its body without running");
  check_cmd->add_option("deck", check_deck, "YAML deck file")->required();

  MeshArgs mesh;
  auto* mesh_cmd = app.add_subcommand("mesh", "Mesh a Gmsh .geo once into a .msh file that decks read (no meshing per run or per rank)");
  mesh_cmd->add_option("geo", mesh.geo, "Gmsh .geo file")->required();
  mesh_cmd->add_option("--size", mesh.size, "element size [m] (0: the sizes in the file), as a deck's discretization.mesh.size")
      ->check(CLI::Range(0.0, 1e30));
  mesh_cmd->add_option("--dimension", mesh.dimension, "2: triangles, 3: tetrahedra")->check(CLI::IsMember({2, 3}));
  mesh_cmd->add_option("--out", mesh.out, "the .msh file to write (default: <stem>.msh in the current directory)");

  // PETSc options (-ksp_type gmres, -pc_type hypre, ...) anywhere on the line go to PETSc's
  // solves; they override a deck's solver.petsc_options.
  auto split = peridot::parallel::split_petsc_arguments(argc, argv);
  try {
    app.parse(int(split.peridot.size()), split.peridot.data());
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? exit_ok : exit_input_error;
  }
  peridot::parallel::set_command_line_options(split.petsc);
  if (!split.petsc.empty() && !*run_cmd) {
    fmt::print(stderr, "error: PETSc options ({}) apply to 'peridot run' only\n", split.petsc);
    return exit_input_error;
  }
  if (peridot::parallel::launched_by_mpirun()) peridot::parallel::start();
  // Only a run is split over ranks; any other command on N ranks would do the same work N times
  // (and `mesh` would write one file from N processes).
  if (!*run_cmd && peridot::parallel::ranks() > 1) {
    if (peridot::parallel::rank() == 0)
      fmt::print(stderr, "error: 'peridot {}' runs on one process, not on {} MPI ranks: run it without mpirun\n",
                 app.get_subcommands().front()->get_name(), peridot::parallel::ranks());
    return exit_input_error;
  }
  if (*run_cmd) return run_command(run);
  if (*check_cmd) return check_command(check_deck);
  if (*conv_cmd) return converge_command(conv);
  if (*ren_cmd) return render_command(ren);
  if (*mesh_cmd) return mesh_command(mesh);
  return exit_input_error;
}
