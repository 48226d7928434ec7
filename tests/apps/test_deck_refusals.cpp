// Decks refused while they are read and composed: DeckError names the field, its value and
// what is allowed, and no file or folder is written. In-process through the library, as
// `peridot run` and `peridot check` compose them; test_cli.cpp checks that the CLI turns such a
// refusal into exit code 2 on stderr.
#include <catch2/catch.hpp>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include "../support/deck_text.hpp"
#include "../support/in_process.hpp"

namespace fs = std::filesystem;

namespace {

fs::path temp(const std::string& name) { return in_process::temp("peridot_refusals_", name); }

// The shipped deck `source` with `from` replaced by `to`, written to a per-process file.
fs::path deck_with(const std::string& name, const std::string& from, const std::string& to,
                   const std::string& source = "crack_branching_2d.yaml") {
  const auto text = deck_text::file_text(fs::path(PERIDOT_SOURCE_DIR) / "data/decks" / source);
  const fs::path file = temp(name + ".yaml");
  std::ofstream(file) << deck_text::replaced(text, from, to);
  return file;
}

void require_refused(const fs::path& deck, const std::string& message) {
  const fs::path out = temp("out");
  fs::remove_all(out);
  const auto why = in_process::refusal(deck, out);
  INFO(deck.filename().string() << ": " << why.substr(0, 400));
  CHECK(why.find(message) != std::string::npos);
  CHECK_FALSE(fs::exists(out));  // nothing written, not even the directory
  if (deck.filename().string().starts_with("peridot_refusals_")) fs::remove(deck);
}

}  // namespace

TEST_CASE("bad values are refused naming the field and the value or what is allowed, before any file") {
  require_refused(deck_with("zero_horizon", "horizon_factor: 4", "horizon: 0"), "discretization.horizon = 0");
  require_refused(deck_with("coarse", "horizon_factor: 4", "horizon: 1.0e-4"), "must be >= spacing");
  require_refused(deck_with("empty", "rectangle: {min: [0.0, 0.0], max: [0.1, 0.04]}",
                             "difference: [{rectangle: {min: [0.0, 0.0], max: [0.1, 0.04]}}, {rectangle: {min: [-1, -1], max: [1, 1]}}]"),
                   "no lattice points");
  require_refused(deck_with("nan", "youngs_modulus: 72.0e9", "youngs_modulus: .nan"), "material.youngs_modulus");
}

TEST_CASE("decks that would overflow, exhaust memory or write outside the output directory are refused before any file") {
  // Bonds that could never fit: refused with the estimate, not allocated until killed.
  require_refused(deck_with("huge_horizon", "horizon_factor: 4", "horizon_factor: 4000"), "directed bonds");
  // double -> integer conversions that used to overflow (found by the sanitizer build).
  require_refused(deck_with("end_time", "end_time: 46.0e-6", "end_time: 1e300"), "steps");
  require_refused(deck_with("light", "density: 2440.0", "density: 1e-300"), "steps");
  require_refused(deck_with("wide", "max: [0.1, 0.04]", "max: [1e20, 0.04]"), "lattice sites");
  require_refused(deck_with("infinite", "{min: [0.0, 0.0], max: [0.1, 0.04]}", "{min: [-1e308, 0.0], max: [1e308, 0.04]}"), "lattice sites");
  // The YAML contract.
  require_refused(deck_with("duplicate", "density: 2440.0", "density: 2440.0\n  density: 1.0"), "'density' appears more than once");
  require_refused(deck_with("slash", "name: crack_branching_2d", "name: /tmp/elsewhere"), "name = '/tmp/elsewhere'");
  require_refused(deck_with("empty_name", "name: crack_branching_2d", "name: ''"), "name = ''");
  require_refused(deck_with("typo", "density: 2440.0", "densty: 2440.0"), "unknown key 'densty' (did you mean 'density'?)");
  require_refused(deck_with("crack_tip_3d", "csv: {every: 50}", "csv: {every: 50}\n  crack_tip: {every: 10}", "crack_branching_3d.yaml"),
                   "output.crack_tip: crack-tip tracking is implemented for 2D runs only");
  require_refused(fs::temp_directory_path(), "is a directory");
}

TEST_CASE("keys the chosen solver does not use, and unsupported combinations, are refused naming both") {
  require_refused(deck_with("static_pmb", "type: explicit", "type: static"), "solver.type = 'static'");
  require_refused(deck_with("pmb_newmark", "type: explicit", "type: newmark"), "material.model = 'pmb' with solver.type = 'newmark'");
  require_refused(deck_with("gmls_pmb", "quadrature: volume", "quadrature: gmls"),
                   "discretization.quadrature = 'gmls' with material.model = 'pmb'");
  const auto lps = [](const std::string& from, const std::string& to) { return deck_with("static", from, to, "lps/hollow_disk.yaml"); };
  require_refused(lps("solver:", "boundaries:\n  - {type: velocity, region: {disk: {center: [0, 0], radius: 2}}, value: [0, 0]}\nsolver:"),
                   "boundaries: not used by solver.type = 'static'");
  require_refused(lps("youngs_modulus: 1.0", "youngs_modulus: 1.0\n  density: 1.0"), "material.density: not used by solver.type = 'static'");
  require_refused(lps("type: static", "type: static\n  end_time: 1.0"), "solver.end_time: not used by solver.type = 'static'");
  // The lattice stencil holds PMB on an unperturbed lattice, and no per-bond pair forces.
  require_refused(deck_with("stencil_typo", "quadrature: volume", "quadrature: volume\n  bonds: grid"), "discretization.bonds = 'grid'");
  require_refused(deck_with("stencil_jitter", "quadrature: volume", "quadrature: volume\n  bonds: stencil\n  perturbation: 0.1"),
                   "discretization.bonds = 'stencil' needs an unperturbed lattice (discretization.perturbation = 0.1; allowed 0)");
  {
    const fs::path stress = deck_with("stencil_stress", "field: damage}", "field: von_mises}");
    std::ifstream in(stress);
    std::stringstream ss;
    ss << in.rdbuf();
    std::string s = ss.str();
    s.replace(s.find("quadrature: volume"), 18, "quadrature: volume\n  bonds: stencil");
    std::ofstream(stress) << s;
    require_refused(stress, "discretization.bonds = 'stencil' stores no per-bond pair forces");
  }
  // A Neumann region whose surface is unknown cannot give x-bar for (4.6).
  require_refused(lps("region: {disk: {center: [0.0, 0.0], radius: 1.0}}", "region: {polygon: {vertices: [[-1, -1], [1, -1], [0, 1]]}}"),
                   "has no surface projection");
}

TEST_CASE("quasi-static and static OSB decks with PETSc options they cannot use, or that PETSc refuses, are refused naming them") {
  const std::string qs = "rnp/plate_2d.yaml", osb = "osb/traction.yaml";
  require_refused(deck_with("qs_options", "tolerance: 1.0e-10", "tolerance: 1.0e-10\n  petsc_options: \"-ksp_type cg\"", qs),
                  "petsc_options: needs linear_solver: petsc (it is 'auto')");
  require_refused(
      deck_with("qs_krylov", "tolerance: 1.0e-10", "tolerance: 1.0e-10\n  linear_solver: petsc\n  petsc_options: \"-ksp_type no_such_krylov\"", qs),
      "no_such_krylov");
  require_refused(deck_with("osb_pc", "type: static", "type: static\n  linear_solver: petsc\n  petsc_options: \"-pc_type no_such_pc\"", osb),
                  "no_such_pc");  // Arc length corrects the load factor inside Newton's iterations, which Ceres does not expose.
  require_refused(deck_with("qs_arc_ceres", "tolerance: 1.0e-10", "tolerance: 1.0e-10\n  nonlinear: ceres\n  control: arc_length", qs),
                  "solver.control = 'arc_length'");
  require_refused(deck_with("qs_arc_typo", "tolerance: 1.0e-10", "tolerance: 1.0e-10\n  control: arclength", qs), "solver.control");
}

TEST_CASE("bad static OSB decks are refused naming the field, before any file") {
  const std::string src = "osb/traction.yaml";
  require_refused(deck_with("osb_both", "right:  {x: {traction: 1.0e6}", "right:  {x: {traction: 1.0e6, displacement: 0}", src),
                   "static.edges.right.x: give exactly one of displacement [m] or traction [Pa]");
  require_refused(deck_with("osb_order", "taylor_order: 1 ", "taylor_order: 4 ", src), "static.taylor_order = 4");
  require_refused(deck_with("osb_uncorrected_order", "boundary_method: fictitious_taylor", "boundary_method: outermost_nodes", src),
                   "static.taylor_order: only boundary_method = 'fictitious_taylor' extrapolates");
  require_refused(deck_with("osb_gmls", "quadrature: cell_area", "quadrature: gmls", src), "discretization.quadrature = 'gmls' with material.model = 'osb'");
  require_refused(deck_with("osb_collar", "boundary_method: fictitious_taylor", "boundary_method: collar_traction", src), "boundary_method = 'collar_traction'");
  require_refused(deck_with("osb_disk", "rectangle: {min: [-0.15, -0.1], max: [0.15, 0.1]}", "disk: {center: [0, 0], radius: 0.1}", src),
                   "static OSB needs a rectangle");
  require_refused(deck_with("osb_cells", "max: [0.15, 0.1]}", "max: [0.155, 0.1]}", src), "whole multiples of the spacing");
  require_refused(deck_with("osb_fracture", "poisson_ratio: 0.2", "poisson_ratio: 0.2\n  fracture_energy: 196", src), "static.fracture");
  require_refused(deck_with("osb_nu", "poisson_ratio: 0.2", "poisson_ratio: 0.5", src), "material.poisson_ratio = 0.5");
  require_refused(deck_with("osb_gradient", "gradient: [[1.0e-3, 0], [0, -2.0e-4]]", "gradient: [1.0e-3, 0]", src), "static.reference.gradient");
}

TEST_CASE("bad dynamic LPS decks are refused naming the field, before any file") {
  const std::string src = "lps_dynamic/glass_plate.yaml";
  require_refused(deck_with("lps_dt", "  dt: 6.25e-8              # [s], 672 steps\n", "", src), "solver.dt");
  require_refused(deck_with("lps_both", "    normal: 2.0e6          # T_n [Pa], pulling", "    normal: 2.0e6\n    value: [0, 2.0e6]", src),
                   "takes either value");
  require_refused(deck_with("lps_inside", "region: {rectangle: {min: [-0.01, 0.02], max: [0.11, 0.03]}}",
                             "region: {rectangle: {min: [0.01, 0.0], max: [0.02, 0.01]}}", src),
                   "its region holds none");
  require_refused(deck_with("lps_motion", "    normal: 2.0e6          # T_n [Pa], pulling", "    normal: 2.0e6\n  - {name: clamp, type: displacement, region: {rectangle: {min: [0.0, -0.02], max: [0.001, 0.02]}}, value: [0, 0]}", src),
                   "not prescribed motion");
  require_refused(deck_with("lps_g0", "fracture_energy: 3.8 ", "fracture_energy: -1 ", src), "material.fracture_energy = -1");
  require_refused(deck_with("lps_stress", "field: damage}", "field: von_mises}", src), "output.png: field = 'von_mises'");
  require_refused(deck_with("lps_tol", "tolerance: 1.0e-8", "tolerance: 0", src), "solver.tolerance = 0");
}

// The estimate guards against allocating what cannot fit, so it must stay above what a set-up
// really takes, without refusing a deck that would fit. The glass plate at h = 0.2 mm: 100,000
// points, 4.74 M directed bonds, 0.75 GB peak resident memory through `peridot check` (measured,
// ci build). The old estimate (the static solve's bytes per bond) asked 2.5 GB of it.
TEST_CASE("a dynamic LPS deck is refused when its set-up would not fit, and only then") {
  const auto deck = deck_with("lps_memory", "spacing: 5.0e-4 ", "spacing: 2.0e-4 ", "lps_dynamic/glass_plate.yaml");
  const fs::path out = temp("lps_memory_out");
  struct Uncap {
    ~Uncap() { peridot::limit_memory_bytes(0); }
  } uncap;
  const double gib = 1024.0 * 1024.0 * 1024.0;
  peridot::limit_memory_bytes(0.5 * gib);  // below the measured 0.75 GB
  CHECK_THAT(in_process::refusal(deck, out), Catch::Contains("directed bonds"));
  CHECK_FALSE(fs::exists(out));
  peridot::limit_memory_bytes(1.0 * gib);  // above it
  peridot::RunOptions options;
  options.out_dir = out;
  CHECK_NOTHROW(peridot::Simulation(peridot::read_deck(deck), options));
  fs::remove_all(out);
  fs::remove(deck);
}
