// peridot-bench-mesh: the nodal finite-element discretization of seed 003 on a structured
// mesh of the unit square: V_ij set-up time, and the force pass per directed bond of RNP and
// PMB on the mesh against PMB on the lattice of the same spacing and horizon.
//   usage: peridot-bench-mesh [cells = 316] [m = 4] [steps = 40]
#include <CLI/CLI.hpp>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <vector>
#include <fmt/core.h>
import peridot.models;
import peridot.quadrature;

namespace {

using namespace peridot;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// A smooth displacement so every bond has a non-zero strain, far below breaking.
VectorField smooth_field(const PointCloud& pc) {
  auto u = zero_field(pc.size());
  for (std::size_t i = 0; i < pc.size(); ++i) {
    u[0][i] = 1e-5 * std::sin(3 * pc.x[0][i]) * std::cos(2 * pc.x[1][i]);
    u[1][i] = 1e-5 * std::cos(pc.x[0][i] + pc.x[1][i]);
  }
  return u;
}

// Best wall time of one force pass over `steps` passes [s].
template <class Model>
double force_pass(const Model& model, Body& body, int steps) {
  const auto u = smooth_field(body.points);
  auto f = zero_field(body.size());
  double best = 1e300;
  for (int k = 0; k < steps; ++k) {
    const auto t0 = Clock::now();
    model.forces(body, u, f);
    best = std::min(best, seconds_since(t0));
  }
  return best;
}

}  // namespace

int main(int argc, char** argv) {
  int cells = 316, m = 4, steps = 40;
  CLI::App app{"peridot-bench-mesh: V_ij set-up and force passes per directed bond, mesh against lattice"};
  app.add_option("cells", cells, "cells per side of the unit square (nodes: (cells + 1)^2)")->check(CLI::Range(8, 5000));
  app.add_option("m", m, "horizon in mesh sizes, eps = m h")->check(CLI::Range(1, 32));
  app.add_option("steps", steps, "force passes timed (best of)")->check(CLI::Range(1, 100000));
  CLI11_PARSE(app, argc, argv);

  const double h = 1.0 / cells, eps = m * h;
  fmt::print("peridot-bench-mesh: {} threads, unit square, {} x {} cells, h = {:.4g}, eps = {} h\n", omp_get_max_threads(), cells, cells, h, m);
  Body mesh;
  mesh.points = mesh_points(structured_triangles({0, 0, 0}, {1, 1, 0}, cells, cells));
  const auto t0 = Clock::now();
  mesh.bonds = element_bonds(mesh.points, {.horizon = eps, .order = 2, .kernel = KernelShape::linear});
  const double vij = seconds_since(t0);
  mesh.density = 1;
  fmt::print("  mesh: {} nodes, {} directed bonds ({:.1f} per node), V_ij and bonds in {:.3f} s\n", mesh.size(), mesh.bonds.size(),
             double(mesh.bonds.size()) / double(mesh.size()), vij);

  Body grid;
  grid.points = lattice(rectangle({0, 0, 0}, {1, 1, 0}), {.spacing = h});
  grid.bonds = build_bonds(grid.points, {.horizon = eps});
  grid.density = 1;
  fmt::print("  lattice: {} points, {} directed bonds ({:.1f} per point)\n", grid.size(), grid.bonds.size(),
             double(grid.bonds.size()) / double(grid.size()));

  const Rnp rnp = Rnp::lipton(1, 1, eps, RnpInfluence::constant);
  const Pmb pmb = Pmb::from_elastic(1, 1e3, eps, Kinematics::plane_strain);
  const double per_lattice = force_pass(pmb, grid, steps) / double(grid.bonds.size());
  const double per_mesh_pmb = force_pass(pmb, mesh, steps) / double(mesh.bonds.size());
  const double per_mesh_rnp = force_pass(rnp, mesh, steps) / double(mesh.bonds.size());
  fmt::print("  force pass per directed bond: PMB lattice {:.2f} ns, PMB mesh {:.2f} ns ({:.2f}x), RNP mesh {:.2f} ns ({:.2f}x)\n",
             per_lattice * 1e9, per_mesh_pmb * 1e9, per_mesh_pmb / per_lattice, per_mesh_rnp * 1e9, per_mesh_rnp / per_lattice);
  // What PMB decks run on: a lean list (partner, float weight, mask), in single precision by default.
  Body lean;
  lean.points = grid.points;
  lean.bonds = build_bonds(lean.points, {.horizon = eps, .lean = true});
  lean.density = 1;
  Pmb exact = pmb;
  exact.lean_kernel = Pmb::LeanKernel::exact;
  const double per_single = force_pass(pmb, lean, steps) / double(lean.bonds.size());
  const double per_double = force_pass(exact, lean, steps) / double(lean.bonds.size());
  fmt::print("  PMB lattice on a lean list: single precision {:.2f} ns, double {:.2f} ns; RNP mesh / PMB single {:.2f}x\n", per_single * 1e9,
             per_double * 1e9, per_mesh_rnp / per_single);
  // What mesh decks run on since wave 3: PMB on a lean list (V_ij in float), RNP with
  // `bonds: compact` on a list without xi and |xi|.
  Body lean_mesh, compact_mesh;
  lean_mesh.points = compact_mesh.points = mesh.points;
  lean_mesh.bonds = element_bonds(mesh.points, {.horizon = eps, .order = 2, .kernel = KernelShape::linear, .lean = true});
  compact_mesh.bonds = element_bonds(mesh.points, {.horizon = eps, .order = 2, .kernel = KernelShape::linear, .geometry = false});
  lean_mesh.density = compact_mesh.density = 1;
  const double per_mesh_lean = force_pass(pmb, lean_mesh, steps) / double(lean_mesh.bonds.size());
  const double per_mesh_compact = force_pass(rnp, compact_mesh, steps) / double(compact_mesh.bonds.size());
  fmt::print("  mesh as decks store it: PMB on a lean list, single precision {:.2f} ns; RNP on a compact list {:.2f} ns ({:.2f}x PMB)\n",
             per_mesh_lean * 1e9, per_mesh_compact * 1e9, per_mesh_compact / per_mesh_lean);
  // RNP with `list_precision: single`: the same lean list as PMB's, in single precision.
  const double per_mesh_rnp_single = force_pass(rnp, lean_mesh, steps) / double(lean_mesh.bonds.size());
  fmt::print("  RNP on the mesh's lean list in single precision {:.2f} ns ({:.2f}x PMB single, {:.2f}x faster than RNP's full list)\n",
             per_mesh_rnp_single * 1e9, per_mesh_rnp_single / per_mesh_lean, per_mesh_rnp / per_mesh_rnp_single);
  return 0;
}
