module;
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>
#include <fmt/core.h>
export module peridot.problem:static_setup;
import peridot.io;
import peridot.quadrature;
import peridot.implicit;
import peridot.deck;

export namespace peridot {

// A static LPS problem built from a deck: the cloud over Omega and its exterior band with
// roles, bonds with quadrature weights and gamma masks, the model, the reference solution
// and the callbacks the static solver reads. The callbacks hold copies, never references
// into the set-up, so a StaticSetup can be moved and copied freely.
struct StaticSetup {
  Body body;
  Lps model;
  ElasticSolution reference;
  StaticLpsProblem problem;
  StaticOptions options;
  QuadratureReport quadrature;
};

StaticSetup setup_static(const Problem& problem);

// Checks the PETSc options a static run would use, the deck's solver.petsc_options and the
// command line's, without solving: unknown KSP or PC types throw std::invalid_argument.
void check_petsc_options(const StaticSetup& setup);

// L2(Omega) errors over the interior points, sqrt(sum_i V_i |e_i|^2), absolute and relative
// to the reference's own L2 norm.
struct StaticErrors {
  double u = 0, theta = 0;
  double u_relative = 0, theta_relative = 0;
};

StaticErrors static_errors(const StaticSetup& setup, const StaticResult& result);

}  // namespace peridot

namespace peridot {

namespace {

ElasticSolution make_reference(const Problem& p, ElasticConstants c) {
  const auto& r = p.statics.reference;
  if (r.type == "linear_patch") return linear_patch(c);
  if (r.type == "manufactured_sine") return manufactured_sine(r.A, c);
  if (r.type == "kirsch_hole") return kirsch_hole(r.radius, r.sigma0, c);
  if (r.type == "hollow_disk") return hollow_disk(r.inner_radius, r.outer_radius, r.pressure, c);
  if (r.type == "circular_inclusion") {
    const auto& in = p.inclusions.at(0);
    return circular_inclusion(r.radius, r.inclusion_stress, lame(in.youngs_modulus, in.poisson_ratio, p.material.kinematics), c);
  }
  throw DeckError(fmt::format("static.reference.type = '{}': unknown", r.type));
}

}  // namespace

StaticSetup setup_static(const Problem& p) {
  if (p.solver_kind != SolverKind::static_linear || p.material.model != ModelKind::lps)
    throw std::invalid_argument("setup_static: the deck is not a static LPS problem");
  StaticSetup s{};
  const ElasticConstants c = lame(p.material.youngs_modulus, p.material.poisson_ratio, p.material.kinematics);
  s.reference = make_reference(p, c);

  Shape neumann;
  for (const auto& n : p.statics.neumann) neumann = neumann.empty() ? n.region : unite(neumann, n.region);
  try {
    require_lattice_fits(p.body.bounds(), p.lattice.spacing, p.dim, p.statics.band_factor * p.horizon);
    s.body.points = lattice_with_exterior(p.body, p.lattice, {.band = p.statics.band_factor * p.horizon, .neumann = neumann});
  } catch (const std::invalid_argument& e) {
    throw DeckError(fmt::format("geometry.body: {} (discretization.spacing = {:g} m)", e.what(), p.lattice.spacing));
  }
  auto& pc = s.body.points;
  require_bonds_fit(pc.size(), pc.dim, p.horizon, p.lattice.spacing, bytes_per_bond_static);
  const auto interior = std::ranges::count(pc.role, Role::interior);
  if (interior == 0) throw DeckError(fmt::format("geometry.body: contains no lattice points at spacing {:g} m", p.lattice.spacing));
  // Weights come from the full ball (seed 000 Sec. 4): pre-cracks only clear gamma below.
  s.body.bonds = build_bonds(pc, {.horizon = p.horizon});
  s.body.density = p.material.density;

  // Weights on interior points and on the collar points their theta rows read.
  std::vector<std::uint8_t> active(pc.size(), 0);
  for (std::size_t i = 0; i < pc.size(); ++i)
    if (pc.role[i] == Role::interior) {
      active[i] = 1;
      for (auto j : s.body.bonds.neighbors(i))
        if (pc.role[j] == Role::collar) active[j] = 1;
    }
  QuadratureOptions qo;
  qo.rule = p.material.quadrature;
  qo.active = active;
  try {
    s.quadrature = compute_weights(pc, s.body.bonds, qo);
  } catch (const std::runtime_error& e) {
    throw DeckError(fmt::format("discretization: quadrature weights failed: {}", e.what()));
  }
  break_neumann_bonds(pc, s.body.bonds, neumann);
  cut_bonds(pc, s.body.bonds, p.cracks);

  std::vector<double> lambda(pc.size(), c.lambda), mu(pc.size(), c.mu);
  for (const auto& in : p.inclusions) {
    const auto ci = lame(in.youngs_modulus, in.poisson_ratio, p.material.kinematics);
    for (auto i : select_points(pc, in.region)) lambda[i] = ci.lambda, mu[i] = ci.mu;
  }
  s.model = Lps::make(2, p.horizon, std::move(lambda), std::move(mu));

  const ElasticSolution ref = s.reference;
  s.problem.body_force = [ref](const Vec3& x) { return ref.body_force(x); };
  s.problem.dirichlet = [ref](const Vec3& x) { return ref.displacement(x); };
  if (!p.statics.neumann.empty())
    s.problem.traction = [ref, specs = p.statics.neumann](const Body& body, std::size_t i, const LpsFrame& f) {
      // The Neumann boundary whose region holds the nearest missing partner of i.
      const auto& bl = body.bonds;
      std::size_t pick = 0;
      double best = std::numeric_limits<double>::infinity();
      for (auto b = bl.offset[i]; b < bl.offset[i + 1]; ++b) {
        if (bl.intact[b] || bl.length[b] >= best) continue;
        const auto q = body.points.position(std::size_t(bl.neighbor[b]));
        for (std::size_t k = 0; k < specs.size(); ++k)
          if (specs[k].region.contains(q)) best = bl.length[b], pick = k;
      }
      const auto& spec = specs[pick];
      const auto x = body.points.position(i);
      // Components of a traction vector in the frame (n, p = (-n_y, n_x)).
      const auto components = [](const std::array<double, 2>& T, const std::array<double, 2>& n) {
        return std::array<double, 2>{T[0] * n[0] + T[1] * n[1], -T[0] * n[1] + T[1] * n[0]};
      };
      // The deck validated that the region projects whenever x-bar or its normal is needed.
      const auto s = spec.region.project(x);
      std::optional<std::array<double, 2>> exact;
      if (s) exact = std::array<double, 2>{s->normal[0], s->normal[1]};
      NeumannLoad load;
      if (spec.exact_normal && exact) load.normal = exact;
      const auto& n = load.normal ? *load.normal : f.n;
      if (spec.from_reference && spec.at_projection && s) load.T = components(ref.traction(s->point, *exact), *exact);
      else if (spec.from_reference) load.T = components(ref.traction(x, n), n);
      else load.T = components({spec.traction[0], spec.traction[1]}, n);
      return load;
    };
  s.options.solver = p.statics.linear_solver;
  s.options.petsc.options = p.statics.petsc_options;
  return s;
}

StaticErrors static_errors(const StaticSetup& s, const StaticResult& r) {
  const auto& pc = s.body.points;
  double eu = 0, et = 0, nu = 0, nt = 0;
  for (std::size_t i = 0; i < pc.size(); ++i) {
    if (pc.role[i] != Role::interior) continue;
    const auto x = pc.position(i);
    const auto u0 = s.reference.displacement(x);
    const double t0 = s.reference.dilatation(x), V = pc.volume[i];
    eu += V * (std::pow(r.u[0][i] - u0[0], 2) + std::pow(r.u[1][i] - u0[1], 2));
    et += V * std::pow(r.theta[i] - t0, 2);
    nu += V * (u0[0] * u0[0] + u0[1] * u0[1]);
    nt += V * t0 * t0;
  }
  StaticErrors e{std::sqrt(eu), std::sqrt(et), 0, 0};
  e.u_relative = nu > 0 ? e.u / std::sqrt(nu) : e.u;
  e.theta_relative = nt > 0 ? e.theta / std::sqrt(nt) : e.theta;
  return e;
}

void check_petsc_options(const StaticSetup& s) {
  if (s.options.solver == LinearSolver::petsc && (!s.options.petsc.options.empty() || !parallel::command_line_options().empty()))
    parallel::check_ksp_options(s.options.petsc);
}

}  // namespace peridot
