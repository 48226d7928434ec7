#include <catch2/catch.hpp>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <fstream>
#include <sstream>
#include <string>
#include "../support/csv_columns.hpp"
#include "../support/deck_text.hpp"
import peridot.problem;

namespace fs = std::filesystem;

namespace {

struct Result {
  int code;
  std::string err;
};

// Per-process temporary names: ctest runs test cases of this file in parallel.
fs::path temp(const std::string& name) { return fs::temp_directory_path() / ("peridot_cli_" + std::to_string(getpid()) + "_" + name); }

// Runs the peridot CLI with a time bound; stderr is captured.
Result cli(const std::string& args) {
  const fs::path err = temp("stderr.txt");
  const std::string cmd = "timeout 120 " + std::string(PERIDOT_EXE) + " " + args + " > /dev/null 2> " + err.string();
  const int status = std::system(cmd.c_str());
  std::ifstream in(err);
  std::stringstream ss;
  ss << in.rdbuf();
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, ss.str()};
}

fs::path deck_with(const std::string& name, const std::string& from, const std::string& to,
                   const std::string& source = "crack_branching_2d.yaml") {
  std::ifstream in(std::string(PERIDOT_SOURCE_DIR) + "/data/decks/" + source);
  std::stringstream ss;
  ss << in.rdbuf();
  std::string s = ss.str();
  const auto p = s.find(from);
  REQUIRE(p != std::string::npos);
  s.replace(p, from.size(), to);
  const fs::path file = temp(name + ".yaml");
  std::ofstream(file) << s;
  return file;
}

// The glass plate at h = 1 mm with a history row every 5 steps (the dissipation seen as it
// grows), written as `name`.yaml and run by the CLI into the fresh folder `name` with `extra`
// arguments; the deck and the folder.
std::pair<fs::path, fs::path> run_small_plate(const std::string& name, const std::string& extra) {
  const auto deck = deck_with(name, "spacing: 1.25e-4", "spacing: 1.0e-3");
  const auto text = deck_text::replaced(deck_text::file_text(deck), "csv: {every: 40}", "csv: {every: 5}");
  std::ofstream(deck) << text;
  const fs::path out = temp(name);
  fs::remove_all(out);
  const auto r = cli("run " + deck.string() + " --out " + out.string() + " --threads 1" + extra);
  INFO(r.err);
  REQUIRE(r.code == 0);
  return {deck, out};
}

void require_rejected(const fs::path& deck, const std::string& message) {
  const fs::path out = temp("out");
  fs::remove_all(out);
  const auto r = cli("run " + deck.string() + " --out " + out.string());
  INFO(r.err);
  CHECK(r.code == 2);
  CHECK(r.err.find(message) != std::string::npos);
  CHECK_FALSE(fs::exists(out));  // nothing written, not even the directory
  CHECK(cli("check " + deck.string()).code == 2);
}

}  // namespace

TEST_CASE("the CLI rejects bad decks with a clear message, exit code 2 and no output files") {
  require_rejected(deck_with("malformed", "dimension: 2", "dimension: [2"), "malformed YAML");
  require_rejected(deck_with("unknown", "density: 2440.0", "density: 2440.0\n  poisson: 0.2"), "unknown key 'poisson'");
  // A value out of range, composed after the YAML is read (more in test_deck_refusals.cpp).
  require_rejected(deck_with("negative_horizon", "horizon_factor: 4", "horizon: -1.0e-3"), "discretization.horizon = -1.0e-3");
  require_rejected(fs::temp_directory_path() / "peridot_no_such_deck.yaml", "cannot open deck file");
  // A 2 MiB value: refused by size, and never echoed in full.
  const auto big = deck_with("big", "name: crack_branching_2d", "name: " + std::string(2 << 20, 'x'));
  const fs::path out = temp("out");
  const auto r = cli("check " + big.string());
  CHECK(r.code == 2);
  CHECK(r.err.find("at most") != std::string::npos);
  CHECK(r.err.size() < 1000);
}

TEST_CASE("check, converge and render work on a static deck through the CLI") {
  const std::string deck = std::string(PERIDOT_SOURCE_DIR) + "/data/decks/lps/sine_dirichlet.yaml";
  CHECK(cli("check " + deck).code == 0);
  const fs::path out = temp("converge");
  fs::remove_all(out);
  const auto c = cli("converge " + deck + " --cells 8 16 32 --out " + out.string());
  INFO(c.err);
  REQUIRE(c.code == 0);
  // The CSV carries the errors; second order for the manufactured solution with Dirichlet data.
  std::ifstream csv(out / "lps_sine_dirichlet_convergence.csv");
  REQUIRE(csv);
  std::string header, line;
  std::getline(csv, header);
  CHECK(header.rfind("cells,h,delta,points,unknowns,error_u,error_theta,order_u", 0) == 0);
  double last_order = 0;
  int rows = 0;
  while (std::getline(csv, line)) {
    ++rows;
    std::stringstream ls(line);
    std::string cell;
    for (int k = 0; k <= 7; ++k) std::getline(ls, cell, ',');
    if (rows > 1) last_order = std::stod(cell);
  }
  CHECK(rows == 3);
  CHECK(last_order > 1.8);
  CHECK(cli("converge " + deck + " --cells 16").code == 2);     // one level is no study
  CHECK(cli("converge " + deck + " --cells 32 16").code == 2);  // coarse to fine
  // run writes the solution VTU, render turns it into a PNG.
  CHECK(cli("run " + deck + " --out " + out.string()).code == 0);
  REQUIRE(fs::exists(out / "lps_sine_dirichlet.vtu"));
  const auto r = cli("render " + (out / "lps_sine_dirichlet.vtu").string() + " --field displacement");
  INFO(r.err);
  CHECK(r.code == 0);
  CHECK(fs::exists(out / "lps_sine_dirichlet.png"));
  fs::remove_all(out);
}

TEST_CASE("the CLI reports usage errors with exit code 2") {
  CHECK(cli("").code == 2);
  CHECK(cli("run --threads -3").code == 2);
  CHECK(cli("frobnicate").code == 2);
}

TEST_CASE("the CLI runs a small deck to completion: one VTU point per lattice cell, every observer's cadence, zero total momentum, and the lost work carried off by broken bonds") {
  const auto [deck, out] = run_small_plate("small", "");
  for (const auto& e : fs::directory_iterator(out)) CHECK(e.path().extension() != ".tmp");
  // The steps: dt from the history (time / step of its second row), end_time = 46 us taking
  // ceil(end_time / dt) steps (choose_time_step). CSV rows every 5 steps, VTUs every 400, and
  // both at the last step.
  const auto h = csv_columns::read(out / "crack_branching_2d_history.csv");
  const auto& step = h.at("step");
  REQUIRE(step.size() >= 2);
  const double dt = h.at("time_s")[1] / step[1];
  const double x = 46.0e-6 / dt;  // a whole number of steps up to 1e-6 of it is taken as such
  const auto steps = std::size_t(std::abs(x - std::round(x)) < 1e-6 * x ? std::round(x) : std::ceil(x));
  INFO("dt = " << dt << " s, " << steps << " steps");
  CHECK(step.back() == double(steps));
  CHECK(step.size() == steps / 5 + 1 + (steps % 5 != 0));
  for (std::size_t k = 0; k + 1 < step.size(); ++k) CHECK(step[k] == double(5 * k));
  const auto series = peridot::read_pvd(out / "crack_branching_2d.pvd");
  CHECK(series.size() == steps / 400 + 1 + (steps % 400 != 0));
  // The plate is 0.1 m x 0.04 m at h = 1 mm: 100 x 40 points, one per cell.
  const auto vtu = peridot::read_vtu(series.back().second);
  CHECK(vtu.x[0].size() == 100 * 40);
  // Momentum: the tractions on the top and bottom layers (100 points each) cancel and pair forces
  // are equal and opposite, so the total momentum stays zero (equal masses: the sum of v).
  {
    const auto* v = vtu.find("velocity");
    REQUIRE(v);
    double p[2] = {0, 0}, scale = 0;
    for (std::size_t i = 0; i < vtu.x[0].size(); ++i)
      for (std::size_t k = 0; k < 2; ++k) p[k] += v->values[3 * i + k], scale += std::abs(v->values[3 * i + k]);
    INFO("sum of velocities (" << p[0] << ", " << p[1] << ") m/s, sum of |v| " << scale << " m/s");
    CHECK(std::abs(p[0]) <= 1e-8 * scale);  // measured 1.5e-9: the stencil's float displacements
    CHECK(std::abs(p[1]) <= 1e-8 * scale);
  }
  // Energy: the work of the tractions that is not kinetic or strain energy went with the broken
  // bonds, each taking its energy at the critical stretch, (c/2) s0^2 |xi| V^2 = 2 G0 |xi| h^4 /
  // delta^4 (c = 9E / (pi delta^3), s0^2 = 4 pi G0 / (9 E delta) in plane stress): between that
  // of a bond of length h and one of length delta, G0 = 3.8 J/m^2, h = 1 mm, delta = 4 mm. The
  // dissipation never decreases.
  const double G0 = 3.8, hh = 1e-3, delta = 4e-3;
  const double e_min = 2 * G0 * std::pow(hh, 5) / std::pow(delta, 4), e_max = 2 * G0 * std::pow(hh, 4) / std::pow(delta, 3);
  double last = 0;
  for (std::size_t k = 0; k < step.size(); ++k) {
    const double work = h.at("external_work_J")[k], dissipated = work - h.at("kinetic_J")[k] - h.at("strain_J")[k];
    const double broken = h.at("broken_bonds")[k];
    INFO("step " << step[k] << ": external work " << work << " J/m, dissipated " << dissipated << " J/m by " << broken << " bonds");
    CHECK(dissipated >= broken * e_min);
    CHECK(dissipated <= broken * e_max);
    CHECK(dissipated >= last);
    last = dissipated;
  }
  CHECK(h.at("broken_bonds").back() > 1000);
  fs::remove_all(out);
}

TEST_CASE("a quasi-static RNP deck runs through the CLI to an equilibrium: its forces balance the load and the clamp carries all of it, and check accepts every rnp deck") {
  const fs::path out = temp("rnp");
  fs::remove_all(out);
  const std::string decks = std::string(PERIDOT_SOURCE_DIR) + "/data/decks/rnp/";
  const auto r = cli("run " + decks + "plate_2d.yaml --out " + out.string() + " --quiet");
  INFO(r.err);
  REQUIRE(r.code == 0);
  std::ifstream csv(out / "rnp_plate_2d_load_steps.csv");
  std::string header, row;
  std::getline(csv, header);
  std::getline(csv, row);
  CHECK(header.rfind("step,load_factor,iterations", 0) == 0);
  CHECK(row.rfind("1,1.000000000e+00,", 0) == 0);  // one converged step at the full load
  // The written solution is an equilibrium: the RNP forces of the VTU's displacement (evaluated
  // here) balance the deck's body force (-50 on x < 0.5) at every free point, and the clamped
  // column x = 1.55 carries the reaction of the whole load, 50 x 1.6 x 0.5 = 40 along +x.
  {
    const auto last = peridot::read_vtu(peridot::read_pvd(out / "rnp_plate_2d.pvd").back().second);
    auto s = peridot::setup_quasi_static(peridot::read_deck(decks + "plate_2d.yaml"));
    const std::size_t n = s.body.size();
    REQUIRE(last.x[0].size() == n);
    const auto* disp = last.find("displacement");
    REQUIRE(disp);
    auto u = peridot::zero_field(n), f = peridot::zero_field(n);
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t k = 0; k < 2; ++k) u[k][i] = disp->values[3 * i + k];
    s.model.forces(s.body, u, f);
    double worst = 0, reaction[2] = {0, 0};
    std::size_t clamped = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const double x = s.body.points.x[0][i], V = s.body.points.volume[i];
      if (x > 1.5) {
        ++clamped;
        for (std::size_t k = 0; k < 2; ++k) reaction[k] -= f[k][i] * V;
        continue;
      }
      const double bx = x < 0.5 ? -50.0 : 0.0;
      worst = std::max({worst, std::abs(f[0][i] + bx), std::abs(f[1][i])});
    }
    INFO("largest |f + b| at a free point " << std::setprecision(17) << worst << ", reaction (" << reaction[0] << ", " << reaction[1] << ") over " << clamped << " points");
    CHECK(clamped == 16);
    // Bounds from the deck's Newton tolerance, 1e-10 relative (measured: 1.1e-13 and a reaction
    // 1.4e-14 short of 40); a residual at that bound on all 256 points moves the reaction by 3e-10.
    CHECK(worst <= 1e-10 * 50);
    CHECK(reaction[0] == Approx(40).epsilon(1e-9));
    CHECK(std::abs(reaction[1]) <= 1e-9 * 40);
  }
  for (const char* d : {"bar_1d.yaml", "bar_1d_explicit.yaml", "plate_2d.yaml", "tension_specimen_soft.yaml", "precracked_soft.yaml",
                        "precracked_hard.yaml"}) {
    INFO(d);
    CHECK(cli("check " + decks + d).code == 0);
  }
  fs::remove_all(out);
}

TEST_CASE("the CLI refuses bad PETSc options naming them, before any file") {
  const auto bad = deck_with("bad_petsc", "type: static", "type: static\n  petsc_options: \"-ksp_type no_such_krylov\"", "lps/sine_dirichlet.yaml");
  require_rejected(bad, "no_such_krylov");
  const auto direct = deck_with("petsc_umfpack", "type: static", "type: static\n  linear_solver: umfpack\n  petsc_options: \"-ksp_type cg\"",
                                "lps/sine_dirichlet.yaml");
  require_rejected(direct, "petsc_options");
  // Command-line PETSc options: an unknown type, and options for a deck that does not solve on PETSc.
  const fs::path out = temp("petsc_cli");
  fs::remove_all(out);
  const std::string sine = std::string(PERIDOT_SOURCE_DIR) + "/data/decks/lps/sine_dirichlet.yaml";
  auto r = cli("run " + sine + " --out " + out.string() + " -pc_type no_such_pc");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("no_such_pc"));
  r = cli("run " + std::string(PERIDOT_SOURCE_DIR) + "/data/decks/crack_branching_2d.yaml --out " + out.string() + " -ksp_type cg");
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("does not solve on PETSc"));
  CHECK_FALSE(fs::exists(out));
  // A misspelt option is reported, and the run goes on with the rest.
  r = cli("run " + sine + " --out " + out.string() + " -ksp_tpye cg");
  CHECK(r.code == 0);
  CHECK_THAT(r.err, Catch::Contains("-ksp_tpye was never read"));
  fs::remove_all(out);
}

// The restarts themselves are tested in-process (test_restart.cpp); here only that `--restart
// FILE` on the command line reaches the library.
TEST_CASE("peridot run --restart FILE continues the run from that checkpoint and refuses a missing one with exit 2") {
  const std::string plate = std::string(PERIDOT_SOURCE_DIR) + "/tests/apps/decks/restart_plate_2d.yaml";
  const auto with_end = [&](const std::string& name, const std::string& end) {
    const fs::path file = temp(name + ".yaml");
    std::ofstream(file) << deck_text::replaced(deck_text::file_text(plate), "end_time: 30.0e-6", "end_time: " + end);
    return file;
  };
  const fs::path first = temp("restart_flag_first"), second = temp("restart_flag_second");
  fs::remove_all(first);
  fs::remove_all(second);
  // 10 steps with a checkpoint at the last, then the same deck to 20 steps from it.
  auto r = cli("run " + with_end("restart_flag_10", "1.0e-6").string() + " --out " + first.string() + " --threads 1 --quiet");
  INFO(r.err);
  REQUIRE(r.code == 0);
  REQUIRE(peridot::read_checkpoint(first / "plate.h5").step == 10);
  const auto deck = with_end("restart_flag_20", "2.0e-6");
  r = cli("run " + deck.string() + " --out " + second.string() + " --threads 2 --quiet --restart " + (first / "plate.h5").string());
  INFO(r.err);
  REQUIRE(r.code == 0);
  CHECK(peridot::read_checkpoint(second / "plate.h5").step == 20);
  // A run from step 0 would have a history row at step 0; this one begins at the checkpoint.
  const auto h = csv_columns::read(second / "restart_plate_2d_history.csv");
  REQUIRE_FALSE(h.at("step").empty());
  CHECK(h.at("step").front() == 10);
  CHECK(h.at("step").back() == 20);
  // A checkpoint that is not there: an input error, before any file.
  const fs::path refused = temp("restart_flag_refused");
  fs::remove_all(refused);
  r = cli("run " + deck.string() + " --out " + refused.string() + " --restart " + temp("restart_flag_none.h5").string());
  CHECK(r.code == 2);
  CHECK_THAT(r.err, Catch::Contains("cannot open checkpoint file"));
  CHECK_FALSE(fs::exists(refused));
  fs::remove_all(first);
  fs::remove_all(second);
}

TEST_CASE("peridot run --max-steps N ends after step N with that step's outputs, and a negative count is a usage error") {
  // The small plate (more than 37 steps) with a history row every 5 steps: steps 0, 5, ..., 35 and the last.
  const auto [deck, out] = run_small_plate("preview", " --max-steps 37");
  const auto steps = csv_columns::read(out / "crack_branching_2d_history.csv").at("step");
  REQUIRE(steps.size() == 9);
  CHECK(steps.back() == 37);
  CHECK(steps[7] == 35);
  fs::remove_all(out);
  // A count the CLI cannot take is a usage error.
  CHECK(cli("run " + deck.string() + " --out " + out.string() + " --max-steps -1").code == 2);
  CHECK_FALSE(fs::exists(out));
  fs::remove_all(out);
}

TEST_CASE("peridot mesh writes a .geo's mesh once into a .msh that a deck reads in its place, and refuses bad input with exit 2, writing nothing") {
  const fs::path dir = temp("mesh");
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path msh = dir / "plate.msh";
  const std::string geo = std::string(PERIDOT_SOURCE_DIR) + "/data/decks/fe/hole_precrack.geo";
  REQUIRE(cli("mesh " + geo + " --size 2.0e-3 --out " + msh.string()).code == 0);
  REQUIRE(fs::exists(msh));
  // The coarse deck on the .geo and on the .msh: the same mesh, so the same nodes and bonds.
  const auto on_geo = deck_with("mesh_geo", "file: hole_precrack.geo, size: 0.5e-3", "file: " + geo + ", size: 2.0e-3",
                                "fe/hole_precrack_coarse.yaml");
  const auto on_msh = deck_with("mesh_msh", "file: hole_precrack.geo, size: 0.5e-3", "file: " + msh.string(), "fe/hole_precrack_coarse.yaml");
  const auto a = peridot::read_deck(on_geo), b = peridot::read_deck(on_msh);
  REQUIRE(b.mesh.mesh->nodes.size() == a.mesh.mesh->nodes.size());
  CHECK((b.mesh.mesh->triangles == a.mesh.mesh->triangles));
  CHECK(b.mesh.mean_edge() == Approx(a.mesh.mean_edge()).epsilon(1e-12));

  const std::pair<std::string, std::string> refused[] = {
      {"mesh " + std::string(PERIDOT_SOURCE_DIR) + "/data/decks/fe/hole_precrack.yaml --out " + (dir / "a.msh").string(), "expected a Gmsh .geo file"},
      {"mesh " + geo + " --out " + (dir / "missing" / "a.msh").string(), "no directory"},
      {"mesh " + geo + " --out " + (dir / "a.vtu").string(), "written as a .msh file"},
      {"mesh " + geo + " --size 1e-9 --out " + (dir / "a.msh").string(), "would make about"},
      {"mesh " + geo + " --dimension 4", "--dimension"},
      {"mesh " + (dir / "none.geo").string() + " --out " + (dir / "a.msh").string(), "no such file"}};
  for (const auto& [args, message] : refused) {
    INFO(args);
    const auto r = cli(args);
    CHECK(r.code == 2);
    CHECK_THAT(r.err, Catch::Contains(message));
  }
  CHECK_FALSE(fs::exists(dir / "a.msh"));
  CHECK_FALSE(fs::exists(dir / "a.vtu"));
  fs::remove_all(dir);
}
