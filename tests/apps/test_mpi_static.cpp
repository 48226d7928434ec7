// peridot run on N MPI ranks of the decks that solve on PETSc, against the one-process run:
// static LPS and quasi-static RNP (each rank builds its part and assembles its rows) and static OSB (every rank assembles the same system, PETSc solves it by
// rows); refusals: see test_mpi_explicit. Every
// mpirun is bounded by `timeout -k`, stays on loopback (shared memory between ranks, the
// launcher's own channel on lo) and is reaped by timeout if it hangs.
#include <catch2/catch.hpp>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <utility>
#include <string>
#include <vector>
#include "../support/cli_run.hpp"
#include "../support/csv_columns.hpp"
#include "../support/deck_text.hpp"
#include "../support/mpirun.hpp"
import peridot.io;

namespace fs = std::filesystem;

namespace {

fs::path temp(const std::string& name) { return cli_run::temp("peridot_mpi_", name); }

const fs::path decks = fs::path(PERIDOT_SOURCE_DIR) / "data/decks";

struct Solution {
  std::vector<double> u, theta;
};

// A field of the pieces a .pvtu lists, put back in global order by their global_id array.
std::vector<double> field_of_pieces(const fs::path& pvtu, const std::string& name) {
  const auto v = peridot::read_vtu(pvtu);
  const auto* f = v.find(name);
  const auto* id = v.find("global_id");
  REQUIRE(f);
  REQUIRE(id);
  const auto c = std::size_t(f->components);
  std::vector<double> out(f->values.size());
  for (std::size_t i = 0; i < id->values.size(); ++i)
    for (std::size_t k = 0; k < c; ++k) out[std::size_t(id->values[i]) * c + k] = f->values[i * c + k];
  return out;
}

// The deck `deck` (under data/decks; its `name:` is `run`) solved into a folder of its own. On
// N ranks the VTU comes in pieces, put back in global order, and the report must say that each
// rank built its own part.
Solution solve(const std::string& launcher, const std::string& name, const std::string& extra = "",
               const std::string& deck = "lps/sine_top_traction.yaml", const std::string& run = "lps_sine_top_traction") {
  const fs::path out = temp(name);
  fs::remove_all(out);
  const auto r = cli_run::run(launcher, temp(name + ".err"), "run " + (decks / deck).string() + " --out " +
                                                              out.string() + " --threads 1 " + extra, temp(name + ".out"));
  INFO(launcher << ": " << r.err);
  REQUIRE(r.code == 0);
  Solution s;
  if (fs::exists(out / (run + ".pvtu"))) {
    CHECK_THAT(deck_text::file_text(temp(name + ".out")), Catch::Contains("each rank built bonds and weights of its own neighbourhood only"));
    s = {field_of_pieces(out / (run + ".pvtu"), "displacement"), field_of_pieces(out / (run + ".pvtu"), "dilatation")};
  } else {
    const auto v = peridot::read_vtu(out / (run + ".vtu"));
    REQUIRE(v.find("displacement"));
    REQUIRE(v.find("dilatation"));
    s = {v.find("displacement")->values, v.find("dilatation")->values};
  }
  fs::remove_all(out);
  return s;
}

double max_relative_difference(const std::vector<double>& a, const std::vector<double>& b) {
  REQUIRE(a.size() == b.size());
  double scale = 0, d = 0;
  for (std::size_t i = 0; i < a.size(); ++i) scale = std::max(scale, std::abs(b[i])), d = std::max(d, std::abs(a[i] - b[i]));
  REQUIRE(scale > 0);
  return d / scale;
}

// A shipped deck with `edits` (pairs of old, new) run by `launcher` into a fresh folder `name`
// (its report in `name`.out).
// extra: more command-line arguments.
fs::path run_edited(const std::string& launcher, const std::string& deck, const std::vector<std::pair<std::string, std::string>>& edits,
                    const std::string& name, const std::string& extra = "") {
  auto text = deck_text::file_text(decks / deck);
  for (const auto& [from, to] : edits) text = deck_text::replaced(text, from, to);
  const fs::path file = temp(name + ".yaml"), out = temp(name);
  std::ofstream(file) << text;
  fs::remove_all(out);
  const auto r = cli_run::run(launcher, temp(name + ".err"), 
                            "run " + file.string() + " --out " + out.string() + " --threads 1" + extra, temp(name + ".out"));
  INFO(launcher << ": " << r.err);
  REQUIRE(r.code == 0);
  return out;
}

std::vector<double> field(const fs::path& vtu, const std::string& name) {
  const auto v = peridot::read_vtu(vtu);
  const auto* f = v.find(name);
  REQUIRE(f);
  return f->values;
}


}  // namespace

TEST_CASE("mpirun -np 2 and 4 solve a static LPS deck as one process does, each rank building only its part") {
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

// A body that is no box (an annulus, pressurised inside): its interior sites are runs of the
// cloud's grid (cloud_grids' any_shape), so the ranks still own bricks and number their unknowns
// from the cut and those runs alone.
TEST_CASE("mpirun -np 2 and 4 solve the hollow disk, a body that is no box, as one process does, each rank building only its brick") {
  const std::vector<std::pair<std::string, std::string>> vtu{{"      traction: reference", "      traction: reference\noutput:\n  directory: out\n  vtu: {every: 1}"}};
  const auto one = peridot::read_vtu(run_edited(PERIDOT_EXE, "lps/hollow_disk.yaml", vtu, "disk_one") / "lps_hollow_disk.vtu");
  const std::vector<double> u1 = one.find("displacement")->values, theta1 = one.find("dilatation")->values;
  for (int ranks : {2, 4}) {
    const std::string name = "disk_np" + std::to_string(ranks);
    const fs::path out = run_edited(mpirun(ranks), "lps/hollow_disk.yaml", vtu, name);
    INFO(ranks << " ranks");
    CHECK_THAT(deck_text::file_text(temp(name + ".out")), Catch::Contains("lattice layers"));
    CHECK(max_relative_difference(field_of_pieces(out / "lps_hollow_disk.pvtu", "displacement"), u1) < 1e-10);
    CHECK(max_relative_difference(field_of_pieces(out / "lps_hollow_disk.pvtu", "dilatation"), theta1) < 1e-10);
  }
}

TEST_CASE("mpirun -np 2 solves the 3D static LPS deck with a traction face as one process does") {
  // N = 8: 2,048 unknowns, MUMPS on either side.
  const std::string deck = "lps_3d/sine_top_traction.yaml", run = "lps3d_sine_top_traction";
  const auto serial = solve(PERIDOT_EXE, "serial3d", "", deck, run);
  const auto par = solve(mpirun(2), "np2_3d", "", deck, run);
  CHECK(max_relative_difference(par.u, serial.u) < 1e-10);
  CHECK(max_relative_difference(par.theta, serial.theta) < 1e-10);
}

// The pre-cracked RNP plate under soft load at h = 0.4 (1,444 points), half the shipped load in
// 12 steps: bonds at the crack tip soften from step 8 (118 past the inflection point at the
// end), so -K turns indefinite and the one-process run moves from CHOLMOD to UMFPACK. On N ranks
// each rank builds only its part (coordinate bisection), assembles the rows of its owned points
// and MUMPS solves them; residual norms are exact sums, so every rank takes the same steps.
TEST_CASE("mpirun -np 2 and 4 run a quasi-static RNP plate through softening on PETSc as one process does, to the Newton tolerance") {
  const std::vector<std::pair<std::string, std::string>> edits{{"spacing: 0.2", "spacing: 0.4"},
                                                               {"value: [0.0, 1.875e8]", "value: [0.0, 0.9375e8]"},
                                                               {"value: [0.0, -1.875e8]", "value: [0.0, -0.9375e8]"},
                                                               {"steps: 24", "steps: 12"},
                                                               {"vtu: {every: 1}", "vtu: {every: 12}"},
                                                               {"png: {every: 4, field: damage}", "png: {every: 12, field: damage}"}};
  const std::string run = "rnp_precracked_soft";
  const fs::path one = run_edited(PERIDOT_EXE, "rnp/precracked_soft.yaml", edits, "qs_one");
  const auto serial = csv_columns::read(one / (run + "_load_steps.csv"));
  REQUIRE(serial.at("step").size() == 12);
  REQUIRE(serial.at("softening_bonds").back() > 50);
  const auto u1 = field(one / (run + "_0000012.vtu"), "displacement");
  for (int ranks : {2, 4}) {
    INFO(ranks << " ranks");
    const fs::path out = run_edited(mpirun(ranks), "rnp/precracked_soft.yaml", edits, "qs_np" + std::to_string(ranks));
    CHECK_THAT(deck_text::file_text(temp("qs_np" + std::to_string(ranks) + ".out")),
               Catch::Contains("each rank built the bonds of its own neighbourhood only"));
    CHECK_THAT(deck_text::file_text(out / (run + "_load_steps.csv")), Catch::Contains("petsc preonly/lu (mumps)"));
    const auto par = csv_columns::read(out / (run + "_load_steps.csv"));
    // The same path: every increment takes the same Newton iterations and cuts, and the same
    // bonds soften.
    for (const std::string column : {"step", "load_factor", "iterations", "cuts", "softening_bonds"}) {
      INFO(column);
      CHECK((par.at(column) == serial.at(column)));
    }
    CHECK(max_relative_difference(par.at("max_damage"), serial.at("max_damage")) < 1e-8);
    // Newton stops at |R| <= 1e-10 of the reference force on both sides.
    CHECK(max_relative_difference(field_of_pieces(out / (run + "_0000012.pvtu"), "displacement"), u1) < 1e-8);
    // The history's strain energy: exact sums over the parts against one process's sum.
    const auto h1 = csv_columns::read(one / (run + "_history.csv")), hn = csv_columns::read(out / (run + "_history.csv"));
    CHECK(max_relative_difference(hn.at("strain_J"), h1.at("strain_J")) < 1e-8);
  }
}

// A quasi-static deck on a Gmsh mesh: rank 0 alone meshes the .geo and sends each rank its
// share of the nodes, elements and boundary nodes (the clamp is the .geo's right edge, a
// physical group).
TEST_CASE("mpirun -np 2 and 4 run a quasi-static RNP plate on a Gmsh mesh as one process does, to the Newton tolerance") {
  const fs::path geo = temp("qs_square.geo");
  std::ofstream(geo) << "SetFactory(\"OpenCASCADE\");\nRectangle(1) = {0, 0, 0, 1.6, 1.6};\n"
                        "Physical Surface(\"body\") = {1};\nPhysical Curve(\"right\") = {2};\n";
  const auto text = deck_text::replaced(
      deck_text::replaced(deck_text::file_text(decks / "rnp/plate_2d.yaml"), "  spacing: 0.1\n  horizon_factor: 5\n",
                          "  type: mesh\n  horizon: 0.5\n  quadrature: element\n  mesh: {file: " + geo.string() + ", size: 0.1}\n"),
      "    region: {rectangle: {min: [1.5, -1.0], max: [2.0, 2.6]}}\n", "    region: {group: right}\n");
  const auto deck = deck_text::replaced(deck_text::replaced(text, "geometry:\n  body:\n    rectangle: {min: [0.0, 0.0], max: [1.6, 1.6]}\n", ""),
                                        "steps: 1", "steps: 3");
  const fs::path file = temp("qs_mesh.yaml");
  std::ofstream(file) << deck;
  const auto run = [&](const std::string& launcher, const std::string& name) {
    const fs::path out = temp(name);
    fs::remove_all(out);
    const auto r = cli_run::run(launcher, temp(name + ".err"), "run " + file.string() + " --out " + out.string() + " --threads 1",
                                temp(name + ".out"));
    INFO(launcher << ": " << r.err);
    REQUIRE(r.code == 0);
    return out;
  };
  const fs::path one = run(PERIDOT_EXE, "qs_mesh_one");
  const auto h1 = csv_columns::read(one / "rnp_plate_2d_history.csv");
  REQUIRE(h1.at("strain_J").back() > 0);
  const auto u1 = field(one / "rnp_plate_2d_0000003.vtu", "displacement");
  for (int ranks : {2, 4}) {
    INFO(ranks << " ranks");
    const fs::path out = run(mpirun(ranks), "qs_mesh_np" + std::to_string(ranks));
    const auto hn = csv_columns::read(out / "rnp_plate_2d_history.csv");
    CHECK(max_relative_difference(hn.at("strain_J"), h1.at("strain_J")) < 1e-8);
    CHECK(max_relative_difference(field_of_pieces(out / "rnp_plate_2d_0000003.pvtu", "displacement"), u1) < 1e-8);
  }
}

// Static OSB on N ranks: each rank makes only its brick of the grown rectangle (real and
// fictitious sites) and its neighbourhood, and assembles its rows of the saddle-point system (u,
// v, theta and the condition rows of its sides), which MUMPS solves with three refinement steps.
// Ex. 1 (600 points) and the first 12 re-solves of the Neumann crack deck (1,600 points, 4 bonds
// removed per re-solve, chosen over every rank's bonds).
TEST_CASE("mpirun -np 2 and 4 solve static OSB decks on PETSc as one process does, bond removals included") {
  const std::vector<std::pair<std::string, std::string>> crack{{"fracture: {bonds_per_solve: 4}", "fracture: {bonds_per_solve: 4, max_solves: 12}"},
                                                                {"vtu: {every: 1}", "vtu: {every: 1}\n  csv: {every: 1}"}};
  const fs::path traction = run_edited(PERIDOT_EXE, "osb/traction.yaml", {}, "osb_one");
  const fs::path cracked = run_edited(PERIDOT_EXE, "osb/crack_neumann.yaml", crack, "osb_crack_one");
  const auto u1 = field(traction / "osb_traction.vtu", "displacement");
  const auto s1 = field(traction / "osb_traction.vtu", "stress_xx");
  const auto c1 = field(cracked / "osb_crack_neumann.vtu", "displacement");
  const auto d1 = field(cracked / "osb_crack_neumann.vtu", "damage");
  const auto h1 = csv_columns::read(cracked / "osb_crack_neumann_history.csv");
  double damaged = 0;
  for (double d : d1) damaged += d > 0;
  REQUIRE(damaged > 10);
  for (int ranks : {2, 4}) {
    INFO(ranks << " ranks");
    const auto n = std::to_string(ranks);
    const fs::path plate = run_edited(mpirun(ranks), "osb/traction.yaml", {}, "osb_np" + n);
    CHECK_THAT(deck_text::file_text(temp("osb_np" + n + ".out")), Catch::Contains("each rank built the bonds of its own neighbourhood only"));
    CHECK(max_relative_difference(field_of_pieces(plate / "osb_traction.pvtu", "displacement"), u1) < 1e-10);
    // The stress (51) of every point from the bonds across its segments, held by its owner.
    CHECK(max_relative_difference(field_of_pieces(plate / "osb_traction.pvtu", "stress_xx"), s1) < 1e-9);
    const fs::path out = run_edited(mpirun(ranks), "osb/crack_neumann.yaml", crack, "osb_crack_np" + n);
    // The same 48 bonds removed, so the same damage; the solution to the solves' rounding.
    CHECK(max_relative_difference(field_of_pieces(out / "osb_crack_neumann.pvtu", "damage"), d1) < 1e-12);
    CHECK(max_relative_difference(field_of_pieces(out / "osb_crack_neumann.pvtu", "displacement"), c1) < 1e-10);
    // A history row per re-solve: the strain energy summed over the owned points, the damage fraction.
    const auto hn = csv_columns::read(out / "osb_crack_neumann_history.csv");
    CHECK(max_relative_difference(hn.at("strain_J"), h1.at("strain_J")) < 1e-9);
    CHECK(hn.at("damage_fraction") == h1.at("damage_fraction"));
    CHECK(fs::file_size(out / "osb_crack_neumann.png") > 1000);
  }
}

// Fragments of a static OSB body on parts: the Dirichlet crack plate at h = 5 mm with its
// pre-crack run through the plate and the fictitious layer, so that two pieces (each held by
// two ranks of 2 x 2 bricks at 4 ranks), both clamped, carry the load. Each rank labels the
// pieces of its part and rank 0 joins the shares: one process's count, with no whole body.
TEST_CASE("mpirun -np 2 and 4 count one process's fragments of a static OSB plate cut in two, building only their parts") {
  const std::vector<std::pair<std::string, std::string>> cut{
      {"spacing: 0.0025", "spacing: 0.005"},
      {"segment: {from: [0, -0.06], to: [0, -0.03]}", "segment: {from: [0, -0.07], to: [0, 0.07]}"},
      {"right: {x: {displacement: 0.001}, y: {traction: 0}}", "right: {x: {displacement: 0.001}, y: {displacement: 0}}"},
      {"fracture: {bonds_per_solve: 4}", "fracture: {bonds_per_solve: 4, max_solves: 3}"},
      {"png: {every: 1, field: damage}", "csv: {every: 1}\n  fragments: {every: 1}"}};
  const fs::path one = run_edited(PERIDOT_EXE, "osb/crack_dirichlet.yaml", cut, "osb_cut_one");
  const auto h1 = csv_columns::read(one / "osb_crack_dirichlet_history.csv");
  REQUIRE(h1.at("fragments").back() == 2);
  for (int ranks : {2, 4}) {
    INFO(ranks << " ranks");
    const std::string name = "osb_cut_np" + std::to_string(ranks);
    const fs::path out = run_edited(mpirun(ranks), "osb/crack_dirichlet.yaml", cut, name);
    CHECK_THAT(deck_text::file_text(temp(name + ".out")), Catch::Contains("each rank built the bonds of its own neighbourhood only"));
    CHECK((csv_columns::read(out / "osb_crack_dirichlet_history.csv").at("fragments") == h1.at("fragments")));
  }
}

// The other boundary treatments on parts: conditions on the outermost nodes (pinned rows,
// tractions as body forces) and the fictitious layer with Taylor order 3 (the widest stencils),
// on 3 ranks (bricks of unequal size) and 4.
TEST_CASE("mpirun -np 3 and 4 solve static OSB with conditions on the outermost nodes and with Taylor order 3 as one process does") {
  const std::vector<std::pair<std::string, std::vector<std::pair<std::string, std::string>>>> cases{
      {"outermost", {{"boundary_method: fictitious_taylor", "boundary_method: outermost_nodes"}, {"  taylor_order: 1 ", "  "}}},
      {"order3", {{"taylor_order: 1 ", "taylor_order: 3 "}}}};
  for (const auto& [name, edits] : cases) {
    INFO(name);
    const auto u1 = field(run_edited(PERIDOT_EXE, "osb/traction.yaml", edits, "osb_" + name + "_one") / "osb_traction.vtu", "displacement");
    for (int ranks : {3, 4}) {
      INFO(ranks << " ranks");
      const fs::path out = run_edited(mpirun(ranks), "osb/traction.yaml", edits, "osb_" + name + "_np" + std::to_string(ranks));
      CHECK(max_relative_difference(field_of_pieces(out / "osb_traction.pvtu", "displacement"), u1) < 1e-10);
    }
  }
}

// The condition number of the reduced tangent on N ranks: each rank's rows go to rank 0, which
// takes a dense SVD; one process takes it of the matrix it assembled whole.
TEST_CASE("mpirun -np 2 and 4 report the one-process condition number of the reduced tangent") {
  const std::string run = "rnp_plate_2d_crack_condition";
  const auto serial = csv_columns::read(run_edited(PERIDOT_EXE, "rnp/plate_2d_crack_condition.yaml", {}, "cond_one") / (run + "_load_steps.csv"));
  REQUIRE(serial.at("condition_number").size() == 1);
  REQUIRE(serial.at("condition_number")[0] > 100);
  for (int ranks : {2, 4}) {
    INFO(ranks << " ranks");
    const fs::path out = run_edited(mpirun(ranks), "rnp/plate_2d_crack_condition.yaml", {}, "cond_np" + std::to_string(ranks));
    const auto par = csv_columns::read(out / (run + "_load_steps.csv"));
    CHECK(max_relative_difference(par.at("condition_number"), serial.at("condition_number")) < 1e-8);
  }
}

// The pre-cracked soft plate at h = 0.4 under its full load loses stability at about half of it
// (Sec. 6.2.3), with the step cutting bounded at 1.5 % of the load. Every rank sees the same reduced residuals, so all stop at the same increment:
// rank 0 says why once, and the job ends with exit 1 without an MPI abort.
TEST_CASE("a quasi-static run that loses stability on 2 ranks stops where one process stops, with one message and exit 1") {
  const std::string deck = "rnp/precracked_soft.yaml", run = "rnp_precracked_soft";
  // Two cuts of the 1/24 increment at most, so the failure comes after a few solves.
  const auto text = deck_text::replaced(deck_text::replaced(deck_text::file_text(decks / deck), "spacing: 0.2", "spacing: 0.4"),
                                        "min_increment: 1.0e-3", "min_increment: 1.5e-2");
  const fs::path file = temp("unstable.yaml");
  std::ofstream(file) << text;
  std::vector<std::size_t> rows;
  std::string message;
  for (int ranks : {1, 2}) {
    INFO(ranks << " ranks");
    const fs::path out = temp("unstable_np" + std::to_string(ranks));
    fs::remove_all(out);
    const auto r = cli_run::run(ranks == 1 ? std::string(PERIDOT_EXE) : mpirun(ranks), temp("unstable.err"),
                                "run " + file.string() + " --out " + out.string() + " --threads 1");
    CHECK(r.code == 1);
    const auto at = r.err.find("error: quasi-static: the load increment from");
    REQUIRE(at != std::string::npos);
    CHECK(r.err.find("error:", at + 1) == std::string::npos);
    CHECK(r.err.find("MPI_ABORT") == std::string::npos);
    // The failing increment's load range, as one process reports it.
    const auto line = r.err.substr(at, r.err.find(" of the full load", at) - at);
    if (ranks == 1) message = line;
    else CHECK(line == message);
    rows.push_back(csv_columns::read(out / (run + "_history.csv")).at("step").size());
  }
  CHECK(rows[0] == rows[1]);
}

// The figures a static LPS run on N ranks reduces over its parts: the L2 errors against the
// reference solution and the strain energy of the history row, exact sums over the owned points,
// against one process's sums over the whole body.
TEST_CASE("mpirun -np 2 reports the one-process L2 errors and strain energy of a static LPS deck, and draws its one-process PNG in parts") {
  const std::vector<std::pair<std::string, std::string>> csv{{"vtu: {every: 1}", "vtu: {every: 1}\n  csv: {every: 1}"}};
  const std::string run = "lps_sine_top_traction";
  // "L2 error vs manufactured_sine: u A (relative B), theta C (relative D)": A and C.
  const auto errors = [](const std::string& report) {
    const auto at = report.find("L2 error vs");
    REQUIRE(at != std::string::npos);
    const auto u = report.find(": u ", at), theta = report.find("theta ", at);
    return std::pair<double, double>{std::stod(report.substr(u + 4)), std::stod(report.substr(theta + 6))};
  };
  const fs::path one = run_edited(PERIDOT_EXE, "lps/sine_top_traction.yaml", csv, "errors_one");
  const fs::path two = run_edited(mpirun(2), "lps/sine_top_traction.yaml", csv, "errors_np2");
  const auto e1 = errors(deck_text::file_text(temp("errors_one.out"))), e2 = errors(deck_text::file_text(temp("errors_np2.out")));
  REQUIRE(e1.first > 0);
  CHECK(std::abs(e2.first - e1.first) <= 1e-6 * e1.first);  // printed to 7 digits
  CHECK(std::abs(e2.second - e1.second) <= 1e-6 * e1.second);
  const auto h1 = csv_columns::read(one / (run + "_history.csv")), h2 = csv_columns::read(two / (run + "_history.csv"));
  REQUIRE(h1.at("strain_J").back() > 0);
  CHECK(max_relative_difference(h2.at("strain_J"), h1.at("strain_J")) < 1e-10);

  // Each rank builds its own part and draws its owned points into rank 0's image, at the square
  // size one process estimates from the whole cloud: the one-process PNGs (before and after the
  // solve), byte for byte.
  const std::vector<std::pair<std::string, std::string>> png{{"vtu: {every: 1}", "png: {every: 1, field: displacement}"}};
  const fs::path drawn_one = run_edited(PERIDOT_EXE, "lps/sine_top_traction.yaml", png, "static_png_one");
  for (int ranks : {2, 3}) {
    INFO(ranks << " ranks");
    const std::string name = "static_png_np" + std::to_string(ranks);
    const fs::path drawn = run_edited(mpirun(ranks), "lps/sine_top_traction.yaml", png, name);
    CHECK_THAT(deck_text::file_text(temp(name + ".out")), Catch::Contains("each rank built bonds and weights"));
    for (const std::string image : {run + "_0000000.png", run + "_0000001.png"}) {
      INFO(image);
      REQUIRE(fs::exists(drawn_one / image));
      // The solutions differ by MUMPS's rounding (1e-12 of u) only, far below a colour level.
      CHECK((deck_text::file_text(drawn / image) == deck_text::file_text(drawn_one / image)));
    }
  }
}

// DDS snapshots of a static run on N ranks come from the points each rank owns (gathered as
// TrackedPoints; test_tracked_points checks what it gathers): the run keeps its parts, with no
// rank composing the whole body, and its history stays one process's. Published into a DDS
// partition of this test process's own, which nothing reads.
TEST_CASE("mpirun -np 2 publishes DDS snapshots of static OSB and static LPS runs from the ranks' parts, as one process's history") {
  const std::string dds = " --dds-partition peridot-mpi-static-" + std::to_string(getpid());
  const std::string published = "csv: {every: 1}\n  dds: {every: 1, snapshot_every: 1}";
  struct Case {
    std::string deck, run, built;
    std::vector<std::pair<std::string, std::string>> edits;
  };
  // Some of the sine deck's bonds start broken, so its damage fraction is not zero either: a
  // sum over the owned points on N ranks.
  const std::vector<Case> cases{
      {"osb/crack_neumann.yaml", "osb_crack_neumann", "each rank built the bonds of its own neighbourhood only",
       {{"fracture: {bonds_per_solve: 4}", "fracture: {bonds_per_solve: 4, max_solves: 4}"}, {"vtu: {every: 1}", published}}},
      {"lps/sine_top_traction.yaml", "lps_sine_top_traction", "each rank built bonds and weights of its own neighbourhood only",
       {{"vtu: {every: 1}", published}}}};
  for (const auto& c : cases) {
    INFO(c.deck);
    const auto h1 = csv_columns::read(run_edited(PERIDOT_EXE, c.deck, c.edits, c.run + "_dds_one", dds) / (c.run + "_history.csv"));
    const fs::path two = run_edited(mpirun(2), c.deck, c.edits, c.run + "_dds_np2", dds);
    const auto report = deck_text::file_text(temp(c.run + "_dds_np2.out"));
    CHECK_THAT(report, Catch::Contains(c.built));
    CHECK_THAT(report, Catch::Contains("DDS snapshots gather every point"));
    const auto h2 = csv_columns::read(two / (c.run + "_history.csv"));
    REQUIRE(h1.at("damage_fraction").back() > 0);
    CHECK(max_relative_difference(h2.at("strain_J"), h1.at("strain_J")) < 1e-9);
    CHECK(h2.at("damage_fraction") == h1.at("damage_fraction"));
  }
}

// The condition number's limit on the unknowns holds for the whole body on N ranks: a deck over
// it is refused by every rank together, with rank 0's one message, exit 2 and no file.
TEST_CASE("mpirun -np 2 refuses a condition number over its unknown limit once, with exit 2 and no output") {
  // h = 0.03 on the 1.6 m plate: 54 x 54 points, about 5,500 unknowns (more than 4,000).
  const auto text = deck_text::replaced(deck_text::file_text(decks / "rnp/plate_2d_crack_condition.yaml"), "spacing: 0.1", "spacing: 0.03");
  const fs::path file = temp("cond_limit.yaml"), out = temp("cond_limit");
  std::ofstream(file) << text;
  fs::remove_all(out);
  const auto r = cli_run::run(mpirun(2), temp("cond_limit.err"), "run " + file.string() + " --out " + out.string() + " --threads 1");
  CHECK(r.code == 2);
  const auto at = r.err.find("error: output.condition_number = true needs a dense SVD");
  CHECK(at != std::string::npos);
  CHECK(r.err.find("error:", at + 1) == std::string::npos);
  CHECK_FALSE(fs::exists(out));
}

// The stress in the VTU on N ranks. On a lattice a point's stress (seed 004 eqs. 51-52) reads the
// bonds of points up to a horizon away, whose rows other ranks hold, so rank 0 writes the
// whole-body VTU from what it gathers, as one process does; the pieces would lack it.
// Each rank writes its owned points' stress into its VTU piece, from rows held whole one bond
// deeper for it; rank 0 holds no bond.
TEST_CASE("mpirun -np 2 writes the one-process stress into the VTU of a quasi-static RNP plate") {
  const std::vector<std::pair<std::string, std::string>> stress{{"vtu: {every: 1}", "vtu: {every: 1, stress: true}"}};
  const fs::path one = run_edited(PERIDOT_EXE, "rnp/plate_2d.yaml", stress, "stress_one");
  const fs::path two = run_edited(mpirun(2), "rnp/plate_2d.yaml", stress, "stress_np2");
  for (const std::string name : {"stress_xx", "stress_yy", "stress_xy"}) {
    INFO(name);
    CHECK(max_relative_difference(field_of_pieces(two / "rnp_plate_2d_0000001.pvtu", name), field(one / "rnp_plate_2d_0000001.vtu", name)) < 1e-8);
  }
}

// Ceres and the finite-difference tangent work on the whole body in one process: refused under
// mpirun by the deck key, exit 2, before any file.
TEST_CASE("mpirun -np 2 refuses Ceres and the finite-difference tangent of a quasi-static deck, naming the key, with exit 2 and no output") {
  const std::vector<std::pair<std::string, std::string>> cases{
      {"nonlinear: ceres", "solver.nonlinear = 'ceres' solves on one process; on 2 MPI ranks use newton"},
      {"tangent: finite_difference", "solver.tangent = 'finite_difference' runs on one process; on 2 MPI ranks use analytic"}};
  for (const auto& [key, message] : cases) {
    INFO(key);
    const auto text = deck_text::replaced(deck_text::file_text(decks / "rnp/plate_2d.yaml"), "tolerance: 1.0e-10", "tolerance: 1.0e-10\n  " + key);
    const fs::path file = temp("one_process_only.yaml"), out = temp("one_process_only");
    std::ofstream(file) << text;
    fs::remove_all(out);
    const auto r = cli_run::run(mpirun(2), temp("one_process_only.err"), "run " + file.string() + " --out " + out.string());
    CHECK(r.code == 2);
    CHECK_THAT(r.err, Catch::Contains(message));
    CHECK_FALSE(fs::exists(out));
  }
}

// The uncorrected Neumann crack deck at h = 5 mm (400 points) runs its sequentially linear
// fracture until the plate comes apart (169 re-solves): a re-solve that finds no equilibrium
// (relative residual above OsbStaticOptions::singular_residual) ends it on any solver, so 2 and
// 4 ranks stop where one process stops and have removed the same bonds. Before, the re-solves
// past the separation went on removing bonds by the noise of near-singular solves (122 more
// here), and their count depended on the solver.
TEST_CASE("mpirun -np 2 and 4 run a static OSB fracture until its plate comes apart and stop at one process's re-solve with its bonds removed") {
  const std::vector<std::pair<std::string, std::string>> coarse{{"spacing: 0.0025", "spacing: 0.005"}, {"vtu: {every: 1}", "vtu: {every: 1}\n  csv: {every: 1}"}};
  const fs::path one = run_edited(PERIDOT_EXE, "osb/crack_neumann_uncorrected.yaml", coarse, "osb_apart_one");
  const std::string stopped = "stopped: equilibrium is no longer possible (singular system)";
  const auto report = deck_text::file_text(temp("osb_apart_one.out"));
  REQUIRE_THAT(report, Catch::Contains(stopped));
  const auto h1 = csv_columns::read(one / "osb_crack_neumann_uncorrected_history.csv");
  const auto d1 = field(one / "osb_crack_neumann_uncorrected.vtu", "damage");
  REQUIRE(h1.at("broken_bonds").back() > 100);
  for (int ranks : {2, 4}) {
    INFO(ranks << " ranks");
    const auto name = "osb_apart_np" + std::to_string(ranks);
    const fs::path out = run_edited(mpirun(ranks), "osb/crack_neumann_uncorrected.yaml", coarse, name);
    CHECK_THAT(deck_text::file_text(temp(name + ".out")), Catch::Contains(stopped));
    const auto hn = csv_columns::read(out / "osb_crack_neumann_uncorrected_history.csv");
    CHECK(hn.at("broken_bonds") == h1.at("broken_bonds"));
    CHECK(max_relative_difference(field_of_pieces(out / "osb_crack_neumann_uncorrected.pvtu", "damage"), d1) < 1e-12);
  }
}

// Arc length on N ranks: the two solves of each iteration are PETSc's, the constraint's dot
// products exact sums over the owned rows, so the ranks follow one process's arcs.
TEST_CASE("mpirun -np 2 follows the hard-loaded pre-cracked plate by arc length through softening as one process does, to the Newton tolerance") {
  const std::vector<std::pair<std::string, std::string>> edits{{"spacing: 0.2", "spacing: 0.5"},
                                                               {"horizon_factor: 8", "horizon_factor: 4"},
                                                               {"vtu: {every: 5}", "vtu: {every: 0}"},
                                                               {"png: {every: 5, field: damage}", "png: {every: 0, field: damage}"}};
  const std::string run = "rnp_precracked_hard";
  const fs::path one = run_edited(PERIDOT_EXE, "rnp/precracked_hard.yaml", edits, "arc_one");
  const auto serial = csv_columns::read(one / (run + "_load_steps.csv"));
  REQUIRE(serial.at("load_factor").back() == Approx(1.0));
  REQUIRE(serial.at("softening_bonds").back() > 300);
  // Arc length took more steps than the deck's 30 load steps, and the load fell on some.
  REQUIRE(serial.at("step").size() > 30);
  const fs::path out = run_edited(mpirun(2), "rnp/precracked_hard.yaml", edits, "arc_np2");
  CHECK_THAT(deck_text::file_text(out / (run + "_load_steps.csv")), Catch::Contains("petsc preonly/lu (mumps)"));
  const auto par = csv_columns::read(out / (run + "_load_steps.csv"));
  for (const std::string column : {"step", "iterations", "cuts", "softening_bonds"}) {
    INFO(column);
    CHECK((par.at(column) == serial.at(column)));
  }
  CHECK(max_relative_difference(par.at("load_factor"), serial.at("load_factor")) < 1e-8);
  CHECK(max_relative_difference(par.at("max_damage"), serial.at("max_damage")) < 1e-8);
  const auto h1 = csv_columns::read(one / (run + "_history.csv")), hn = csv_columns::read(out / (run + "_history.csv"));
  CHECK(max_relative_difference(hn.at("strain_J"), h1.at("strain_J")) < 1e-8);
}
