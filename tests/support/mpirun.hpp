#pragma once
// The launcher for app tests that run peridot on N MPI ranks: bounded by `timeout -k` (which
// reaps every rank if one hangs), shared memory between ranks and the launcher's own channel on
// lo, so no traffic leaves the machine. Needs PERIDOT_MPIRUN and PERIDOT_EXE.
#include <string>

inline std::string mpirun(int ranks) {
  return "env OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 timeout -k 5 120 " + std::string(PERIDOT_MPIRUN) +
         " --mca btl self,vader --mca oob_tcp_if_include lo --bind-to none --oversubscribe -np " + std::to_string(ranks) + " " + PERIDOT_EXE;
}
