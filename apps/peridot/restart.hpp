#pragma once
#include <cstddef>
#include <filesystem>
import peridot.problem;

// Restart checkpoints of explicit runs: the bridge between a run (deck, body, state, solver
// counters) and the plain peridot::Checkpoint that peridot.io writes and reads.

// The checkpoint of a run after state.step; the bond state is body.bonds.intact.
peridot::Checkpoint make_checkpoint(const peridot::Problem& p, const peridot::Setup& s, const peridot::State& state,
                                    double external_work, std::size_t broken);

// Reads `--restart file` and checks that it belongs to this deck and set-up: deck name, point
// and bond counts, dimension, scheme, dt, the deck's content hash, and a step within the run.
// Throws DeckError naming what differs (an input error: exit 2, before any output).
peridot::Checkpoint read_restart(const std::filesystem::path& file, const peridot::Problem& p, const peridot::Setup& s);

// Moves the checkpoint's u, v, f, time, step and bond mask into the run.
void restore_run(peridot::Checkpoint& c, peridot::Body& body, peridot::State& state);
