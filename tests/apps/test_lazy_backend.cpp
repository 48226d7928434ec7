// PETSc and MPI live in a library that peridot.parallel opens at the first call needing them
// (parallel_backend.h): a serial explicit run loads neither; a PETSc solve in the same process
// then does, which also shows that the check below would see them.
#include <catch2/catch.hpp>
#include <link.h>
#include <omp.h>

#include <filesystem>
#include <string>
#include <variant>
import peridot.run;
import peridot.parallel;

namespace fs = std::filesystem;

namespace {

// Whether a shared object whose file name contains `part` is loaded in this process.
bool loaded(const std::string& part) {
  struct Search {
    const std::string* part;
    bool found = false;
  } s{&part};
  dl_iterate_phdr(
      [](dl_phdr_info* info, std::size_t, void* data) {
        auto* s = static_cast<Search*>(data);
        if (info->dlpi_name && fs::path(info->dlpi_name).filename().string().find(*s->part) != std::string::npos) s->found = true;
        return 0;
      },
      &s);
  return s.found;
}

peridot::RunOutcome run(const std::string& deck) {
  peridot::Problem p = peridot::read_deck((fs::path(PERIDOT_SOURCE_DIR) / deck).string());
  p.output = peridot::OutputSpec{};
  omp_set_num_threads(2);
  peridot::Simulation simulation(std::move(p));
  return simulation.run();
}

}  // namespace

TEST_CASE("a serial explicit run loads neither PETSc nor MPI, and a static solve on PETSc in the same process loads both") {
  REQUIRE_FALSE(loaded("libpetsc"));
  REQUIRE_FALSE(loaded("libmpi"));
  const auto explicit_run = run("tests/apps/decks/restart_plate_2d.yaml");
  REQUIRE(explicit_run.exit_status() == 0);
  CHECK_FALSE(loaded("libpetsc"));
  CHECK_FALSE(loaded("libmpi"));
  CHECK_FALSE(peridot::parallel::started());
  // Static LPS solves on PETSc by default.
  const auto static_run = run("data/decks/lps/patch_dirichlet.yaml");
  REQUIRE(static_run.exit_status() == 0);
  CHECK(peridot::parallel::started());
  CHECK(loaded("libpetsc"));
  CHECK(loaded("libmpi"));
  CHECK(loaded("peridot_petsc_backend"));
}
