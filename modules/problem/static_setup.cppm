export module peridot.problem:static_setup;
import peridot.std;
import peridot.io;
import peridot.quadrature;
import peridot.implicit;
import peridot.deck;
import :setup;

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
  QuadratureReport quadrature;  // on N ranks: its figures over the ranks' owned points
  // On N ranks: which local points this rank owns (Slab: owned, ghosts with their owners), and
  // the interior numbering the solve takes. Absent on one process.
  std::optional<Slab> slab;
  std::optional<StaticParts> parts;
};

StaticSetup setup_static(const Problem& problem);

// Rank `rank`'s share of a static LPS deck on `ranks` MPI ranks (collective): every rank
// generates the cloud with its exterior band (positions and roles) and cuts it by recursive
// coordinate bisection, then builds bonds, GMLS weights, Neumann and pre-crack masks and the
// model's moduli only for the points within three bond reaches of its owned points' box. Each
// row within two reaches is the one-rank row, weights included (the same active rule on a
// complete ball), which covers every row its owned rows and their energies read. Ghosts are all
// held points it does not own, refreshed from their owners after the solve.
StaticSetup setup_static_part(const Problem& problem, int rank, int ranks);

// Checks the PETSc options a run would use, the deck's solver.petsc_options and the command
// line's, without solving: unknown KSP or PC types throw DeckError naming where they came from.
void check_petsc_options(const parallel::KspOptions& options);
// The same for a static run that solves on PETSc.
void check_petsc_options(const StaticSetup& setup);

// L2(Omega) errors over the interior points, sqrt(sum_i V_i |e_i|^2), absolute and relative
// to the reference's own L2 norm. On N ranks (setup.slab) a sum over every rank's owned points:
// collective.
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
  if (r.type == "linear_patch") return linear_patch(c, p.dim);
  if (r.type == "manufactured_sine") return manufactured_sine(r.A, c, p.dim);
  if (r.type == "kirsch_hole") return kirsch_hole(r.radius, r.sigma0, c);
  if (r.type == "hollow_disk") return hollow_disk(r.inner_radius, r.outer_radius, r.pressure, c);
  if (r.type == "circular_inclusion") {
    const auto& in = p.inclusions.at(0);
    return circular_inclusion(r.radius, r.inclusion_stress, lame(in.youngs_modulus, in.poisson_ratio, p.material.kinematics), c);
  }
  if (r.type == "spherical_inclusion") {
    const auto& in = p.inclusions.at(0);
    return spherical_inclusion(r.radius, r.inclusion_stress, lame(in.youngs_modulus, in.poisson_ratio, p.material.kinematics), c);
  }
  throw DeckError(fmt::format("static.reference.type = '{}': unknown", r.type));
}

// The smallest rotation that takes the unit vector `from` onto `to`, applied to v (Rodrigues).
// In 2D it is the rotation by the angle between the normals, which also takes one tangent
// onto the other.
std::array<double, 3> rotate_onto(const std::array<double, 3>& v, const std::array<double, 3>& from, const std::array<double, 3>& to) {
  const auto cross = [](const std::array<double, 3>& a, const std::array<double, 3>& b) {
    return std::array<double, 3>{a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
  };
  const auto dot = [](const std::array<double, 3>& a, const std::array<double, 3>& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; };
  const auto k = cross(from, to);
  const double c = dot(from, to);
  if (c <= -1 + 1e-12) return {-v[0], -v[1], -v[2]};  // opposite normals: no preferred axis
  // v c + (k x v) + k (k . v) / (1 + c), with |k| = sin of the angle.
  const auto kv = cross(k, v);
  const double kdotv = dot(k, v) / (1 + c);
  return {v[0] * c + kv[0] + k[0] * kdotv, v[1] * c + kv[1] + k[1] * kdotv, v[2] * c + kv[2] + k[2] * kdotv};
}

}  // namespace

namespace {

// The cloud over the body and its exterior band (positions and roles), and the union of the
// Neumann regions.
// The deck's Neumann regions as one shape (empty: none).
Shape static_neumann(const Problem& p) {
  Shape neumann;
  for (const auto& n : p.statics.neumann) neumann = neumann.empty() ? n.region : unite(neumann, n.region);
  return neumann;
}

PointCloud static_cloud(const Problem& p, Shape& neumann) {
  neumann = static_neumann(p);
  PointCloud pc;
  try {
    require_lattice_fits(p.body.bounds(), p.lattice.spacing, p.dim, p.statics.band_factor * p.horizon);
    pc = lattice_with_exterior(p.body, p.lattice, {.band = p.statics.band_factor * p.horizon, .neumann = neumann});
  } catch (const std::invalid_argument& e) {
    throw DeckError(fmt::format("geometry.body: {} (discretization.spacing = {:g} m)", e.what(), p.lattice.spacing));
  }
  if (std::ranges::count(pc.role, Role::interior) == 0)
    throw DeckError(fmt::format("geometry.body: contains no lattice points at spacing {:g} m", p.lattice.spacing));
  return pc;
}

// Whether point i gets weights: interior points, and the collar points their theta rows read
// (those with an interior partner).
bool weighed(const PointCloud& pc, const BondList& bonds, std::size_t i) {
  if (pc.role[i] == Role::interior) return true;
  if (pc.role[i] != Role::collar) return false;
  for (auto j : bonds.neighbors(i))
    if (pc.role[j] == Role::interior) return true;
  return false;
}

// The set-up on `pc` (the whole cloud, or a rank's near points): bonds, weights where the ball
// is whole (`complete`; empty: everywhere), masks, moduli, the reference and the callbacks.
StaticSetup static_setup_on(const Problem& p, PointCloud pc, const Shape& neumann, std::span<const std::uint8_t> complete) {
  StaticSetup s{};
  const ElasticConstants c = lame(p.material.youngs_modulus, p.material.poisson_ratio, p.material.kinematics);
  s.reference = make_reference(p, c);
  s.body.points = std::move(pc);
  const auto& points = s.body.points;
  require_bonds_fit(points.size(), points.dim, p.horizon, p.lattice.spacing, bytes_per_bond_static);
  // Weights come from the full ball (seed 000 Sec. 4): pre-cracks only clear gamma below.
  s.body.bonds = build_bonds(points, {.horizon = p.horizon});
  s.body.density = p.material.density;
  std::vector<std::uint8_t> active(points.size(), 0);
  for (std::size_t i = 0; i < points.size(); ++i) active[i] = (complete.empty() || complete[i]) && weighed(points, s.body.bonds, i);
  QuadratureOptions qo;
  qo.rule = p.material.quadrature;
  qo.active = active;
  try {
    s.quadrature = compute_weights(points, s.body.bonds, qo);
  } catch (const std::runtime_error& e) {
    throw DeckError(fmt::format("discretization: quadrature weights failed: {}", e.what()));
  }
  break_neumann_bonds(points, s.body.bonds, neumann);
  cut_bonds(points, s.body.bonds, p.cracks);

  std::vector<double> lambda(points.size(), c.lambda), mu(points.size(), c.mu);
  for (const auto& in : p.inclusions) {
    const auto ci = lame(in.youngs_modulus, in.poisson_ratio, p.material.kinematics);
    for (auto i : select_points(points, in.region)) lambda[i] = ci.lambda, mu[i] = ci.mu;
  }
  s.model = Lps::make(p.dim, p.horizon, std::move(lambda), std::move(mu));

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
      // The deck validated that the region projects whenever x-bar or its normal is needed.
      const auto s = spec.region.project(x);
      std::optional<std::array<double, 3>> exact;
      if (s) exact = std::array<double, 3>{s->normal[0], s->normal[1], s->normal[2]};
      NeumannLoad load;
      if (spec.exact_normal && exact) load.normal = exact;
      const auto& n = load.normal ? *load.normal : f.n;
      // sigma n at x-bar, with its components in the exact frame kept in the frame (4.6) uses.
      if (spec.from_reference && spec.at_projection && s) load.T = rotate_onto(ref.traction(s->point, *exact), *exact, n);
      else if (spec.from_reference) load.T = ref.traction(x, n);
      else load.T = {spec.traction[0], spec.traction[1], spec.traction[2]};
      return load;
    };
  s.options.solver = p.statics.linear_solver;
  s.options.petsc.options = p.statics.petsc_options;
  // 3D balls hold ~180 partners at delta = 3.5 h and LU fills in badly: at 16,384 unknowns
  // (N = 16) MUMPS took 157 s and 2.3 GB here, GMRES with BoomerAMG 17.5 s and 1.4 GB. Below
  // 5000 unknowns (N = 8: 1 s) LU stays, so small 3D patch tests see no iteration error.
  if (p.dim == 3) s.options.petsc.direct_below = 5000;
  return s;
}


}  // namespace

StaticSetup setup_static(const Problem& p) {
  if (p.solver_kind != SolverKind::static_linear || p.material.model != ModelKind::lps)
    throw std::invalid_argument("setup_static: the deck is not a static LPS problem");
  Shape neumann;
  PointCloud pc = static_cloud(p, neumann);
  return static_setup_on(p, std::move(pc), neumann, {});
}

// A static part's layout and numbering: `first` is where each rank's interior numbers start
// (ranks + 1 entries), owner(j) and unknown(j) (-1: none) those of near point j.
template <class Owner, class Unknown>
void set_static_part(StaticSetup& s, const std::vector<std::int64_t>& near, const std::vector<std::int64_t>& first, int rank, int ranks,
                     std::size_t global_size, Owner owner, Unknown unknown) {
  StaticParts parts;
  parts.first = first[std::size_t(rank)];
  parts.count = first[std::size_t(rank) + 1] - parts.first;
  parts.global = first.back();
  parts.unknown.assign(near.size(), -1);
  Slab slab;
  slab.rank = rank;
  slab.ranks = ranks;
  slab.axis = -1;
  slab.global_size = global_size;
  slab.local_ids = near;
  slab.is_owned.assign(near.size(), 0);
  for (std::size_t j = 0; j < near.size(); ++j) {
    parts.unknown[j] = unknown(j);
    const int o = owner(j);
    if (o == rank) {
      slab.owned.push_back(std::int64_t(j));
      slab.is_owned[j] = 1;
    } else {
      slab.ghost.push_back(std::int64_t(j));
      slab.ghost_owner.push_back(o);
    }
  }
  s.parts = std::move(parts);
  s.slab = std::move(slab);
}

// Rank `rank`'s part of the cloud from grids alone (cloud_grids): the ranks own bricks of the
// cloud's grid (collar and ghosts included, so every point has one owner), a rank makes the
// sites within three bond reaches of its brick and weighs those within two. Interior points are
// numbered rank after rank, each brick's in global order: every rank counts every rank's from
// the cut and the interior sites alone (a box body's grid, or the runs of sites whose points lie
// in the body). False, with nothing built, where a brick holds no interior point (a ring's
// middle): the caller then cuts by coordinate bisection.
bool static_part_from_grids(const Problem& p, const CloudGrids& grids, int rank, int ranks, StaticSetup& s) {
  const double h = p.lattice.spacing, band = p.statics.band_factor * p.horizon;
  BrickCut cut;
  try {
    require_lattice_fits(p.body.bounds(), h, p.dim, band);
    cut = brick_cut(grids.cloud, ranks);
  } catch (const std::invalid_argument& e) {
    throw DeckError(fmt::format("geometry.body: {} (discretization.spacing = {:g} m, mpirun -np {})", e.what(), h, ranks));
  }
  // The interior sites in the cloud's grid, each brick's numbered in site order, and where each
  // brick's numbers start.
  const BoxLattice interior = grids.body.full() ? keep_sites(grids.cloud, [&](std::int64_t g) { return grids.body_id(g) >= 0; }) : grids.body;
  std::vector<BoxNumbering> numbering;
  std::vector<std::int64_t> first(std::size_t(ranks) + 1, 0);
  for (int r = 0; r < ranks; ++r) {
    numbering.emplace_back(interior, cut.brick(r, 0));
    if (numbering.back().size() == 0) return false;
    first[std::size_t(r) + 1] = first[std::size_t(r)] + numbering.back().size();
  }
  const Shape neumann = static_neumann(p);
  auto n = grids.neighbourhood(cut.brick(rank, 0), p.horizon + h, p.body, {.band = band, .neumann = neumann});
  const auto near = std::move(n.sites);
  s = static_setup_on(p, std::move(n.points), neumann, n.complete);
  const auto& m = grids.cloud.m;
  set_static_part(s, near, first, rank, ranks, grids.cloud.size(), [&](std::size_t j) { return cut.owner_of(near[j]); },
                  [&](std::size_t j) -> std::int64_t {
                    const auto g = near[j];
                    if (grids.body_id(g) < 0) return -1;
                    const int o = cut.owner_of(g);
                    return first[std::size_t(o)] + numbering[std::size_t(o)].index(g % m[0], (g / m[0]) % m[1], g / (m[0] * m[1]));
                  });
  s.slab->axis = cut.axis;
  s.slab->grid = cut.grid;
  return true;
}

StaticSetup setup_static_part(const Problem& p, int rank, int ranks) {
  if (p.solver_kind != SolverKind::static_linear || p.material.model != ModelKind::lps)
    throw std::invalid_argument("setup_static_part: the deck is not a static LPS problem");
  StaticSetup s;
  const auto grids = cloud_grids(p, p.statics.band_factor * p.horizon, true);
  parallel::together("set-up", [&] {
    if (grids && static_part_from_grids(p, *grids, rank, ranks, s)) return;
    Shape neumann;
    const PointCloud pc = static_cloud(p, neumann);
    const std::vector<int> owner = owners_of(pc, ranks);
    const NearPart part = near_part(p, pc, pc, owner, rank);
    const auto& near = part.ids;
    s = static_setup_on(p, subset(pc, near), neumann, part.complete);
    // Interior points are numbered rank after rank, each rank's in global order.
    std::vector<std::int64_t> first(std::size_t(ranks) + 1, 0), at(pc.size(), -1);
    for (std::size_t g = 0; g < pc.size(); ++g)
      if (pc.role[g] == Role::interior) at[g] = first[std::size_t(owner[g]) + 1]++;
    for (int r = 0; r < ranks; ++r) first[std::size_t(r) + 1] += first[std::size_t(r)];
    set_static_part(s, near, first, rank, ranks, pc.size(), [&](std::size_t j) { return owner[std::size_t(near[j])]; },
                    [&](std::size_t j) {
                      const auto g = std::size_t(near[j]);
                      return at[g] >= 0 ? first[std::size_t(owner[g])] + at[g] : std::int64_t(-1);
                    });
  }, is_input_error);
  // Where each ghost is on its owner, and the weights' figures over the owned points.
  auto& slab = *s.slab;
  std::vector<std::int64_t> ghost_ids;
  for (auto g : slab.ghost) ghost_ids.push_back(slab.local_ids[std::size_t(g)]);
  slab.ghost_owner_index = parallel::index_on_owners(ghost_ids, slab.ghost_owner, slab.local_ids);
  auto& q = s.quadrature;
  std::uint64_t points = 0, bonds = 0, negative = 0;
  double worst[2] = {0, 0};
  for (auto j : slab.owned) {
    const auto i = std::size_t(j);
    if (!weighed(s.body.points, s.body.bonds, i)) continue;
    ++points;
    bonds += s.body.bonds.count(i);
    negative += q.negative[i];
    worst[0] = std::max(worst[0], q.residual[i]);
    worst[1] = std::max(worst[1], q.condition[i]);
  }
  parallel::sum_over_ranks(points);
  parallel::sum_over_ranks(bonds);
  parallel::sum_over_ranks(negative);
  parallel::max_over_ranks(std::span<double>(worst, 2));
  q.points = points;
  q.bonds = bonds;
  q.total_negative = negative;
  q.max_residual = worst[0];
  q.max_condition = worst[1];
  q.seconds = -parallel::min_over_ranks(-q.seconds);
  return s;
}

StaticErrors static_errors(const StaticSetup& s, const StaticResult& r) {
  const auto& pc = s.body.points;
  // Exact sums, over the owned points on N ranks: the same figures for any cut.
  ExactSum eu, et, nu, nt;
  const std::size_t count = s.slab ? s.slab->owned.size() : pc.size();
  for (std::size_t k = 0; k < count; ++k) {
    const auto i = s.slab ? std::size_t(s.slab->owned[k]) : k;
    if (pc.role[i] != Role::interior) continue;
    const auto x = pc.position(i);
    const auto u0 = s.reference.displacement(x);
    const double t0 = s.reference.dilatation(x), V = pc.volume[i];
    for (int c = 0; c < pc.dim; ++c) {
      eu += V * std::pow(r.u[std::size_t(c)][i] - u0[std::size_t(c)], 2);
      nu += V * u0[std::size_t(c)] * u0[std::size_t(c)];
    }
    et += V * std::pow(r.theta[i] - t0, 2);
    nt += V * t0 * t0;
  }
  if (s.slab)
    for (ExactSum* sum : {&eu, &et, &nu, &nt}) {
      parallel::sum_over_ranks(sum->words_for_reduction());
      sum->normalise();
    }
  StaticErrors e{std::sqrt(eu.value()), std::sqrt(et.value()), 0, 0};
  const double nuv = nu.value(), ntv = nt.value();
  e.u_relative = nuv > 0 ? e.u / std::sqrt(nuv) : e.u;
  e.theta_relative = ntv > 0 ? e.theta / std::sqrt(ntv) : e.theta;
  return e;
}

void check_petsc_options(const parallel::KspOptions& o) {
  if (o.options.empty() && parallel::command_line_options().empty()) return;
  try {
    parallel::check_ksp_options(o);
  } catch (const std::invalid_argument& e) {
    throw DeckError(fmt::format("{}: {}", o.options.empty() ? "PETSc options on the command line" : "solver.petsc_options", e.what()));
  }
}

void check_petsc_options(const StaticSetup& s) {
  if (s.options.solver == LinearSolver::petsc) check_petsc_options(s.options.petsc);
}

}  // namespace peridot
