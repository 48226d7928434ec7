export module peridot.problem:lps_dynamics_setup;
import peridot.std;
import peridot.io;
import peridot.quadrature;
import peridot.implicit;
import peridot.deck;
import :setup;

export namespace peridot {

// The body and the LPS model of a dynamic fracture run (seed 000 Sec. 6). The cloud covers the
// body and a delta-wide exterior band; weights are built over full balls in the reference
// configuration; then the exterior points are dropped, each real point keeping the moments of
// its exterior bonds (all free or loaded Neumann surface), so observers see only the body.
struct LpsDynamicBody {
  Body body;
  Lps model;
  QuadratureReport quadrature;
  std::size_t exterior_points = 0;
};

LpsDynamicBody lps_dynamic_body(const Problem& problem);

// The pieces of lps_dynamic_body, for a rank that builds its own neighbourhood only:
//   - lps_cloud: the body's lattice with its delta-wide exterior band (Role::ghost points) and
//     the exterior's shape; checks that the lattice fits and that every nonlocal traction's
//     region holds exterior points.
//   - lps_body_of: the body of the interior points of `cloud` (lps_cloud's points or a subset
//     of them, ascending), from their bonds within it. GMLS (or the deck's) weights for the
//     points marked `complete` (whose whole neighbourhood `cloud` holds; empty: every point),
//     volume weights elsewhere. No no-fail flags: regions are selected on the whole body.
struct LpsCloud {
  PointCloud points;
  Shape exterior;
};
LpsCloud lps_cloud(const Problem& problem);
// lps_cloud's exterior shape: everything outside the body, within delta + 3h of its box.
Shape lps_exterior(const Problem& problem);
// Per nonlocal traction (the deck's order), the exterior points of `cloud` it loads (the first
// region holding a point takes it); the check that none is 0, which a rank that holds part of
// the cloud makes on the counts summed over the ranks.
std::vector<std::int64_t> traction_points(const Problem& problem, const PointCloud& cloud);
void require_traction_points(const Problem& problem, std::span<const std::int64_t> counts);
LpsDynamicBody lps_body_of(const Problem& problem, const PointCloud& cloud, const Shape& exterior, std::span<const std::uint8_t> complete);
// The body's points of an LPS deck (the interior points of lps_cloud, in its order).
PointCloud lps_body_points(const Problem& problem);
// Refuses a Newmark deck's prescribed-motion boundaries.
void check_newmark_boundaries(const Problem& problem);

// An implicit Newmark run: body, model, body-force boundaries and the solver's options.
struct NewmarkSetup {
  Body body;
  Lps model;
  std::vector<Boundary> boundaries;
  NewmarkOptions options;
  QuadratureReport quadrature;
};

NewmarkSetup setup_newmark(const Problem& problem);
// An explicit (velocity Verlet) run of the same body and model.
Setup setup_lps_explicit(const Problem& problem);

}  // namespace peridot

namespace peridot {

namespace {

// The traction loads of the deck, and per point of `pc` the first one whose region holds it
// (exterior points only; -1 for none).
std::vector<BoundarySpec const*> traction_specs(const Problem& p) {
  std::vector<BoundarySpec const*> tractions;
  for (const auto& bc : p.boundaries)
    if (bc.nonlocal_traction) tractions.push_back(&bc);
  return tractions;
}

std::vector<std::int32_t> traction_regions(const PointCloud& pc, const std::vector<BoundarySpec const*>& tractions) {
  std::vector<std::int32_t> load_of(pc.size(), -1);
  for (std::size_t j = 0; j < pc.size(); ++j)
    if (pc.role[j] == Role::ghost)
      for (std::size_t k = 0; k < tractions.size() && load_of[j] < 0; ++k)
        if (tractions[k]->region.contains(pc.position(j))) load_of[j] = std::int32_t(k);
  return load_of;
}

}  // namespace

LpsCloud lps_cloud(const Problem& p) {
  if (p.material.model != ModelKind::lps) throw std::invalid_argument("lps_cloud: the deck's model is not lps");
  const double h = p.lattice.spacing, delta = p.horizon;
  const int dim = p.dim;
  const Aabb b = p.body.bounds();
  LpsCloud c;
  c.exterior = lps_exterior(p);
  try {
    require_lattice_fits(b, h, dim, delta);
    c.points = lattice_with_exterior(p.body, p.lattice, {.band = delta, .neumann = c.exterior});
  } catch (const std::invalid_argument& e) {
    throw DeckError(fmt::format("geometry.body: {} (discretization.spacing = {:g} m)", e.what(), h));
  }
  if (std::none_of(c.points.role.begin(), c.points.role.end(), [](Role r) { return r == Role::interior; }))
    throw DeckError(fmt::format("geometry.body: contains no lattice points at spacing {:g} m", h));
  require_traction_points(p, traction_points(p, c.points));
  return c;
}

std::vector<std::int64_t> traction_points(const Problem& p, const PointCloud& cloud) {
  const auto tractions = traction_specs(p);
  std::vector<std::int64_t> count(tractions.size(), 0);
  for (const auto k : traction_regions(cloud, tractions))
    if (k >= 0) ++count[std::size_t(k)];
  return count;
}

void require_traction_points(const Problem& p, std::span<const std::int64_t> counts) {
  const auto tractions = traction_specs(p);
  for (std::size_t k = 0; k < tractions.size(); ++k)
    if (counts[k] == 0)
      throw DeckError(fmt::format("boundaries ('{}'): a nonlocal traction acts on exterior points, and its region holds none "
                                  "(the exterior band is delta = {:g} m wide around geometry.body)",
                                  tractions[k]->name, p.horizon));
}

Shape lps_exterior(const Problem& p) {
  // Everything outside the body is free or loaded surface: one exterior shape around it.
  const Aabb b = p.body.bounds();
  const double grow = p.horizon + 3 * p.lattice.spacing;
  return p.dim == 3 ? subtract(box({b.lo[0] - grow, b.lo[1] - grow, b.lo[2] - grow}, {b.hi[0] + grow, b.hi[1] + grow, b.hi[2] + grow}), p.body)
                    : subtract(rectangle({b.lo[0] - grow, b.lo[1] - grow, 0}, {b.hi[0] + grow, b.hi[1] + grow, 0}), p.body);
}

PointCloud lps_body_points(const Problem& p) {
  const LpsCloud c = lps_cloud(p);
  std::vector<std::int64_t> interior;
  for (std::size_t i = 0; i < c.points.size(); ++i)
    if (c.points.role[i] == Role::interior) interior.push_back(std::int64_t(i));
  return subset(c.points, interior);
}

LpsDynamicBody lps_body_of(const Problem& p, const PointCloud& pc, const Shape& exterior, std::span<const std::uint8_t> complete) {
  LpsDynamicBody out;
  const double h = p.lattice.spacing, delta = p.horizon;
  const ElasticConstants c = lame(p.material.youngs_modulus, p.material.poisson_ratio, p.material.kinematics);
  const int dim = p.dim;
  require_bonds_fit(pc.size(), dim, delta, h, bytes_per_bond_lps_dynamic);
  BondList bonds = build_bonds(pc, {.horizon = delta});
  std::vector<std::uint8_t> active(pc.size(), 0);
  for (std::size_t i = 0; i < pc.size(); ++i) active[i] = pc.role[i] == Role::interior && (complete.empty() || complete[i]);
  QuadratureOptions qo;
  qo.rule = p.material.quadrature;
  qo.active = active;
  try {
    out.quadrature = compute_weights(pc, bonds, qo);
  } catch (const std::runtime_error& e) {
    throw DeckError(fmt::format("discretization: quadrature weights failed: {}", e.what()));
  }
  // Fracture changes masks, never weights: ghosts, chords across notches and holes, and
  // pre-cracks start as w^ bonds.
  break_neumann_bonds(pc, bonds, exterior);
  cut_bonds(pc, bonds, p.cracks);

  // Which traction loads each exterior point (the first region holding it).
  const auto tractions = traction_specs(p);
  const auto load_of = traction_regions(pc, tractions);

  // Compact to the real points; keep each one's exterior moments. In place: a row only ever
  // moves down, so the cloud's list becomes the body's and the set-up never holds two lists.
  std::vector<std::int32_t> index(pc.size(), -1);
  PointCloud real;
  real.dim = dim;
  real.spacing = pc.spacing;
  for (std::size_t i = 0; i < pc.size(); ++i)
    if (pc.role[i] == Role::interior) {
      index[i] = std::int32_t(real.size());
      real.push_back(pc.position(i), pc.volume[i], Role::interior);
    }
  const std::size_t n = real.size();
  out.exterior_points = pc.size() - n;
  Lps model = Lps::make(dim, delta, std::vector<double>(n, c.lambda), std::vector<double>(n, c.mu));
  model.single_precision = p.solver_kind == SolverKind::explicit_dynamics && p.list_precision == ListPrecision::single;
  if (model.single_precision) {
    require_single_precision_reach(p, real);
    if (!model.single_precision_fits())
      throw DeckError(fmt::format("discretization.list_precision = 'single': LPS's pair constants {:g} and {:g} are no normal floats for "
                                  "horizon {:g} m; set list_precision: double",
                                  model.theta_coefficient(0, 0, 1.0), model.shear_coefficient(0, 0, 1.0, 1.0), delta));
  }
  model.exterior.assign(n, {});
  model.loaded.assign(n, {});
  model.traction_of.assign(n, -1);
  std::vector<std::int64_t> offset(n + 1, 0);
  std::int64_t to = 0;
  for (std::size_t i = 0; i < pc.size(); ++i) {
    if (index[i] < 0) continue;
    const auto r = std::size_t(index[i]);
    // The traction of the nearest loaded exterior partner.
    double nearest = std::numeric_limits<double>::infinity();
    for (auto q = bonds.offset[i]; q < bonds.offset[i + 1]; ++q) {
      const auto j = std::size_t(bonds.neighbor[q]);
      if (pc.role[j] == Role::ghost && load_of[j] >= 0 && bonds.length[q] < nearest) {
        nearest = bonds.length[q];
        model.traction_of[r] = load_of[j];
      }
    }
    for (auto q = bonds.offset[i]; q < bonds.offset[i + 1]; ++q) {
      const auto j = std::size_t(bonds.neighbor[q]);
      const auto from = std::size_t(q);
      const double L = bonds.length[from];
      if (index[j] >= 0) {
        const auto at = std::size_t(to++);
        bonds.neighbor[at] = index[j];
        for (int k = 0; k < 3; ++k) bonds.xi[k][at] = bonds.xi[k][from];
        bonds.length[at] = L;
        bonds.weight[at] = bonds.weight[from];
        bonds.intact[at] = bonds.intact[from];
        continue;
      }
      const double Kw = model.kernel(L) * bonds.weight[from];
      const std::array<double, 3> xi{bonds.xi[0][from], bonds.xi[1][from], bonds.xi[2][from]};
      model.exterior[r].add(Kw, bonds.weight[from], xi, L * L);
      if (model.traction_of[r] >= 0 && load_of[j] == model.traction_of[r]) model.loaded[r].add(Kw, bonds.weight[from], xi, L * L);
    }
    offset[r + 1] = to;
  }
  const auto m = std::size_t(to);
  bonds.offset.resize(n + 1);
  std::copy(offset.begin(), offset.end(), bonds.offset.begin());
  bonds.neighbor.resize(m);
  for (auto& x : bonds.xi) x.resize(m);
  bonds.length.resize(m);
  bonds.weight.resize(m);
  bonds.intact.resize(m);
  bonds.release_spare();
  bonds.horizon = delta;
  for (const auto* t : tractions) {
    Lps::Traction tr;
    tr.T = {t->value[0], t->value[1], t->value[2]};
    tr.normal = t->normal;
    tr.history = t->history;
    model.tractions.push_back(std::move(tr));
  }
  if (p.material.fracture_energy > 0) model.s0 = Lps::critical_stretch(p.material.fracture_energy, delta, c, dim);

  out.body.points = std::move(real);
  out.body.bonds = std::move(bonds);
  out.body.density = p.material.density;
  out.model = std::move(model);
  return out;
}

LpsDynamicBody lps_dynamic_body(const Problem& p) {
  const LpsCloud cloud = lps_cloud(p);
  LpsDynamicBody out = lps_body_of(p, cloud.points, cloud.exterior, {});
  out.body.no_fail.assign(out.body.size(), 0);
  for (const auto& region : p.no_fail)
    for (auto i : select_points(out.body.points, region)) out.body.no_fail[i] = 1;
  out.model.prepare(out.body);
  return out;
}

void check_newmark_boundaries(const Problem& p) {
  for (std::size_t k = 0; k < p.boundaries.size(); ++k)
    if (p.boundaries[k].kind != BoundaryKind::body_force)
      throw DeckError(fmt::format("boundaries[{}] ('{}'): solver.type = 'newmark' takes tractions and body forces, not prescribed motion",
                                  k, p.boundaries[k].name));
}

NewmarkSetup setup_newmark(const Problem& p) {
  auto d = lps_dynamic_body(p);
  NewmarkSetup s{std::move(d.body), std::move(d.model), {}, p.newmark, d.quadrature};
  s.boundaries = build_boundaries(p, s.body);
  check_newmark_boundaries(p);
  return s;
}

Setup setup_lps_explicit(const Problem& p) {
  auto d = lps_dynamic_body(p);
  Setup s{};
  s.body = std::move(d.body);
  if (p.bond_layout == BondLayout::compact) s.body.bonds.drop_geometry();
  if (d.model.single_precision) s.body.bonds.add_float_weights();
  s.boundaries = build_boundaries(p, s.body);
  const double estimate = d.model.stable_time_step(s.body);
  s.model = std::move(d.model);
  try {
    s.time_step = choose_time_step(estimate, p.solver);
  } catch (const std::invalid_argument& e) {
    throw DeckError(e.what());
  }
  return s;
}

}  // namespace peridot
