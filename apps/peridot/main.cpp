// peridot: run and check peridynamic simulation decks.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <fmt/core.h>

#include "commands.hpp"

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

  ConvergeArgs conv;
  auto* conv_cmd = app.add_subcommand("converge", "Refine a static deck and report L2 errors and observed orders (CSV)");
  conv_cmd->add_option("deck", conv.deck, "static YAML deck")->required();
  conv_cmd->add_option("--cells", conv.cells, "cells across the body's x extent, coarse to fine")->check(CLI::Range(2, 100000));
  conv_cmd->add_option("--out", conv.out_dir, "Output directory (overrides output.directory)");

  std::string check_deck;
  auto* check_cmd = app.add_subcommand("check", "Validate a deck and build its body without running");
  check_cmd->add_option("deck", check_deck, "YAML deck file")->required();

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? exit_ok : exit_input_error;
  }
  if (*run_cmd) return run_command(run);
  if (*check_cmd) return check_command(check_deck);
  if (*conv_cmd) return converge_command(conv);
  return exit_input_error;
}
