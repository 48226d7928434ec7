// peridot run on N MPI ranks: a static LPS deck solved on PETSc by mpirun -np 2 and 4 (each
// rank assembles its own rows) against the one-process run (decks refused on N ranks: see
// test_mpi_explicit). Every mpirun is bounded by `timeout -k`, stays on loopback (shared memory
// between ranks, the launcher's own channel on lo) and is reaped by timeout if it hangs.
#include <catch2/catch.hpp>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>
#include "../support/cli_run.hpp"
#include "../support/mpirun.hpp"
import peridot.io;

namespace fs = std::filesystem;

namespace {

fs::path temp(const std::string& name) { return cli_run::temp("peridot_mpi_", name); }

const fs::path decks = fs::path(PERIDOT_SOURCE_DIR) / "data/decks";

struct Solution {
  std::vector<double> u, theta;
};

// The deck `deck` (under data/decks; its `name:` is `run`) solved into a folder of its own.
Solution solve(const std::string& launcher, const std::string& name, const std::string& extra = "",
               const std::string& deck = "lps/sine_top_traction.yaml", const std::string& run = "lps_sine_top_traction") {
  const fs::path out = temp(name);
  fs::remove_all(out);
  const auto r = cli_run::run(launcher, temp(name + ".err"), "run " + (decks / deck).string() + " --out " +
                                                              out.string() + " --threads 1 " + extra);
  INFO(launcher << ": " << r.err);
  REQUIRE(r.code == 0);
  const auto v = peridot::read_vtu(out / (run + ".vtu"));
  fs::remove_all(out);
  REQUIRE(v.find("displacement"));
  REQUIRE(v.find("dilatation"));
  return {v.find("displacement")->values, v.find("dilatation")->values};
}

double max_relative_difference(const std::vector<double>& a, const std::vector<double>& b) {
  REQUIRE(a.size() == b.size());
  double scale = 0, d = 0;
  for (std::size_t i = 0; i < a.size(); ++i) scale = std::max(scale, std::abs(b[i])), d = std::max(d, std::abs(a[i] - b[i]));
  REQUIRE(scale > 0);
  return d / scale;
}

}  // namespace

TEST_CASE("mpirun -np 2 and 4 solve a static LPS deck as one process does") {
  const auto serial = solve(PERIDOT_EXE, "serial");
  for (int ranks : {2, 4}) {
    // MUMPS on N ranks factorises the same matrix with another pivot order: rounding only.
    const auto par = solve(mpirun(ranks), "np" + std::to_string(ranks));
    INFO(ranks << " ranks");
    CHECK(max_relative_difference(par.u, serial.u) < 1e-10);
    CHECK(max_relative_difference(par.theta, serial.theta) < 1e-10);
  }
  // GMRES with BoomerAMG on 2 ranks, options from the command line.
  const auto amg = solve(mpirun(2), "amg", "-ksp_type gmres -pc_type hypre");
  CHECK(max_relative_difference(amg.u, serial.u) < 1e-8);
  CHECK(max_relative_difference(amg.theta, serial.theta) < 1e-8);
}

TEST_CASE("mpirun -np 2 solves the 3D static LPS deck with a traction face as one process does") {
  // N = 8: 2,048 unknowns, MUMPS on either side.
  const std::string deck = "lps_3d/sine_top_traction.yaml", run = "lps3d_sine_top_traction";
  const auto serial = solve(PERIDOT_EXE, "serial3d", "", deck, run);
  const auto par = solve(mpirun(2), "np2_3d", "", deck, run);
  CHECK(max_relative_difference(par.u, serial.u) < 1e-10);
  CHECK(max_relative_difference(par.theta, serial.theta) < 1e-10);
}
