// PETSc and MPI live in a library that peridot.parallel opens at the first call needing them
// (parallel_backend.h): a serial explicit run loads neither; a PETSc solve in the same process
// then does, which also shows that the check below would see them.
#include <catch2/catch.hpp>
#include <omp.h>

#include <filesystem>
#include <string>
#include <variant>
#include "../support/mapped.hpp"
import peridot.run;
import peridot.parallel;

namespace fs = std::filesystem;

namespace {

peridot::RunOutcome run(const std::string& deck) {
  peridot::Problem p = peridot::read_deck((fs::path(PERIDOT_SOURCE_DIR) / deck).string());
  p.output = peridot::OutputSpec{};
  omp_set_num_threads(2);
  peridot::Simulation simulation(std::move(p));
  return simulation.run();
}

}  // namespace

TEST_CASE("a serial explicit run loads neither PETSc nor MPI, and a static solve on PETSc in the same process loads both") {
  REQUIRE_FALSE(mapped("libpetsc"));
  REQUIRE_FALSE(mapped("libmpi"));
  const auto explicit_run = run("tests/apps/decks/restart_plate_2d.yaml");
  REQUIRE(explicit_run.exit_status() == 0);
  CHECK_FALSE(mapped("libpetsc"));
  CHECK_FALSE(mapped("libmpi"));
  CHECK_FALSE(peridot::parallel::started());
  // Static LPS solves on PETSc by default.
  const auto static_run = run("data/decks/lps/patch_dirichlet.yaml");
  REQUIRE(static_run.exit_status() == 0);
  CHECK(peridot::parallel::started());
  CHECK(mapped("libpetsc"));
  CHECK(mapped("libmpi"));
  CHECK(mapped("peridot_petsc_backend"));
}
