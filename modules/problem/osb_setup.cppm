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
};

OsbStaticSetup setup_osb_static(const Problem& problem);

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

OsbBody osb_rectangle(const Vec3& lo, const Vec3& hi, double h, double delta, double E, double nu, Kinematics kin, bool corrected,
                      const std::vector<Crack>& cracks) {
  OsbBody o;
  o.layers = corrected ? int(std::ceil(delta / h - 0.5 - 1e-9)) : 0;
  o.body.points = rectangle_with_layer(lo, hi, h, o.layers);
  auto& pc = o.body.points;
  o.body.bonds = cell_area_bonds(pc, delta);
  cut_bonds(pc, o.body.bonds, cracks);
  o.body.density = 1.0;
  o.model = Osb::make(E, nu, kin, delta);
  o.model.weigh(o.body);
  // With the layer every real point's neighbourhood is full, so any real point's m is the bulk one.
  double bulk = 0;
  for (std::size_t i = 0; i < pc.size(); ++i)
    if (pc.role[i] == Role::interior) bulk = std::max(bulk, o.model.m[i]);
  for (std::size_t i = 0; i < pc.size(); ++i)
    if (pc.role[i] == Role::fictitious) o.model.m[i] = bulk;
  return o;
}

OsbStaticSetup setup_osb_static(const Problem& p) {
  OsbStaticSetup s;
  const bool corrected = p.boundary_method == BoundaryMethodKind::fictitious_taylor;
  const double h = p.lattice.spacing;
  const auto b = p.body.bounds();
  if (p.lattice.perturbation > 0) throw DeckError("discretization.perturbation: material.model = 'osb' on a static solve needs the regular grid (0)");
  require_lattice_fits(b, h, 2, 2 * std::ceil(p.horizon / h) * h);
  require_bonds_fit(std::size_t((b.hi[0] - b.lo[0]) / h + 2 * p.horizon / h + 1) * std::size_t((b.hi[1] - b.lo[1]) / h + 2 * p.horizon / h + 1), 2,
                    p.horizon + h, h, bytes_per_bond_static);
  OsbBody built;
  try {
    built = osb_rectangle(b.lo, b.hi, h, p.horizon, p.material.youngs_modulus, p.material.poisson_ratio, p.material.kinematics, corrected, p.cracks);
  } catch (const std::invalid_argument& e) {
    throw DeckError(fmt::format("geometry.body: {} (static OSB needs a rectangle of whole cells)", e.what()));
  }
  s.body = std::move(built.body);
  s.model = std::move(built.model);
  s.layers = built.layers;
  const auto& pc = s.body.points;
  for (std::size_t i = 0; i < pc.size(); ++i)
    if (pc.role[i] == Role::interior && !p.body.contains(pc.position(i)))
      throw DeckError(fmt::format("geometry.body: static OSB needs a rectangle; the point ({:g}, {:g}) m of its bounding box lies outside", pc.x[0][i],
                                  pc.x[1][i]));

  const auto& o = p.statics.osb;
  s.problem.conditions = o.conditions;
  s.problem.corrected = corrected;
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
  s.options.petsc.options = p.statics.petsc_options;
  s.options.critical_stretch = osb_critical_stretch(p);
  s.options.bonds_per_solve = o.bonds_per_solve;
  s.options.max_solves = o.max_solves;
  return s;
}

OsbErrors osb_errors(const Problem& p, const OsbStaticSetup& s, const OsbStaticResult& r) {
  OsbErrors e;
  const auto& pc = s.body.points;
  double ref_max = 0;
  std::vector<std::size_t> real;
  for (std::size_t i = 0; i < pc.size(); ++i)
    if (pc.role[i] == Role::interior) real.push_back(i);
  for (auto i : real) {
    const auto u0 = osb_reference(p, pc.position(i));
    ref_max = std::max({ref_max, std::abs(u0[0]), std::abs(u0[1])});
    e.u_zero = e.u_zero || u0[0] != 0;
    e.v_zero = e.v_zero || u0[1] != 0;
    e.max_u = std::max(e.max_u, std::abs(r.u[0][i]));
    e.max_v = std::max(e.max_v, std::abs(r.u[1][i]));
  }
  e.u_zero = !e.u_zero, e.v_zero = !e.v_zero;
  e.rel_u_min = e.rel_v_min = 1e300;
  for (auto i : real) {
    const auto u0 = osb_reference(p, pc.position(i));
    const double du = std::abs(r.u[0][i] - u0[0]), dv = std::abs(r.u[1][i] - u0[1]);
    if (!e.u_zero && u0[0] != 0) e.rel_u_min = std::min(e.rel_u_min, 100 * du / std::abs(u0[0])), e.rel_u_max = std::max(e.rel_u_max, 100 * du / std::abs(u0[0]));
    if (!e.v_zero && u0[1] != 0) e.rel_v_min = std::min(e.rel_v_min, 100 * dv / std::abs(u0[1])), e.rel_v_max = std::max(e.rel_v_max, 100 * dv / std::abs(u0[1]));
    if (ref_max > 0) e.abs_u_max = std::max(e.abs_u_max, 100 * du / ref_max), e.abs_v_max = std::max(e.abs_v_max, 100 * dv / ref_max);
  }
  if (e.rel_u_min > e.rel_u_max) e.rel_u_min = e.rel_u_max = 0;
  if (e.rel_v_min > e.rel_v_max) e.rel_v_min = e.rel_v_max = 0;
  return e;
}

}  // namespace peridot
