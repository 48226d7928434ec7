export module peridot.problem:setup;
import peridot.std;
import peridot.io;
import peridot.quadrature;
import peridot.implicit;
import peridot.deck;

export namespace peridot {

// Every force model a deck can name; the app visits it once and runs a solver
// instantiated on the concrete type.
using AnyModel = std::variant<Pmb, Rnp, Osb, Lps>;

struct Setup {
  Body body;
  AnyModel model;
  std::vector<Boundary> boundaries;
  TimeStep time_step;
  Slab slab;  // which points this rank owns: all of them on one rank
};

// Builds the body (lattice, bonds, pre-cracks, no-fail flags), the model, the boundary
// point sets and the time step. Throws DeckError for problems only visible at this stage
// (an empty geometry or a boundary region that selects no point).
Setup setup(const Problem& problem);

// A quasi-static problem: body, the tangent model, loads and clamps, and Newton's options.
struct QuasiStaticSetup {
  Body body;
  Rnp model;
  std::vector<Boundary> boundaries;
  QuasiStaticSpec solver;
};

QuasiStaticSetup setup_quasi_static(const Problem& problem);

// The pieces both share: the body (lattice, bonds, pre-cracks, no-fail flags), the force
// model the deck names, and the boundary point sets.
Body build_body(const Problem& problem);
AnyModel make_model(const Problem& problem);
// OSB's critical stretch s_c = sqrt(4 G0 / (9 E delta)) (seed 004 eq. 71); 0 without fracture.
double osb_critical_stretch(const Problem& problem);
std::vector<Boundary> build_boundaries(const Problem& problem, const Body& body);
// Whether the deck's bonds are a lattice stencil (else a CSR list): what a restart needs to
// know of a checkpoint's bond layout before the body exists.
bool uses_stencil(const Problem& p);

}  // namespace peridot

namespace peridot {

// A deck whose cloud (the body's lattice with an exterior band `band` wide: the lattice of the
// grown box, exterior_hull) can be cut from grids alone.
//   - A box body: each cloud site's role follows from its index: a site of the body's grid is an
//     interior point, any other an exterior one. With a perturbation that holds where no
//     perturbed site can cross a face of the body, which the gaps between the faces and the
//     sites next to them decide.
//   - Otherwise, with any_shape: the body's grid is the cloud's own (band 0), keeping the sites
//     whose perturbed points lie in the body (classify_exterior's test; every rank streams the
//     cloud's points once to find them, keeping runs of sites, not points). Its ids are body ids;
//     points are made from the cloud's grid.
//   - Otherwise nullopt, and the cloud is generated whole.
// Boxes of sites are [lo, hi) per axis, in the cloud's grid.
struct CloudGrids {
  BoxLattice body, cloud;
  std::int64_t band = 0;  // layers of the band
  // The body id of a cloud site, or -1 for an exterior one.
  std::int64_t body_id(std::int64_t site) const;
  // A box of the body's grid (a brick of brick_cut) in the cloud's grid.
  std::array<std::int64_t, 6> cloud_box(std::array<std::int64_t, 6> body_box) const;
  // The cloud's sites within `grow` layers of a box, clipped to the cloud, ascending.
  std::vector<std::int64_t> sites_near(const std::array<std::int64_t, 6>& box, std::int64_t grow) const;
  // What a rank makes of the cloud around its box of sites: the sites within three bond reaches
  // (`reach`: the farthest partner), their points with their roles (classify_exterior), and
  // which lie within two, whose balls are whole there. Throws std::logic_error where a point's
  // role does not follow from its site's index.
  struct Neighbourhood {
    std::vector<std::int64_t> sites;
    PointCloud points;
    std::vector<std::uint8_t> complete;
  };
  Neighbourhood neighbourhood(const std::array<std::int64_t, 6>& box, double reach, const Shape& omega, const ExteriorOptions& exterior) const;
};
std::optional<CloudGrids> cloud_grids(const Problem& p, double band, bool any_shape = false);

// some_points: `points` are part of the body (a rank's), so a region may select none of them;
// require_selected then checks the whole body's counts.
std::vector<Boundary> boundaries_on(const Problem& p, const PointCloud& points, bool some_points = false);
// Throws DeckError naming the first boundary of boundaries_on's list (its order) whose count is 0.
void require_selected(const Problem& p, std::span<const std::int64_t> counts);
PointCloud lattice_of(const Problem& p);
// The bond list of a lattice deck's points (any subset of its lattice: a rank's neighbourhood),
// with the deck's quadrature, pre-cracks and list layout; checks that it fits in memory.
BondList lattice_bonds(const Problem& p, const PointCloud& points);
// The same for a mesh deck's nodes (with their elements): element-ball bonds and V_ij, pre-crack
// cuts; lean for PMB, compact for `bonds: compact`. grid: the whole mesh's box, where `nodes` is
// part of it (ElementWeightOptions::grid).
BondList mesh_bonds(const Problem& p, const PointCloud& nodes, std::optional<Aabb> grid = {});
TimeStep time_step_of(const Problem& p, double estimate);
// The owner of every point of `whole` under the coordinate bisection on `ranks` ranks; fewer
// points than ranks is the deck's error.
std::vector<int> owners_of(const PointCloud& whole, int ranks);
// A rank's neighbourhood in a cloud `pc` cut by the owners of `whole` (pc itself, or its body
// points): the ids (ascending) of pc's points within three bond reaches of the box of the rank's
// owned points, and which of them lie within two, where each ball is whole.
struct NearPart {
  std::vector<std::int64_t> ids;
  std::vector<std::uint8_t> complete;
  Aabb box;
};
NearPart near_part(const Problem& p, const PointCloud& pc, const PointCloud& whole, const std::vector<int>& owner, int rank);

}  // namespace peridot

namespace peridot {

// PMB explicit runs on an unperturbed lattice need no neighbour list (Stencil), unless an
// observer needs per-bond pair forces.
bool uses_stencil(const Problem& p) {
  if (p.bond_layout != BondLayout::automatic) return p.bond_layout == BondLayout::stencil;
  return p.discretization_kind == DiscretizationKind::lattice && p.material.model == ModelKind::pmb &&
         p.solver_kind == SolverKind::explicit_dynamics && p.lattice.perturbation == 0 &&
         (p.quadrature_kind == QuadratureKind::volume || p.quadrature_kind == QuadratureKind::partial_volume) && !p.output.wants_stress();
}

namespace {

// Seam 1 and 2 on a mesh: the nodes are the points; bonds and V_ij weights come together from
// element-ball overlap. RNP's kernel J lives in V_ij, so the model then runs with J = 1.
Body mesh_body(const Problem& p) {
  Body body;
  body.points = p.mesh.points();
  body.bonds = mesh_bonds(p, body.points);
  return body;
}

// Points inside any no_fail region keep their bonds whatever the stretch.
void mark_no_fail(Body& body, const Problem& p) {
  body.no_fail.assign(body.size(), 0);
  for (const auto& region : p.no_fail)
    for (auto i : select_points(body.points, region)) body.no_fail[i] = 1;
}

}  // namespace

// The deck's boundary point sets on `points` (ids into it).
namespace {

// The deck's boundaries that act on point sets (a nonlocal traction is none: the model's
// traction operator carries it), as indices into p.boundaries.
std::vector<std::size_t> point_boundaries(const Problem& p) {
  std::vector<std::size_t> out;
  for (std::size_t k = 0; k < p.boundaries.size(); ++k)
    if (!p.boundaries[k].nonlocal_traction) out.push_back(k);
  return out;
}

}  // namespace

std::vector<Boundary> boundaries_on(const Problem& p, const PointCloud& points, bool some_points) {
  const auto made = [&](std::size_t k) {
    const auto& spec = p.boundaries[k];
    return Boundary{spec.name, spec.kind, spec.group.empty() ? select_points(points, spec.region) : p.mesh.groups().at(spec.group),
                    spec.value, spec.components, spec.history};
  };
  std::vector<Boundary> out;
  for (auto&& bc : point_boundaries(p) | std::views::transform(made)) out.push_back(std::move(bc));
  if (!some_points) {
    std::vector<std::int64_t> counts;
    for (const auto& bc : out) counts.push_back(std::int64_t(bc.points.size()));
    require_selected(p, counts);
  }
  return out;
}

void require_selected(const Problem& p, std::span<const std::int64_t> counts) {
  const auto on = point_boundaries(p);
  for (std::size_t q = 0; q < counts.size() && q < on.size(); ++q)
    if (counts[q] == 0)
      throw DeckError(fmt::format("boundaries[{}] ('{}'): region selects no point of the body", on[q], p.boundaries[on[q]].name));
}

PointCloud lattice_of(const Problem& p) {
  require_lattice_fits(p.body.bounds(), p.lattice.spacing, p.dim, 0.0);
  try {
    return lattice(p.body, p.lattice);
  } catch (const std::invalid_argument& e) {
    throw DeckError(fmt::format("geometry.body: {} (discretization.spacing = {:g} m)", e.what(), p.lattice.spacing));
  }
}

std::vector<int> owners_of(const PointCloud& whole, int ranks) {
  try {
    return rcb_owners(whole, ranks);
  } catch (const std::invalid_argument& e) {
    throw DeckError(fmt::format("discretization: {} (mpirun -np {})", e.what(), ranks));
  }
}

NearPart near_part(const Problem& p, const PointCloud& pc, const PointCloud& whole, const std::vector<int>& owner, int rank) {
  NearPart n;
  n.box = part_box(whole, owner, rank);
  const double reach = p.horizon + p.lattice.spacing;  // the farthest partner, with a margin
  n.ids = points_in_box(pc, n.box, 3 * reach);
  n.complete.resize(n.ids.size());
  for (std::size_t j = 0; j < n.ids.size(); ++j) n.complete[j] = in_box(n.box, 2 * reach, pc.position(std::size_t(n.ids[j])));
  return n;
}

TimeStep time_step_of(const Problem& p, double estimate) {
  try {
    return choose_time_step(estimate, p.solver);
  } catch (const std::invalid_argument& e) {
    throw DeckError(e.what());
  }
}

Body build_body(const Problem& p) {
  if (p.discretization_kind == DiscretizationKind::mesh) {
    Body body = mesh_body(p);
    body.density = p.material.density;
    mark_no_fail(body, p);
    return body;
  }
  Body body;
  body.points = lattice_of(p);
  body.density = p.material.density;
  if (uses_stencil(p)) {
    require_bonds_fit(body.size(), p.dim, p.horizon, p.lattice.spacing, bytes_per_bond_stencil);
    std::string why;
    auto stencil = build_stencil(body.points, {.horizon = p.horizon, .partial_volume = p.partial_volume, .cracks = p.cracks}, p.precrack_damage, why);
    if (stencil) {
      body.stencil = std::move(*stencil);
      mark_no_fail(body, p);
      set_no_fail(body.stencil, body.no_fail);
      return body;
    }
    if (p.bond_layout == BondLayout::stencil) throw DeckError(fmt::format("discretization.bonds = 'stencil': {}; use list or auto", why));
  }
  body.bonds = lattice_bonds(p, body.points);
  mark_no_fail(body, p);
  return body;
}

// Whether a deck's bond list is lean (BondList: partner, float weight, state): PMB reads only
// those; RNP with list_precision: single runs in single precision on them (its observers
// recompute xi from the positions). Cell-area lattices keep a full list.
bool lean_list(const Problem& p) {
  return p.material.model == ModelKind::pmb || (p.material.model == ModelKind::rnp && p.list_precision == ListPrecision::single);
}

// Before the bonds: a lean list in single precision needs every point within the kernel's
// fixed point (lean_reach), refused here rather than at the first force pass.
void require_single_precision_reach(const Problem& p, const PointCloud& points) {
  if (p.list_precision != ListPrecision::single) return;
  const double reach = lean_reach(p.horizon);
  double far = 0;
  for (int k = 0; k < points.dim; ++k)
    for (double x : points.x[std::size_t(k)]) far = std::max(far, std::abs(x));
  if (!(far < reach))
    throw DeckError(fmt::format("discretization.list_precision = 'single': a point lies {:g} m from the origin, beyond the "
                                "single-precision kernel's reach of {:g} m for horizon {:g} m; move the body nearer the origin "
                                "or set list_precision: double",
                                far, reach, p.horizon));
}

// `bonds: compact` (explicit RNP, which recomputes xi and |xi| from the positions in Rnp::forces
// and its observers): 13 bytes per bond instead of 45. fe/hole_precrack (19.2 million directed
// bonds): peak 0.71 GB instead of 1.08, 10-20 % longer steps (2 threads, Zen 5).
bool stores_bond_geometry(const Problem& p) { return p.bond_layout != BondLayout::compact; }

BondList mesh_bonds(const Problem& p, const PointCloud& nodes, std::optional<Aabb> grid) {
  // Partners lie within eps plus an element of the node, at the mesh's node density.
  // Lumped P1 volumes sum to the mesh's area (2D) or volume (3D).
  const double per_node = std::accumulate(nodes.volume.begin(), nodes.volume.end(), 0.0) / double(nodes.size());
  require_bonds_fit(nodes.size(), p.dim, p.horizon + 2 * p.lattice.spacing, std::pow(per_node, 1.0 / p.dim), bytes_per_bond_explicit);
  const bool linear = p.material.model == ModelKind::rnp && p.material.influence == RnpInfluence::linear;
  // PMB reads only partner, weight and mask: its list is lean, as on a lattice (V_ij rounded to
  // float, 2^-24 relative), and runs the single-precision kernel unless list_precision: double.
  // So does RNP with list_precision: single.
  const bool lean = lean_list(p);
  if (lean) require_single_precision_reach(p, nodes);
  BondList bonds = element_bonds(nodes, {.horizon = p.horizon, .order = p.mesh.quadrature_order,
                                         .kernel = linear ? KernelShape::linear : KernelShape::constant, .grid = grid,
                                         .geometry = stores_bond_geometry(p), .lean = lean});
  // Bonds across a pre-crack start broken and stay broken (seed 003 Sec. 2.5).
  cut_bonds(nodes, bonds, p.cracks);
  return bonds;
}

BondList lattice_bonds(const Problem& p, const PointCloud& points) {
  const bool lean = lean_list(p) && p.quadrature_kind != QuadratureKind::cell_area;
  if (lean) require_single_precision_reach(p, points);
  require_bonds_fit(points.size(), p.dim, p.horizon, p.lattice.spacing, lean ? bytes_per_bond_lean : bytes_per_bond_explicit);
  BondList bonds;
  if (p.quadrature_kind == QuadratureKind::cell_area) {
    bonds = cell_area_bonds(points, p.horizon, p.precrack_damage ? std::vector<Crack>{} : p.cracks);
    if (p.precrack_damage) cut_bonds(points, bonds, p.cracks);
  } else if (p.precrack_damage) {
    // Bonds across a pre-crack exist and start broken, so damage shows the pre-crack.
    bonds = build_bonds(points, {.horizon = p.horizon, .partial_volume = p.partial_volume, .lean = lean, .geometry = stores_bond_geometry(p)});
    cut_bonds(points, bonds, p.cracks);
  } else {
    bonds = build_bonds(points,
                        {.horizon = p.horizon, .partial_volume = p.partial_volume, .cracks = p.cracks, .lean = lean, .geometry = stores_bond_geometry(p)});
  }
  return bonds;
}

AnyModel make_model(const Problem& p) {
  const auto& m = p.material;
  if (m.model == ModelKind::rnp) {
    Rnp r = m.rnp_C > 0            ? Rnp::make(p.dim, m.rnp_C, m.rnp_beta, p.horizon, 0, m.influence)
            : m.lipton_calibration ? Rnp::lipton(m.youngs_modulus, m.fracture_energy, p.horizon, m.influence)
                                   : Rnp::from_elastic(m.youngs_modulus, m.fracture_energy, p.horizon, m.kinematics, p.dim, m.influence);
    r.break_factor = m.break_factor;
    if (p.quadrature_kind == QuadratureKind::element) r.influence = RnpInfluence::constant;  // J is inside V_ij
    if (lean_list(p) && !r.single_precision_fits())
      throw DeckError(fmt::format("discretization.list_precision = 'single': RNP's pair force constant 2 P C beta = {:g} (or beta q = {:g}, "
                                  "q the fixed point's unit) is no normal float for horizon {:g} m; set list_precision: double",
                                  r.micromodulus(), r.beta * lean_unit(p.horizon), p.horizon));
    return r;
  }
  if (m.model == ModelKind::lps) throw std::invalid_argument("make_model: an LPS body and model come together from lps_dynamic_body()");
  if (m.model == ModelKind::osb) {
    Osb o = Osb::make(m.youngs_modulus, m.poisson_ratio, m.kinematics, p.horizon);
    o.critical_stretch = osb_critical_stretch(p);
    return o;  // weighted volumes come with the body: setup() weighs them
  }
  Pmb pmb = Pmb::from_elastic(m.youngs_modulus, m.fracture_energy, p.horizon, m.kinematics);
  if (p.list_precision == ListPrecision::double_precision) pmb.lean_kernel = Pmb::LeanKernel::exact;
  return pmb;
}

double osb_critical_stretch(const Problem& p) {
  const auto& m = p.material;
  return m.fracture_energy > 0 ? std::sqrt(4 * m.fracture_energy / (9 * m.youngs_modulus * p.horizon)) : 0.0;
}

std::vector<Boundary> build_boundaries(const Problem& p, const Body& body) { return boundaries_on(p, body.points); }

Setup setup(const Problem& p) {
  Setup s{};
  s.body = build_body(p);
  s.model = make_model(p);
  if (auto* o = std::get_if<Osb>(&s.model)) o->weigh(s.body);
  s.boundaries = build_boundaries(p, s.body);
  s.slab.global_size = s.body.size();
  s.time_step = time_step_of(p, std::visit([&](const auto& m) { return m.stable_time_step(s.body); }, s.model));
  return s;
}

QuasiStaticSetup setup_quasi_static(const Problem& p) {
  QuasiStaticSetup s{build_body(p), std::get<Rnp>(make_model(p)), {}, p.quasi_static};
  s.solver.options.condition_number = p.output.condition_number;
  s.boundaries = build_boundaries(p, s.body);
  // The options' unknown limits are input errors, found before any output is written.
  const auto fixed = fixed_components(s.body, s.boundaries);
  check_quasi_static_size(std::size_t(std::count(fixed.begin(), fixed.end(), 0)), s.solver.options);
  return s;
}


std::int64_t CloudGrids::body_id(std::int64_t site) const {
  if (!body.full()) return body.id_of_site(site);  // the cloud's own grid
  std::array<std::int64_t, 3> k{site % cloud.m[0], (site / cloud.m[0]) % cloud.m[1], site / (cloud.m[0] * cloud.m[1])};
  for (int a = 0; a < body.dim; ++a) {
    k[std::size_t(a)] -= band;
    if (k[std::size_t(a)] < 0 || k[std::size_t(a)] >= body.m[std::size_t(a)]) return -1;
  }
  return k[0] + body.m[0] * (k[1] + body.m[1] * k[2]);
}

std::array<std::int64_t, 6> CloudGrids::cloud_box(std::array<std::int64_t, 6> b) const {
  for (int a = 0; a < body.dim; ++a) b[std::size_t(2 * a)] += band, b[std::size_t(2 * a + 1)] += band;
  return b;
}

std::vector<std::int64_t> CloudGrids::sites_near(const std::array<std::int64_t, 6>& b, std::int64_t grow) const {
  std::array<std::int64_t, 6> c{0, 1, 0, 1, 0, 1};
  for (int a = 0; a < body.dim; ++a) {
    c[std::size_t(2 * a)] = std::max<std::int64_t>(0, b[std::size_t(2 * a)] - grow);
    c[std::size_t(2 * a + 1)] = std::min<std::int64_t>(cloud.m[std::size_t(a)], b[std::size_t(2 * a + 1)] + grow);
  }
  return cloud.ids_in(c);
}

CloudGrids::Neighbourhood CloudGrids::neighbourhood(const std::array<std::int64_t, 6>& box, double reach, const Shape& omega,
                                                    const ExteriorOptions& exterior) const {
  // A perturbed point sits within h / 2 of its site along each axis: one layer more than the
  // distance covers it.
  const auto layers = [&](double d) { return std::int64_t(std::ceil(d / cloud.h)) + 1; };
  Neighbourhood n;
  n.sites = sites_near(box, layers(3 * reach));
  n.points = lattice_points(cloud, n.sites);
  classify_exterior(n.points, omega, exterior);
  const auto inner = sites_near(box, layers(2 * reach) - 1);
  n.complete.resize(n.sites.size());
  for (std::size_t j = 0; j < n.sites.size(); ++j) {
    n.complete[j] = std::binary_search(inner.begin(), inner.end(), n.sites[j]);
    if ((body_id(n.sites[j]) >= 0) != (n.points.role[j] == Role::interior))
      throw std::logic_error("a cloud site's role does not follow from its index (cloud_grids)");
  }
  return n;
}

namespace {

// cloud_grids' box body, where its sites' roles follow from their indices.
std::optional<CloudGrids> box_cloud_grids(const Problem& p, const BoxLattice& cloud) {
  const auto body = box_lattice(p.body, p.lattice);
  if (!body) return std::nullopt;
  const double h = p.lattice.spacing;
  CloudGrids g{*body, cloud, std::int64_t(std::llround((cloud.bounds.hi[0] - body->bounds.hi[0]) / h))};
  const Vec3 first = g.cloud.site(g.band * (1 + g.cloud.m[0] + (p.dim == 3 ? g.cloud.m[0] * g.cloud.m[1] : 0)));
  for (int a = 0; a < p.dim; ++a) {
    const auto k = std::size_t(a);
    if (g.cloud.m[k] != g.body.m[k] + 2 * g.band || std::abs(first[k] - g.body.bounds.lo[k] - h / 2) > 1e-9 * h) return std::nullopt;
    // The body's last site and the exterior site after it, against the upper face; the lower
    // face is h / 2 from both (sites sit at cell centres) and p < 1/2.
    const double gap = g.body.bounds.hi[k] - (g.body.bounds.lo[k] + (double(g.body.m[k]) - 0.5) * h);
    const double moves = p.lattice.perturbation * h * (1 + 1e-9) + 1e-12 * h;
    if (p.lattice.perturbation > 0 && (gap <= moves || h - gap <= moves)) return std::nullopt;
  }
  return g;
}

}  // namespace

std::optional<CloudGrids> cloud_grids(const Problem& p, double band, bool any_shape) {
  const auto cloud = box_lattice(exterior_hull(p.body, p.lattice.spacing, band), p.lattice);
  if (!cloud) return std::nullopt;
  if (auto g = box_cloud_grids(p, *cloud)) return g;
  if (!any_shape) return std::nullopt;
  LatticeStream stream(*cloud);
  CloudGrids g{keep_sites(*cloud, [&](std::int64_t site) { return p.body.contains(stream.point(site)); }), *cloud, 0};
  if (g.body.size() == 0) return std::nullopt;
  return g;
}

}  // namespace peridot
