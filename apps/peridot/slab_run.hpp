#pragma once
#include <optional>

#include "commands.hpp"
import peridot.problem;

// An explicit run on N MPI ranks (mpirun -np N peridot run deck.yaml), any force model. Every
// rank steps its part of the body (setup_slab: lattice slabs on the stencil, coordinate
// bisection on a bond list), refreshing ghost displacements through a PetscSF halo before each
// force pass; each point sums its bonds in the one-rank order, so displacements and damage are
// bitwise those of one rank.
//   - VTU: every rank writes its owned points as one piece, rank 0 the .pvtu and the .pvd.
//   - CSV, terminal, DDS, PNG, fragments, crack tips and checkpoints: rank 0 gathers the owned
//     pieces of u, v, f and the bond states into `whole` (its one-rank set-up) on the steps they
//     are due and reports from there, so they equal the one-rank outputs.
//   - A restart: rank 0 reads and checks the checkpoint against `whole` and scatters it; ghost
//     rows a rank evaluates (state-based models) take their owners' bond states.
// whole: rank 0's one-rank set-up; null on the other ranks. restart: read on rank 0 only.
int simulate_slab(const peridot::Problem& p, peridot::Setup& local, peridot::Setup* whole, const RunArgs& args,
                  std::optional<peridot::Checkpoint>& restart);
