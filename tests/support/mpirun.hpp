#pragma once
// The launcher for app tests that run peridot on N MPI ranks: bounded by `timeout -k` (which
// reaps every rank if one hangs), shared memory between ranks and the launcher's own channel on
// lo, so no traffic leaves the machine.
//
// Every rank yields its core while it waits (mpi_yield_when_idle). Open MPI busy-polls unless it
// counts more ranks than the cores hwloc reports, and two tests' mpiruns share the machine's
// cores. CI once timed out two PETSc tests at 120 s that take 8 and 22 s here; forcing the poll
// here (OMPI_MCA_mpi_yield_when_idle=0) did the same, and a 14 s one took 118 s.
#include <string>
#include <vector>

inline std::vector<std::string> mpirun_argv(int ranks) {
  return {"/usr/bin/timeout", "-k", "5", "120", PERIDOT_MPIRUN, "--mca", "btl", "self,vader", "--mca", "oob_tcp_if_include", "lo",
          "--mca", "mpi_yield_when_idle", "1", "--bind-to", "none", "--oversubscribe", "-np", std::to_string(ranks)};
}

#ifdef PERIDOT_EXE
// The same as one shell command line, starting PERIDOT_EXE.
inline std::string mpirun(int ranks) {
  std::string line = "env OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1";
  for (const auto& word : mpirun_argv(ranks)) line += " " + word;
  return line + " " + PERIDOT_EXE;
}
#endif
