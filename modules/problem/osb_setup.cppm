export module peridot.problem:osb_setup;
import peridot.std;
import peridot.io;
import peridot.quadrature;
import peridot.implicit;
import peridot.deck;
import :setup;

export namespace peridot {

// A static OSB problem on a rectangle (seed 004): real points, the fictitious layer when the
// boundary method is fictitious_taylor, cell-area bonds, the model with its weighted volumes,
// and the edge conditions.
struct OsbStaticSetup {
  Body body;
  Osb model;
  OsbStaticProblem problem;
  OsbStaticOptions options;
  int layers = 0;
  std::optional<OsbParts> parts;  // N ranks: this rank's part (setup_osb_static_part)
  std::size_t global_points = 0;  // real and fictitious, of the whole rectangle
};

OsbStaticSetup setup_osb_static(const Problem& problem);
// Rank `rank`'s part on N ranks: the whole rectangle's sites (real and fictitious) are cut into
// bricks of their grid, and a rank makes only the sites within a few bond reaches of its brick,
// their bonds and weighted volumes; no rank makes the whole body. Solves on PETSc. Collective.
OsbStaticSetup setup_osb_static_part(const Problem& problem, int rank, int ranks);

// The body and model of a static OSB rectangle [lo, hi] of cells of size h: real points, and
// with `corrected` the fictitious layer ceil(delta / h - 1/2) cells deep (the cells overlapping
// the disk of an edge node), cell-area bonds (pre-cracks cut), and weighted volumes, the
// fictitious points carrying the bulk value (Sec. 3.1).
struct OsbBody {
  Body body;
  Osb model;
  int layers = 0;
};
OsbBody osb_rectangle(const Vec3& lo, const Vec3& hi, double h, double delta, double youngs_modulus, double poisson_ratio, Kinematics kinematics,
                      bool corrected, const std::vector<Crack>& cracks = {});

// Nodal errors against the deck's affine reference, in percent: relative (66) per component
// (its smallest and largest value over the real points; a component whose reference is zero
// everywhere reports its largest |u| instead) and (64), |u - u_ref| / max |u_ref|.
struct OsbErrors {
  double rel_u_min = 0, rel_u_max = 0, rel_v_min = 0, rel_v_max = 0;
  double abs_u_max = 0, abs_v_max = 0;
  bool v_zero = false, u_zero = false;
  double max_u = 0, max_v = 0;  // largest |u|, |v| [m]
};

std::array<double, 2> osb_reference(const Problem& problem, const Vec3& x);
// On N ranks (setup.parts) collective: the extremes over every rank's owned real points.
OsbErrors osb_errors(const Problem& problem, const OsbStaticSetup& setup, const OsbStaticResult& result);

}  // namespace peridot

namespace peridot {

namespace {

Vec3 centre_of(const Problem& p) {
  const auto b = p.body.bounds();
  return {0.5 * (b.lo[0] + b.hi[0]), 0.5 * (b.lo[1] + b.hi[1]), 0};
}

}  // namespace

std::array<double, 2> osb_reference(const Problem& p, const Vec3& x) {
  const auto& o = p.statics.osb;
  const auto c = centre_of(p);
  const double dx = x[0] - c[0], dy = x[1] - c[1];
  const auto& g = o.reference_gradient;
  return {o.reference_displacement[0] + g[0] * dx + g[1] * dy, o.reference_displacement[1] + g[2] * dx + g[3] * dy};
}

namespace {

int osb_layers(double delta, double h, bool corrected) { return corrected ? int(std::ceil(delta / h - 0.5 - 1e-9)) : 0; }

// Bonds, pre-crack cuts and weighted volumes of o.body.points. Returns the largest real point's
// m: with the layer every real point's neighbourhood is full, so any uncut real point's m is the
// bulk one, which the fictitious points carry (set_fictitious_m).
double weigh_osb_body(OsbBody& o, double delta, double E, double nu, Kinematics kin, const std::vector<Crack>& cracks) {
  auto& pc = o.body.points;
  o.body.bonds = cell_area_bonds(pc, delta);
  cut_bonds(pc, o.body.bonds, cracks);
  o.body.density = 1.0;
  o.model = Osb::make(E, nu, kin, delta);
  o.model.weigh(o.body);
  double bulk = 0;
  for (std::size_t i = 0; i < pc.size(); ++i)
    if (pc.role[i] == Role::interior) bulk = std::max(bulk, o.model.m[i]);
  return bulk;
}

void set_fictitious_m(OsbBody& o, double bulk) {
  const auto& pc = o.body.points;
  for (std::size_t i = 0; i < pc.size(); ++i)
    if (pc.role[i] == Role::fictitious) o.model.m[i] = bulk;
}

}  // namespace

OsbBody osb_rectangle(const Vec3& lo, const Vec3& hi, double h, double delta, double E, double nu, Kinematics kin, bool corrected,
                      const std::vector<Crack>& cracks) {
  OsbBody o;
  o.layers = osb_layers(delta, h, corrected);
  o.body.points = rectangle_with_layer(lo, hi, h, o.layers);
  set_fictitious_m(o, weigh_osb_body(o, delta, E, nu, kin, cracks));
  return o;
}

namespace {

void require_osb_fits(const Problem& p, int ranks) {
  const double h = p.lattice.spacing;
  const auto b = p.body.bounds();
  if (p.lattice.perturbation > 0) throw DeckError("discretization.perturbation: material.model = 'osb' on a static solve needs the regular grid (0)");
  require_lattice_fits(b, h, 2, 2 * std::ceil(p.horizon / h) * h);
  require_bonds_fit(std::size_t((b.hi[0] - b.lo[0]) / h + 2 * p.horizon / h + 1) * std::size_t((b.hi[1] - b.lo[1]) / h + 2 * p.horizon / h + 1) /
                        std::size_t(ranks),
                    2, p.horizon + h, h, bytes_per_bond_static);
}

void require_rectangle(const Problem& p, const PointCloud& pc) {
  for (std::size_t i = 0; i < pc.size(); ++i)
    if (pc.role[i] == Role::interior && !p.body.contains(pc.position(i)))
      throw DeckError(fmt::format("geometry.body: static OSB needs a rectangle; the point ({:g}, {:g}) m of its bounding box lies outside", pc.x[0][i],
                                  pc.x[1][i]));
}

// Everything of the deck but the body: conditions, body force, solver options.
void osb_conditions(const Problem& p, OsbStaticSetup& s) {
  const auto b = p.body.bounds();
  const auto& o = p.statics.osb;
  s.problem.conditions = o.conditions;
  s.problem.corrected = p.boundary_method == BoundaryMethodKind::fictitious_taylor;
  s.problem.taylor_order = o.taylor_order;
  if (o.body_force == "uniform") {
    const auto v = o.body_force_value;
    s.problem.body_force = [v](const Vec3&) { return std::array<double, 2>{v[0], v[1]}; };
  } else if (o.body_force == "cosine") {
    const auto v = o.body_force_value;
    const auto c = centre_of(p);
    const double Lx = b.hi[0] - b.lo[0], Ly = b.hi[1] - b.lo[1];
    s.problem.body_force = [v, c, Lx, Ly](const Vec3& x) {
      const double f = std::cos(std::numbers::pi * (x[0] - c[0]) / Lx) * std::cos(std::numbers::pi * (x[1] - c[1]) / Ly);
      return std::array<double, 2>{v[0] * f, v[1] * f};
    };
  }
  s.options.solver = p.statics.linear_solver;
  // A deck that names UMFPACK gets it; by default a small system takes the banded LU.
  s.options.banded = p.statics.linear_solver_named ? OsbStaticOptions::Banded::never : OsbStaticOptions::Banded::when_cheaper;
  s.options.petsc.options = p.statics.petsc_options;
  s.options.critical_stretch = osb_critical_stretch(p);
  s.options.bonds_per_solve = o.bonds_per_solve;
  s.options.max_solves = o.max_solves;
}

}  // namespace

OsbStaticSetup setup_osb_static(const Problem& p) {
  OsbStaticSetup s;
  const bool corrected = p.boundary_method == BoundaryMethodKind::fictitious_taylor;
  const double h = p.lattice.spacing;
  const auto b = p.body.bounds();
  require_osb_fits(p, 1);
  OsbBody built;
  try {
    built = osb_rectangle(b.lo, b.hi, h, p.horizon, p.material.youngs_modulus, p.material.poisson_ratio, p.material.kinematics, corrected, p.cracks);
  } catch (const std::invalid_argument& e) {
    throw DeckError(fmt::format("geometry.body: {} (static OSB needs a rectangle of whole cells)", e.what()));
  }
  s.body = std::move(built.body);
  s.model = std::move(built.model);
  s.layers = built.layers;
  s.global_points = s.body.size();
  require_rectangle(p, s.body.points);
  osb_conditions(p, s);
  return s;
}

OsbStaticSetup setup_osb_static_part(const Problem& p, int rank, int ranks) {
  OsbStaticSetup s;
  osb_conditions(p, s);
  s.options.solver = LinearSolver::petsc;
  const bool corrected = s.problem.corrected;
  const double h = p.lattice.spacing, delta = p.horizon;
  const auto b = p.body.bounds();
  const int L = osb_layers(delta, h, corrected);
  s.layers = L;
  OsbParts parts;
  parts.rank = rank, parts.ranks = ranks;
  OsbBody built;
  double bulk = 0;
  parallel::together("set-up", [&] {
    require_osb_fits(p, ranks);
    std::array<std::int64_t, 2> n{};
    try {
      n = rectangle_cells(b.lo, b.hi, h);
    } catch (const std::invalid_argument& e) {
      throw DeckError(fmt::format("geometry.body: {} (static OSB needs a rectangle of whole cells)", e.what()));
    }
    const auto [nx, ny] = n;
    const std::int64_t m0 = nx + 2 * L, m1 = ny + 2 * L;
    s.global_points = std::size_t(m0 * m1);
    BoxLattice grown;
    grown.dim = 2;
    grown.h = h;
    grown.bounds = {{b.lo[0] - L * h, b.lo[1] - L * h, 0}, {b.hi[0] + L * h, b.hi[1] + L * h, 0}};
    grown.m = {m0, m1, 1};
    BrickCut cut;
    try {
      cut = brick_cut(grown, ranks);
    } catch (const std::invalid_argument& e) {
      throw DeckError(fmt::format("geometry.body: {} (discretization.spacing = {:g} m, mpirun -np {})", e.what(), h, ranks));
    }
    // Sites held: an owned row reads its partners' Taylor stencils (order + 1 cells), and a
    // condition row whose entries reach an owned node reads the bonds across its side and their
    // ends' stencils; every row those read must be whole, a bond reach further.
    const std::int64_t reach = std::int64_t(std::ceil(delta / h)) + 1, stencil = (corrected ? s.problem.taylor_order : 0) + 1;
    const auto held = cut.brick(rank, 3 * reach + 2 * stencil + 2);
    std::vector<std::int64_t> sites;
    built.layers = L;
    built.body.points = rectangle_with_layer_part(b.lo, b.hi, h, L, {held[0], held[1], held[2], held[3]}, &parts.global_id, &sites);
    require_rectangle(p, built.body.points);
    // Each rank's real points are numbered row by row within its brick, then its sides' rows.
    const auto real_box = [&](int r) {
      const auto& c = cut.box[std::size_t(r)];
      return std::array<std::int64_t, 4>{std::max<std::int64_t>(c[0], L), std::min<std::int64_t>(c[1], L + nx), std::max<std::int64_t>(c[2], L),
                                         std::min<std::int64_t>(c[3], L + ny)};
    };
    parts.reals.assign(std::size_t(ranks), 0);
    for (int r = 0; r < ranks; ++r) {
      const auto q = real_box(r);
      parts.reals[std::size_t(r)] = std::max<std::int64_t>(q[1] - q[0], 0) * std::max<std::int64_t>(q[3] - q[2], 0);
    }
    // The whole rectangle's sides in OsbStaticResult's order (left, right, bottom, top), by the site of their real node.
    std::vector<std::array<std::int64_t, 2>> side_site;
    for (std::int64_t y = L; y < L + ny; ++y) side_site.push_back({L, y});
    for (std::int64_t y = L; y < L + ny; ++y) side_site.push_back({L + nx - 1, y});
    for (std::int64_t x = L; x < L + nx; ++x) side_site.push_back({x, L});
    for (std::int64_t x = L; x < L + nx; ++x) side_site.push_back({x, L + ny - 1});
    std::vector<std::int64_t> sides_of(std::size_t(ranks), 0);
    for (const auto& [x, y] : side_site) {
      const int o = cut.owner(x, y, 0);
      parts.side_owner.push_back(o);
      parts.side_row.push_back(2 * sides_of[std::size_t(o)]++);  // within the owner's condition rows, for now
    }
    parts.first.assign(std::size_t(ranks) + 1, 0);
    for (int r = 0; r < ranks; ++r)
      parts.first[std::size_t(r) + 1] = parts.first[std::size_t(r)] + 3 * parts.reals[std::size_t(r)] + (corrected ? 2 * sides_of[std::size_t(r)] : 0);
    for (std::size_t k = 0; k < side_site.size(); ++k) {
      const auto o = std::size_t(parts.side_owner[k]);
      parts.side_row[k] += parts.first[o] + 3 * parts.reals[o];
    }
    const auto& pc = built.body.points;
    parts.owner.resize(pc.size());
    parts.index.assign(pc.size(), -1);
    for (std::size_t i = 0; i < pc.size(); ++i) {
      const std::int64_t x = sites[i] % m0, y = sites[i] / m0;
      const int o = cut.owner(x, y, 0);
      parts.owner[i] = o;
      if (o != rank) parts.ghost.push_back(std::int64_t(i)), parts.ghost_owner.push_back(o);
      if (pc.role[i] != Role::interior) continue;
      const auto q = real_box(o);
      parts.index[i] = (y - q[2]) * (q[1] - q[0]) + (x - q[0]);
    }
    // The whole rectangle of real points in lattice_grid's coordinates of the local points
    // (point 0 is grid (0, 0)).
    parts.box = {int(L - sites[0] % m0), int(L - sites[0] / m0), int(nx), int(ny)};
    bulk = weigh_osb_body(built, delta, p.material.youngs_modulus, p.material.poisson_ratio, p.material.kinematics, p.cracks);
  }, is_input_error);
  set_fictitious_m(built, -parallel::min_over_ranks(-bulk));
  std::vector<std::int64_t> ghost_ids;
  for (auto g : parts.ghost) ghost_ids.push_back(parts.global_id[std::size_t(g)]);
  parts.ghost_owner_index = parallel::index_on_owners(ghost_ids, parts.ghost_owner, parts.global_id);
  s.body = std::move(built.body);
  s.model = std::move(built.model);
  s.parts = std::move(parts);
  return s;
}

OsbErrors osb_errors(const Problem& p, const OsbStaticSetup& s, const OsbStaticResult& r) {
  OsbErrors e;
  const auto& pc = s.body.points;
  // On N ranks each rank's owned real points, and the extremes over the ranks.
  const auto largest = [&](auto&&... v) {
    if (!s.parts) return;
    std::array<double, sizeof...(v)> m{*v...};
    parallel::max_over_ranks(m);
    std::size_t k = 0;
    ((*v = m[k++]), ...);
  };
  std::vector<std::size_t> real;
  for (std::size_t i = 0; i < pc.size(); ++i)
    if (pc.role[i] == Role::interior && (!s.parts || s.parts->owns(i))) real.push_back(i);
  double ref_max = 0, u_nonzero = 0, v_nonzero = 0;
  for (auto i : real) {
    const auto u0 = osb_reference(p, pc.position(i));
    ref_max = std::max({ref_max, std::abs(u0[0]), std::abs(u0[1])});
    if (u0[0] != 0) u_nonzero = 1;
    if (u0[1] != 0) v_nonzero = 1;
    e.max_u = std::max(e.max_u, std::abs(r.u[0][i]));
    e.max_v = std::max(e.max_v, std::abs(r.u[1][i]));
  }
  largest(&ref_max, &u_nonzero, &v_nonzero, &e.max_u, &e.max_v);
  e.u_zero = u_nonzero == 0, e.v_zero = v_nonzero == 0;
  double low_u = -1e300, low_v = -1e300;  // minus the smallest relative errors
  for (auto i : real) {
    const auto u0 = osb_reference(p, pc.position(i));
    const double du = std::abs(r.u[0][i] - u0[0]), dv = std::abs(r.u[1][i] - u0[1]);
    if (!e.u_zero && u0[0] != 0) low_u = std::max(low_u, -100 * du / std::abs(u0[0])), e.rel_u_max = std::max(e.rel_u_max, 100 * du / std::abs(u0[0]));
    if (!e.v_zero && u0[1] != 0) low_v = std::max(low_v, -100 * dv / std::abs(u0[1])), e.rel_v_max = std::max(e.rel_v_max, 100 * dv / std::abs(u0[1]));
    if (ref_max > 0) e.abs_u_max = std::max(e.abs_u_max, 100 * du / ref_max), e.abs_v_max = std::max(e.abs_v_max, 100 * dv / ref_max);
  }
  largest(&low_u, &low_v, &e.rel_u_max, &e.rel_v_max, &e.abs_u_max, &e.abs_v_max);
  e.rel_u_min = -low_u, e.rel_v_min = -low_v;
  if (e.rel_u_min > e.rel_u_max) e.rel_u_min = e.rel_u_max = 0;
  if (e.rel_v_min > e.rel_v_max) e.rel_v_min = e.rel_v_max = 0;
  return e;
}

}  // namespace peridot
