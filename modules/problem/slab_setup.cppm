export module peridot.problem:slab_setup;
import peridot.std;
import peridot.io;
import peridot.quadrature;
import peridot.implicit;
import peridot.deck;
import :setup;
import :lps_dynamics_setup;
import :compose;

export namespace peridot {

// Whether setup_slab can distribute this deck: every explicit deck.
bool distributable(const Problem& problem);

// Rank `rank`'s share of an explicit run on `ranks` MPI ranks (collective). The body holds the
// rank's owned points and the ghosts their forces read (see Slab); boundaries hold owned points
// only. Regions (boundaries, no-fail) are selected on the whole body, so each point gets what it
// gets in the one-rank run, and each owned point sums its bonds in the one-rank order.
//   - PMB on a lattice stencil: slabs of lattice layers; each rank builds its slab's stencil only.
//     The stable step is the minimum of the ranks' estimates.
//   - Bond lists (PMB, RNP, OSB, LPS; lattices, perturbed lattices, meshes): each rank builds the
//     whole one-rank set-up, cuts it by recursive coordinate bisection and keeps its rows, so the
//     set-up peaks at the one-rank memory and the run then holds its part. State-based models
//     (OSB, LPS), whose forces read partners' dilatations, keep ghosts two bonds deep with the
//     rows of the nearer ones. The stable step is the whole body's. When `whole` is given, rank 0
//     gets the whole set-up there (its observers report from it); the stencil path leaves it empty.
Setup setup_slab(const Problem& problem, int rank, int ranks, std::optional<Setup>* whole = nullptr);

}  // namespace peridot

namespace peridot {

namespace {

// The boundaries (point ids into the whole body) restricted to this rank's owned points (local
// indices): loads and constraints act on owned points, and ghosts take their owners' values.
std::vector<Boundary> owned_boundaries(std::vector<Boundary> all, const Slab& slab) {
  for (auto& bc : all) {
    std::vector<std::int32_t> mine;
    for (auto g : bc.points)
      if (const auto i = slab.local_of(g); i >= 0 && slab.is_owned[std::size_t(i)]) mine.push_back(std::int32_t(i));
    bc.points = std::move(mine);
  }
  return all;
}

Setup setup_stencil_slab(const Problem& p, int rank, int ranks) {
  Setup s{};
  double local = 0;
  // Rank-local work, each rank's memory check among it: a rank that fails must not leave the
  // others waiting in the stable-step reduction below.
  parallel::together("set-up", [&] {
    const PointCloud whole = lattice_of(p);
    // Ghost layers: as many as the stencil reaches.
    const BondOptions bond_options{.horizon = p.horizon, .partial_volume = p.partial_volume, .cracks = p.cracks};
    const int reach = stencil_reach(bond_options, p.dim, p.lattice.spacing);
    try {
      s.slab = slab_of(whole, rank, ranks, reach);
    } catch (const std::invalid_argument& e) {
      throw DeckError(fmt::format("discretization: {} (mpirun -np {})", e.what(), ranks));
    }
    const Slab& slab = s.slab;
    s.body.points = subset(whole, slab.local_ids);
    s.body.density = p.material.density;
    require_bonds_fit(s.body.size(), p.dim, p.horizon, p.lattice.spacing, bytes_per_bond_stencil);
    std::string why;
    auto stencil = build_stencil(s.body.points, bond_options, p.precrack_damage, why);
    if (!stencil) throw DeckError(fmt::format("discretization: a rank's slab is not a lattice stencil ({}); run without mpirun", why));
    s.body.stencil = std::move(*stencil);
    // Rows with no owned point are ghosts only: their forces are never read.
    s.body.stencil.restrict_rows(slab.owned);
    s.body.no_fail.assign(s.body.size(), 0);
    for (const auto& region : p.no_fail)
      for (auto g : select_points(whole, region))
        if (const auto i = slab.local_of(g); i >= 0) s.body.no_fail[std::size_t(i)] = 1;
    set_no_fail(s.body.stencil, s.body.no_fail);
    s.model = make_model(p);
    s.boundaries = owned_boundaries(boundaries_on(p, whole), s.slab);
    // Each rank's estimate covers its owned rows: their minimum is the whole body's.
    local = std::visit([&](const auto& m) { return m.stable_time_step(s.body); }, s.model);
  }, is_input_error);
  s.time_step = time_step_of(p, parallel::min_over_ranks(local));
  return s;
}

Setup setup_rcb(const Problem& p, int rank, int ranks, std::optional<Setup>* whole_out) {
  Setup whole = std::get<Setup>(compose(p));
  const bool state_based = std::holds_alternative<Osb>(whole.model) || std::holds_alternative<Lps>(whole.model);
  Setup s{};
  try {
    s.slab = rcb_of(whole.body.points, whole.body.bonds, rank, ranks, state_based ? 2 : 1);
  } catch (const std::invalid_argument& e) {
    throw DeckError(fmt::format("discretization: {} (mpirun -np {})", e.what(), ranks));
  }
  const Slab& slab = s.slab;
  s.body.points = subset(whole.body.points, slab.local_ids);
  s.body.density = whole.body.density;
  s.body.bonds = local_bonds(whole.body.bonds, slab);
  s.body.no_fail.resize(slab.local_size());
  for (std::size_t j = 0; j < slab.local_size(); ++j) s.body.no_fail[j] = whole.body.no_fail[std::size_t(slab.local_ids[j])];
  // The model's per-point data follow the points; its caches are rebuilt on the rank's rows.
  s.model = std::visit(
      [&](const auto& m) -> AnyModel {
        auto mine = m;
        if constexpr (requires { mine.restrict_to(slab.local_ids); }) mine.restrict_to(slab.local_ids);
        if constexpr (requires { mine.prepare(s.body); }) mine.prepare(s.body);
        return mine;
      },
      whole.model);
  s.boundaries = owned_boundaries(whole.boundaries, slab);
  s.time_step = whole.time_step;
  if (whole_out && rank == 0) whole_out->emplace(std::move(whole));
  return s;
}

}  // namespace

bool distributable(const Problem& p) { return capabilities(p.solver_kind).distributed; }

Setup setup_slab(const Problem& p, int rank, int ranks, std::optional<Setup>* whole) {
  if (!distributable(p))
    throw DeckError(fmt::format("this deck cannot run on {} MPI ranks yet: explicit decks and static LPS decks on PETSc run distributed, "
                                "the Newmark, quasi-static and static OSB solvers do not; run this one without mpirun",
                                ranks));
  if (ranks == 1) {
    if (whole) whole->reset();
    return std::get<Setup>(compose(p));
  }
  if (uses_stencil(p) && p.bond_layout != BondLayout::list) return setup_stencil_slab(p, rank, ranks);
  Setup s;
  parallel::together("set-up", [&] { s = setup_rcb(p, rank, ranks, whole); }, is_input_error);
  return s;
}

}  // namespace peridot
