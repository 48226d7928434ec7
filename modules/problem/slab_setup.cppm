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

// Whether setup_slab can distribute this deck: every explicit, Newmark and quasi-static deck.
bool distributable(const Problem& problem);

// Rank `rank`'s share of an explicit run on `ranks` MPI ranks (collective). The body holds the
// rank's owned points and the ghosts their forces read (see Slab); boundaries hold owned points
// only. Regions (boundaries, no-fail) are selected on the whole body, so each point gets what it
// gets in the one-rank run, and each owned point sums its bonds in the one-rank order.
//   - PMB on a lattice stencil: slabs of lattice layers; each rank builds its slab's stencil only.
//     The stable step is the minimum of the ranks' estimates.
//   - Bond lists of PMB, RNP and OSB (lattices, perturbed lattices, meshes): a lattice of any
//     body shape is cut into bricks from its grid and each rank makes its brick's points only;
//     a mesh (held by rank 0 alone) is cut there by recursive coordinate bisection and each
//     rank is sent its share. Each rank builds bonds, weights and the model's per-point data
//     for its own neighbourhood only (setup_rcb_local).
//   - LPS bond lists (explicit or Newmark; a Newmark deck's Setup carries its body-force
//     boundaries and its step count): the same, on the lattice with its exterior band
//     (setup_lps_local); GMLS weights are solved for the rank's rows only. State-based models
//     (OSB, LPS), whose forces read partners' dilatations, keep ghosts two bonds deep with the
//     rows of the nearer ones. LPS's stable step is a power iteration run on the parts.
//   Where each rank builds its own part and rank 0's observers need no bond (root_gathers_bonds
//   false), rank 0's `whole` holds no bond and no point: its history rows are reductions over
//   the ranks, PNGs are drawn by every rank, and crack trackers and DDS snapshots read points
//   gathered from the ranks (the cracked ones; every k-th one).
Setup setup_slab(const Problem& problem, int rank, int ranks, std::optional<Setup>* whole = nullptr, bool restart = false);

// Whether rank 0 of a distributed run holds the whole body's bonds and gathers their states:
// for restarts from a one-file checkpoint, and every deck whose set-up is not built per rank
// (builds_locally). Otherwise rank 0 holds no bond: fragments are joined from the ranks'
// shares, checkpoints are written in parts, one per rank, and each rank writes its owned
// points' stress.
bool root_gathers_bonds(const Problem& problem, bool restart);
bool builds_locally(const Problem& problem);
// How many bonds deep a bond-list part holds ghosts (rows whole up to depth - 1 bonds out).
int ghost_depth(const Problem& problem);
// The deck's points (the lattice, or the mesh nodes with their elements), for rank 0 when a
// library user's observer asks for fields after the set-up.
PointCloud positions_of(const Problem& problem);

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

// Where each rank's owned rows' bonds start in gather order (the last: the whole body's
// directed bonds), from every rank's count. Collective.
void set_bond_starts(Slab& slab, std::uint64_t owned_bonds, int ranks) {
  const auto counts = parallel::all_gather(owned_bonds);
  slab.bond_starts.assign(std::size_t(ranks) + 1, 0);
  for (std::size_t r = 0; r < counts.size(); ++r) slab.bond_starts[r + 1] = slab.bond_starts[r] + std::size_t(counts[r]);
}

// The deck's lattice as a grid a rank makes its own points from (shape_lattice), once it fits in
// memory; nullopt where the body holds no point (lattice_of then names the deck's error).
std::optional<BoxLattice> lattice_grid_of(const Problem& p) {
  require_lattice_fits(p.body.bounds(), p.lattice.spacing, p.dim, 0.0);
  try {
    return shape_lattice(p.body, p.lattice);
  } catch (const std::invalid_argument& e) {
    throw DeckError(fmt::format("geometry.body: {} (discretization.spacing = {:g} m)", e.what(), p.lattice.spacing));
  }
}

Setup setup_stencil_slab(const Problem& p, int rank, int ranks) {
  Setup s{};
  double local = 0;
  std::uint64_t owned_bonds = 0;
  // The lattice is cut from its grid (a box's, or any shape's rows of sites), and each rank makes
  // its own points only.
  std::optional<BoxLattice> grid;
  std::vector<std::int64_t> selected;  // per boundary: the owned points in its region
  // Rank-local work, each rank's memory check among it: a rank that fails must not leave the
  // others waiting in the stable-step reduction below.
  parallel::together("set-up", [&] {
    // Ghost layers: as many as the stencil reaches.
    const BondOptions bond_options{.horizon = p.horizon, .partial_volume = p.partial_volume, .cracks = p.cracks};
    const int reach = stencil_reach(bond_options, p.dim, p.lattice.spacing);
    PointCloud whole;
    grid = lattice_grid_of(p);
    if (!grid) whole = lattice_of(p);
    try {
      s.slab = grid ? slab_of(*grid, rank, ranks, reach) : slab_of(whole, rank, ranks, reach);
    } catch (const std::invalid_argument& e) {
      throw DeckError(fmt::format("discretization: {} (mpirun -np {})", e.what(), ranks));
    }
    const Slab& slab = s.slab;
    s.body.points = grid ? lattice_points(*grid, slab.local_ids) : subset(whole, slab.local_ids);
    s.body.density = p.material.density;
    require_bonds_fit(s.body.size(), p.dim, p.horizon, p.lattice.spacing, bytes_per_bond_stencil);
    std::string why;
    auto stencil = build_stencil(s.body.points, bond_options, p.precrack_damage, why);
    if (!stencil) throw DeckError(fmt::format("discretization: a rank's slab is not a lattice stencil ({}); run without mpirun", why));
    s.body.stencil = std::move(*stencil);
    // Rows with no owned point are ghosts only: their forces are never read.
    s.body.stencil.restrict_rows(slab.owned);
    s.body.no_fail.assign(s.body.size(), 0);
    // Regions are tested point by point: the rank's own points select its share.
    for (const auto& region : p.no_fail)
      for (auto i : select_points(s.body.points, region)) s.body.no_fail[std::size_t(i)] = 1;
    set_no_fail(s.body.stencil, s.body.no_fail);
    s.model = make_model(p);
    s.boundaries = boundaries_on(p, s.body.points, true);
    for (auto& bc : s.boundaries) {
      std::erase_if(bc.points, [&](std::int32_t i) { return !slab.is_owned[std::size_t(i)]; });
      selected.push_back(std::int64_t(bc.points.size()));
    }
    // Each rank's estimate covers its owned rows: their minimum is the whole body's.
    local = std::visit([&](const auto& m) { return m.stable_time_step(s.body); }, s.model);
    const Stencil& st = s.body.stencil;
    for (auto j : slab.owned)
      for (std::size_t k = 0; k < st.offsets(); ++k) owned_bonds += (st.state[st.state_index(std::size_t(j), k)] & Stencil::exists) != 0;
  }, is_input_error);
  // A region that selects no point of the whole body is the deck's error, on every rank.
  parallel::sum_over_ranks(selected);
  parallel::together("set-up", [&] { require_selected(p, selected); }, is_input_error);
  set_bond_starts(s.slab, owned_bonds, ranks);
  s.time_step = time_step_of(p, parallel::min_over_ranks(local));
  return s;
}

// A Newmark deck's steps: its fixed dt to its end time.
TimeStep newmark_time_step(const Problem& p) { return choose_time_step(p.newmark.dt, {.end_time = p.newmark.end_time, .dt = p.newmark.dt}); }

// The whole one-rank set-up as an explicit run's: a Newmark deck's body, model and loads, with
// its own step count; a quasi-static deck's body, model and loads.
Setup whole_setup(const Problem& p) {
  auto composed = compose(p);
  if (auto* q = std::get_if<QuasiStaticSetup>(&composed)) {
    Setup s{};
    s.body = std::move(q->body);
    s.model = std::move(q->model);
    s.boundaries = std::move(q->boundaries);
    return s;
  }
  if (auto* n = std::get_if<NewmarkSetup>(&composed)) {
    Setup s{};
    s.body = std::move(n->body);
    s.model = std::move(n->model);
    s.boundaries = std::move(n->boundaries);
    s.time_step = newmark_time_step(p);
    return s;
  }
  return std::get<Setup>(std::move(composed));
}

// The longest edge of the cloud's elements (0 without elements).
double longest_edge(const PointCloud& pc) {
  double longest = 0;
  const auto edges = [&](const auto& elements) {
    for (const auto& e : elements)
      for (std::size_t a = 0; a < e.size(); ++a)
        for (std::size_t b = a + 1; b < e.size(); ++b)
          longest = std::max(longest, norm(pc.position(std::size_t(e[a])) - pc.position(std::size_t(e[b]))));
  };
  edges(pc.triangles);
  edges(pc.tetrahedra);
  return longest;
}

// For every rank, the elements of `whole` whose nodes it all holds (near[r], ascending ids),
// renumbered to its points, in the whole mesh's order (triangles, then tetrahedra): one pass
// over the elements, from the ranks that hold each node, not one pass per rank.
struct PartElements {
  std::vector<std::vector<std::array<std::int32_t, 3>>> triangles;
  std::vector<std::vector<std::array<std::int32_t, 4>>> tetrahedra;
};
PartElements elements_of_parts(const PointCloud& whole, const std::vector<std::vector<std::int64_t>>& near) {
  // The ranks that hold each node, node by node (CSR), in rank order.
  std::vector<std::size_t> start(whole.size() + 1, 0);
  for (const auto& ids : near)
    for (auto id : ids) ++start[std::size_t(id) + 1];
  for (std::size_t i = 1; i < start.size(); ++i) start[i] += start[i - 1];
  std::vector<int> holder(start.back());
  {
    std::vector<std::size_t> next(start.begin(), start.end() - 1);
    for (std::size_t r = 0; r < near.size(); ++r)
      for (auto id : near[r]) holder[next[std::size_t(id)]++] = int(r);
  }
  const auto holds = [&](std::int64_t node, int r) {
    return std::binary_search(holder.begin() + std::ptrdiff_t(start[std::size_t(node)]), holder.begin() + std::ptrdiff_t(start[std::size_t(node) + 1]), r);
  };
  PartElements out;
  out.triangles.resize(near.size());
  out.tetrahedra.resize(near.size());
  const auto keep = [&](const auto& from, auto& to) {
    for (const auto& e : from)
      for (auto k = start[std::size_t(e[0])]; k < start[std::size_t(e[0]) + 1]; ++k) {
        const int r = holder[k];
        if (!std::all_of(e.begin() + 1, e.end(), [&](std::int32_t node) { return holds(node, r); })) continue;
        auto local = e;
        const auto& ids = near[std::size_t(r)];
        for (auto& node : local) node = std::int32_t(std::lower_bound(ids.begin(), ids.end(), std::int64_t(node)) - ids.begin());
        to[std::size_t(r)].push_back(local);
      }
  };
  keep(whole.triangles, out.triangles);
  keep(whole.tetrahedra, out.tetrahedra);
  return out;
}

// A mesh deck's share for one rank on N ranks. Rank 0 alone holds the mesh (make_mesh_once):
// it cuts the nodes by coordinate bisection, as every rank did when all held the mesh, and sends
// each rank the nodes within `depth` bond reaches of its owned nodes (ids, owners, positions,
// lumped volumes), the elements among them in mesh order, the deck's boundary nodes among them,
// and what only the whole mesh decides (its bounds, every rank's owned count). So no other rank
// holds the whole mesh. Rank 0 finds every rank's nodes and elements in one pass each, and
// packs one rank's share at a time.
struct MeshShare {
  std::vector<std::int64_t> near;  // global ids, ascending
  std::vector<int> near_owner;
  PointCloud points;               // the near nodes, with the elements whose nodes are all near
  Aabb bounds{};                   // the whole mesh's
  std::vector<std::uint64_t> owned_counts;
  std::vector<std::vector<std::int32_t>> boundaries;  // per point boundary: its global ids among near
  std::vector<int> root_owner;     // rank 0: every node's owner, for the gather order
  std::shared_ptr<const BrickCut> bricks;  // a structured mesh made in parts: the owners' bricks (no root_owner)
};

// A mesh read in parts (read_mesh_part): the share is cut from this rank's own part as
// share_mesh cuts it from the whole mesh on rank 0, the nodes within `depth` bond reaches of its
// owned nodes and the elements among them, in mesh order. No rank holds the whole mesh.
MeshShare share_of_part(const Problem& p, int rank, int depth) {
  const auto& part = *p.mesh.part;
  if (depth > part.depth) throw std::logic_error("share_of_part: the part holds shallower ghosts than the set-up needs");
  // Partners are nodes of elements the ball reaches into: within the horizon and an element.
  const std::vector<std::int64_t> near = nodes_near_owned(part, rank, depth, 1.01 * (p.horizon + part.longest_edge));  // into the part
  std::vector<std::int32_t> to(part.ids.size(), -1);
  for (std::size_t j = 0; j < near.size(); ++j) {
    if (!part.complete[std::size_t(near[j])]) throw std::logic_error("share_of_part: a near node's elements are not all held");
    to[std::size_t(near[j])] = std::int32_t(j);
  }
  MeshShare share;
  share.points = subset(part.points, near);
  const auto among = [&](const auto& from, auto& into) {
    for (auto e : from) {
      bool all = true;
      for (auto& node : e) all &= (node = to[std::size_t(node)]) >= 0;
      if (all) into.push_back(e);
    }
  };
  among(part.points.triangles, share.points.triangles);
  among(part.points.tetrahedra, share.points.tetrahedra);
  for (auto i : near) share.near.push_back(part.ids[std::size_t(i)]), share.near_owner.push_back(part.owner[std::size_t(i)]);
  share.bounds = p.mesh.bounds();
  share.owned_counts = part.owned_counts;
  // The deck's point boundaries in order: a group's nodes from the part's groups, a region's
  // selected on the near nodes.
  const auto& specs = p.boundaries;
  const auto bcs = boundaries_on(p, share.points, true);
  for (std::size_t b = 0, k = 0; b < bcs.size(); ++b, ++k) {
    while (specs[k].nonlocal_traction) ++k;
    auto& ids = share.boundaries.emplace_back();
    if (!specs[k].group.empty()) {
      for (auto g : part.groups.at(specs[k].group))
        if (std::ranges::binary_search(share.near, g)) ids.push_back(std::int32_t(g));
    } else {
      for (auto j : bcs[b].points) ids.push_back(std::int32_t(share.near[std::size_t(j)]));
    }
  }
  share.bricks = part.bricks;
  if (rank == 0 && !part.bricks)
    for (std::size_t r = 0; r < part.owned_counts.size(); ++r) share.root_owner.insert(share.root_owner.end(), part.owned_counts[r], int(r));
  return share;
}

MeshShare share_mesh(const Problem& p, int rank, int ranks, int depth) {
  if (p.mesh.part) {
    MeshShare share;
    parallel::together("set-up", [&] { share = share_of_part(p, rank, depth); }, is_input_error);
    return share;
  }
  PointCloud whole;
  std::vector<int> owner;
  std::vector<std::uint64_t> counts(std::size_t(ranks), 0);
  std::vector<std::vector<std::int64_t>> near_of;
  PartElements elements;
  std::vector<std::vector<std::uint8_t>> on_boundary;  // per point boundary, per node: 1 if it acts there
  std::vector<double> scalars;                        // the whole mesh's bounds and spacing
  parallel::together("set-up", [&] {
    if (rank != 0) return;
    whole = positions_of(p);
    owner = owners_of(whole, ranks);
    // The horizon and the longest element edge: partners are nodes of elements the ball reaches into.
    const double reach = 1.01 * (p.horizon + longest_edge(whole));
    near_of = points_near_parts(whole, owner, ranks, depth * reach);
    elements = elements_of_parts(whole, near_of);
    for (const auto& bc : boundaries_on(p, whole)) {
      auto& flags = on_boundary.emplace_back(whole.size(), 0);
      for (auto g : bc.points) flags[std::size_t(g)] = 1;
    }
    for (int o : owner) ++counts[std::size_t(o)];
    const Aabb box = whole.bounds();
    scalars = {box.lo[0], box.lo[1], box.lo[2], box.hi[0], box.hi[1], box.hi[2], whole.spacing};
  }, is_input_error);
  const auto make = [&](int r) {
    const auto near = std::move(near_of[std::size_t(r)]);
    const PointCloud part = subset(whole, near);
    parallel::Bytes b;
    b.put(near);
    std::vector<int> near_owner(near.size());
    for (std::size_t j = 0; j < near.size(); ++j) near_owner[j] = owner[std::size_t(near[j])];
    b.put(near_owner);
    for (int k = 0; k < 3; ++k) b.put(part.x[std::size_t(k)]);
    b.put(part.volume);
    b.put(part.role);
    b.put(std::exchange(elements.triangles[std::size_t(r)], {}));
    b.put(std::exchange(elements.tetrahedra[std::size_t(r)], {}));
    b.put(scalars);
    b.put(counts);
    b.put_count(on_boundary.size());
    for (const auto& flags : on_boundary) {
      std::vector<std::int32_t> mine;
      for (auto g : near)
        if (flags[std::size_t(g)]) mine.push_back(std::int32_t(g));
      b.put(mine);
    }
    return std::move(b.data);
  };
  parallel::Bytes in;
  in.data = parallel::or_abort("set-up", [&] { return parallel::scatter_from_root(make); });
  MeshShare share;
  in.get(share.near);
  in.get(share.near_owner);
  share.points.dim = p.dim;
  for (int k = 0; k < 3; ++k) in.get(share.points.x[std::size_t(k)]);
  in.get(share.points.volume);
  in.get(share.points.role);
  in.get(share.points.triangles);
  in.get(share.points.tetrahedra);
  const auto v = in.get<double>();
  share.bounds = {{v[0], v[1], v[2]}, {v[3], v[4], v[5]}};
  share.points.spacing = v[6];
  in.get(share.owned_counts);
  share.boundaries.resize(in.count());
  for (auto& ids : share.boundaries) in.get(ids);
  if (rank == 0) share.root_owner = std::move(owner);
  return share;
}

// What a part built from its own neighbourhood learns from the others: where its ghosts are on
// their owners, and where each rank's owned rows start in gather order. Collective.
void join_parts(Setup& s, int ranks) {
  std::vector<std::int64_t> ghost_ids;
  for (auto g : s.slab.ghost) ghost_ids.push_back(s.slab.local_ids[std::size_t(g)]);
  std::uint64_t owned_bonds = 0;
  for (auto j : s.slab.owned) owned_bonds += s.body.bonds.count(std::size_t(j));
  s.slab.ghost_owner_index = parallel::index_on_owners(ghost_ids, s.slab.ghost_owner, s.slab.local_ids);
  set_bond_starts(s.slab, owned_bonds, ranks);
}

// Rank `rank`'s share built from its own neighbourhood: the points are cut into parts from
// their positions alone, and each rank builds bonds, weights, pre-crack cuts and the model's
// per-point data only for the points within `depth` bond reaches of its owned points: the rows
// that must be whole (the owned points' and, two bonds deep, the nearer ghosts') are then whole,
// and the outer ghosts are found among their partners. Each held row is then the one-rank row,
// partner for partner, since bonds are found in global partner order on any subset that holds
// the whole neighbourhood.
//   - A lattice body of any shape (perturbed or not: the glass plates, blocks and bars, plates
//     with holes, specimens cut from unions) is cut into bricks of sites from its grid alone
//     (shape_lattice: runs of kept sites row by row), and each rank makes only the points of its
//     brick and its neighbourhood (lattice_points): no rank generates the whole body.
//   - A mesh is held by rank 0 alone (make_mesh_once), cut there by recursive coordinate
//     bisection, and each rank is sent its neighbourhood (share_mesh).
// Collective (ghost indices on their owners, bond counts, region counts, the stable step).
Setup setup_rcb_local(const Problem& p, int rank, int ranks) {
  const int depth = ghost_depth(p);
  const bool mesh = p.discretization_kind == DiscretizationKind::mesh;
  std::optional<BoxLattice> grid;
  Setup s{};
  double local_step = 0;
  std::vector<std::int64_t> selected;  // a box lattice's boundaries: the owned points in each region
  std::optional<MeshShare> share;
  if (mesh) share = share_mesh(p, rank, ranks, depth);
  parallel::together("set-up", [&] {
    // The farthest partner any weight rule takes, plus a margin, never a miss: on a lattice the
    // horizon and a cell diagonal (partial volumes, cell areas) and a cell.
    const double lattice_reach = bond_cutoff({.horizon = p.horizon, .partial_volume = true}, p.dim, p.lattice.spacing) + p.lattice.spacing;
    PointCloud whole;
    std::vector<int> owner;
    std::vector<std::int64_t> near;
    std::optional<BrickCut> cut;
    if (!mesh) grid = lattice_grid_of(p);
    if (grid) {
      try {
        cut = brick_cut(*grid, ranks);
      } catch (const std::invalid_argument& e) {
        throw DeckError(fmt::format("discretization: {} (mpirun -np {})", e.what(), ranks));
      }
      if (!every_brick_holds_points(*cut)) cut.reset(), grid.reset();
    }
    if (grid) {
      // A perturbed point sits within perturbation * h < h / 2 of its site along each axis, so a
      // site more than `depth` reaches + 1 layers from the brick holds no point that near.
      near = brick_sites(*cut, rank, std::int64_t(std::ceil(depth * lattice_reach / p.lattice.spacing)) + 1);
    } else if (share) {
      near = std::move(share->near);
    } else {
      whole = positions_of(p);
      owner = owners_of(whole, ranks);
      near = points_near_part(whole, owner, rank, depth * lattice_reach);
    }
    Body nb;
    nb.points = grid ? lattice_points(*grid, near) : share ? std::move(share->points) : subset(whole, near);
    nb.density = p.material.density;
    if (share) {
      // The share's elements are those whose nodes are all near, in mesh order: every element
      // that a held row's ball reaches into; the weights then sum in the one-rank order (the
      // whole mesh's grid).
      nb.bonds = mesh_bonds(p, nb.points, share->bounds);
    } else {
      nb.bonds = lattice_bonds(p, nb.points);
    }
    // Regions are tested point by point, so a point near a part's edge gets its one-rank flags.
    nb.no_fail.assign(near.size(), 0);
    for (const auto& region : p.no_fail)
      for (auto j : select_points(nb.points, region)) nb.no_fail[std::size_t(j)] = 1;
    AnyModel model = make_model(p);
    // m_i sums i's whole row: right on every point whose row is held (within depth - 1 reaches
    // of the owned points, so its row is whole), and those are the partners a held row reads.
    if (auto* o = std::get_if<Osb>(&model)) o->weigh(nb);
    std::vector<std::int64_t> held;
    s.slab = grid                      ? brick_part(*cut, near, nb.bonds, rank, depth, held)
             : share && share->bricks ? brick_part(*share->bricks, near, nb.bonds, rank, depth, held)
             : share                  ? rcb_part(share->near_owner, share->owned_counts, &share->root_owner, near, nb.bonds, rank, depth, held)
                                      : rcb_part(owner, near, nb.bonds, rank, ranks, depth, held);
    if (share && p.mesh.part) s.slab.axis = share->bricks ? -4 : -3;
    Slab by_near = s.slab;
    by_near.local_ids = held;
    s.body.points = subset(nb.points, held);
    s.body.density = nb.density;
    keep_held_rows(nb.bonds, by_near);
    s.body.bonds = std::move(nb.bonds);
    s.body.no_fail.resize(held.size());
    for (std::size_t j = 0; j < held.size(); ++j) s.body.no_fail[j] = nb.no_fail[std::size_t(held[j])];
    s.model = std::visit(
        [&](auto m) -> AnyModel {
          if constexpr (requires { m.restrict_to(held); }) m.restrict_to(held);
          if constexpr (requires { m.prepare(s.body); }) m.prepare(s.body);
          return m;
        },
        std::move(model));
    if (grid) {
      // Only the ranks together know whether a region holds a point of the body (below).
      s.boundaries = boundaries_on(p, s.body.points, true);
      for (auto& bc : s.boundaries) {
        std::erase_if(bc.points, [&](std::int32_t i) { return !s.slab.is_owned[std::size_t(i)]; });
        selected.push_back(std::int64_t(bc.points.size()));
      }
    } else if (share) {
      // Names, kinds and values from the deck; the points from rank 0's selection on the whole mesh.
      auto all = boundaries_on(p, s.body.points, true);
      for (std::size_t k = 0; k < all.size(); ++k) all[k].points = std::move(share->boundaries[k]);
      s.boundaries = owned_boundaries(std::move(all), s.slab);
      // A mesh read in parts: whether a region holds a node is a sum over the ranks (below).
      if (p.mesh.part)
        for (const auto& bc : s.boundaries) selected.push_back(std::int64_t(bc.points.size()));
    } else {
      s.boundaries = owned_boundaries(boundaries_on(p, whole), s.slab);
    }
    // Every point's estimate reads its own row only: the minimum over the ranks' owned rows is
    // the whole body's.
    local_step = std::visit([&](const auto& m) { return m.stable_time_step(s.body); }, s.model);
  }, is_input_error);
  if (grid || p.mesh.part) {
    parallel::sum_over_ranks(selected);
    parallel::together("set-up", [&] { require_selected(p, selected); }, is_input_error);
  }
  join_parts(s, ranks);
  // A quasi-static run has no time step.
  const double step = parallel::min_over_ranks(local_step);
  if (p.solver_kind != SolverKind::quasi_static) s.time_step = time_step_of(p, step);
  return s;
}

// Rank `rank`'s share of an LPS deck (explicit or Newmark) built from its own neighbourhood, as
// setup_rcb_local does for bond-based decks: the body's points are cut into bricks of their grid
// (cloud_grids: a box body's grid, or the cloud's grid keeping the sites whose points are
// interior), and a rank makes, and builds bonds, GMLS weights, exterior moments and traction
// regions for, only the cloud points within three bond reaches of its brick. Where a brick
// would hold no point, every rank generates the lattice with its exterior band (positions
// only) and cuts the body's points by coordinate bisection instead. Weights are solved only
// where a point's whole ball is held (two reaches), which covers every row the rank keeps
// (ghosts two bonds deep). The explicit stable step is a power iteration run on the parts
// through the halo: the one-rank estimate.
// Collective.
Setup setup_lps_local(const Problem& p, int rank, int ranks) {
  Setup s{};
  auto grids = cloud_grids(p, p.horizon, true);
  // On box grids: per boundary the owned points in its region, then per traction the exterior
  // points it loads.
  std::vector<std::int64_t> selected;
  std::size_t boundary_count = 0;
  parallel::together("set-up", [&] {
    if (p.solver_kind == SolverKind::newmark) check_newmark_boundaries(p);
    LpsCloud cloud;
    PointCloud whole;  // the body's points, where the cloud is generated whole
    std::vector<int> owner;
    std::optional<BrickCut> cut;
    std::vector<std::int64_t> near, near_ids;  // cloud indices (or sites); the interior ones' body ids
    std::vector<std::uint8_t> complete;
    if (grids) {
      // A rank makes the cloud's sites within three bond reaches of its brick of the body's grid
      // and solves weights for those within two (lps_cloud's checks: the lattice fits here,
      // tractions hold exterior points below, over the ranks).
      const double h = p.lattice.spacing;
      try {
        require_lattice_fits(p.body.bounds(), h, p.dim, p.horizon);
        cut = brick_cut(grids->body, ranks);
      } catch (const std::invalid_argument& e) {
        throw DeckError(fmt::format("geometry.body: {} (discretization.spacing = {:g} m, mpirun -np {})", e.what(), h, ranks));
      }
      if (!every_brick_holds_points(*cut)) cut.reset(), grids.reset();
    }
    if (grids) {
      const double h = p.lattice.spacing;
      cloud.exterior = lps_exterior(p);
      auto n = grids->neighbourhood(grids->cloud_box(cut->brick(rank, 0)), p.horizon + h, p.body, {.band = p.horizon, .neumann = cloud.exterior});
      near = std::move(n.sites);
      cloud.points = std::move(n.points);
      complete = std::move(n.complete);
      for (const auto site : near)
        if (const auto id = grids->body_id(site); id >= 0) near_ids.push_back(id);
    } else {
      cloud = lps_cloud(p);
      const PointCloud& pc = cloud.points;
      // The body's points, which ranks own: the cloud's interior points, in its order. Exterior
      // points only lend their moments to the rows that reach them.
      std::vector<std::int64_t> interior;
      for (std::size_t i = 0; i < pc.size(); ++i)
        if (pc.role[i] == Role::interior) interior.push_back(std::int64_t(i));
      whole = subset(pc, interior);
      owner = owners_of(whole, ranks);
      NearPart part = near_part(p, pc, whole, owner, rank);
      near = std::move(part.ids);
      complete = std::move(part.complete);
      cloud.points = subset(pc, near);
      // The body points among the near ones, by their ids in the whole body.
      for (std::size_t j = 0; j < near.size(); ++j)
        if (cloud.points.role[j] == Role::interior)
          near_ids.push_back(std::int64_t(std::lower_bound(interior.begin(), interior.end(), near[j]) - interior.begin()));
    }
    LpsDynamicBody d = lps_body_of(p, cloud.points, cloud.exterior, complete);
    std::vector<std::int64_t> held;
    s.slab = cut ? brick_part(*cut, near_ids, d.body.bonds, rank, 2, held) : rcb_part(owner, near_ids, d.body.bonds, rank, ranks, 2, held);
    Slab by_near = s.slab;
    by_near.local_ids = held;
    s.body.points = subset(d.body.points, held);
    s.body.density = d.body.density;
    keep_held_rows(d.body.bonds, by_near);
    s.body.bonds = std::move(d.body.bonds);
    // Regions are tested point by point, so a point near a part's edge gets its one-rank flags.
    s.body.no_fail.assign(held.size(), 0);
    for (const auto& region : p.no_fail)
      for (auto i : select_points(s.body.points, region)) s.body.no_fail[std::size_t(i)] = 1;
    d.model.restrict_to(held);
    d.model.prepare(s.body);
    if (p.bond_layout == BondLayout::compact && p.solver_kind == SolverKind::explicit_dynamics) s.body.bonds.drop_geometry();
    if (d.model.single_precision) s.body.bonds.add_float_weights();
    s.model = std::move(d.model);
    if (cut) {
      // Only the ranks together know whether a region holds a point of the body, or a traction
      // an exterior point of the cloud (each rank counts those it made: a sum over overlapping
      // neighbourhoods, which is 0 only where every rank's is).
      s.boundaries = boundaries_on(p, s.body.points, true);
      for (auto& bc : s.boundaries) {
        std::erase_if(bc.points, [&](std::int32_t i) { return !s.slab.is_owned[std::size_t(i)]; });
        selected.push_back(std::int64_t(bc.points.size()));
      }
      boundary_count = selected.size();
      const auto loaded = traction_points(p, cloud.points);
      selected.insert(selected.end(), loaded.begin(), loaded.end());
    } else {
      s.boundaries = owned_boundaries(boundaries_on(p, whole), s.slab);
    }
  }, is_input_error);
  if (grids) {
    parallel::sum_over_ranks(selected);
    parallel::together("set-up", [&] {
      require_selected(p, std::span<const std::int64_t>(selected).first(boundary_count));
      require_traction_points(p, std::span<const std::int64_t>(selected).subspan(boundary_count));
    }, is_input_error);
  }
  join_parts(s, ranks);
  if (p.solver_kind == SolverKind::newmark) {
    s.time_step = newmark_time_step(p);
    return s;
  }
  const double estimate = parallel::or_abort("stable time step", [&] {
    const parallel::Halo halo(s.slab.local_size(), s.slab.ghost, s.slab.ghost_owner, s.slab.ghost_owner_index);
    const int dim = p.dim;
    const BodyParts parts{s.slab.owned, s.slab.local_ids,
                          [&](VectorField& u) {
                            const std::array<double*, 3> a{u[0].data(), u[1].data(), u[2].data()};
                            halo.exchange(std::span<double* const>(a.data(), std::size_t(dim)));
                          },
                          [](ExactSum& e) {
                            parallel::sum_over_ranks(e.words_for_reduction());
                            e.normalise();
                          }};
    return std::get<Lps>(s.model).stable_time_step(s.body, parts);
  });
  s.time_step = time_step_of(p, estimate);
  return s;
}

}  // namespace

// Every deck setup_slab distributes builds its parts per rank: the stencil's bricks, and bond
// lists of PMB, RNP and OSB (lattices and meshes) and of LPS (GMLS weights; its power-iteration
// stable step runs on the parts) from each rank's neighbourhood.
bool builds_locally(const Problem& p) { return distributable(p); }

PointCloud positions_of(const Problem& p) {
  if (p.material.model == ModelKind::lps) return lps_body_points(p);
  return p.discretization_kind == DiscretizationKind::mesh ? p.mesh.points() : lattice_of(p);
}

bool root_gathers_bonds(const Problem& p, bool restart) { return !builds_locally(p) || restart; }

int ghost_depth(const Problem& p) {
  // OSB's forces read their partners' dilatations, from rows held whole one bond further out;
  // the stress (51) of a point reads bonds starting up to a bond away: one more again.
  return (p.material.model == ModelKind::osb ? 2 : 1) + (p.output.wants_stress() ? 1 : 0);
}

bool distributable(const Problem& p) { return capabilities(p.solver_kind).distributed; }

Setup setup_slab(const Problem& p, int rank, int ranks, std::optional<Setup>* whole, bool restart) {
  if (!distributable(p))
    throw DeckError(fmt::format("this deck cannot run on {} MPI ranks yet: explicit, Newmark and quasi-static decks run distributed, "
                                "static decks on PETSc solve by rows; run this one without mpirun",
                                ranks));
  if (ranks == 1) {
    if (whole) whole->reset();
    return whole_setup(p);
  }
  if (!builds_locally(p)) throw std::logic_error("setup_slab: a deck that does not build per rank");
  const bool bonds_on_root = root_gathers_bonds(p, restart);
  const bool lps = p.material.model == ModelKind::lps;
  Setup s = uses_stencil(p) ? setup_stencil_slab(p, rank, ranks) : lps ? setup_lps_local(p, rank, ranks) : setup_rcb_local(p, rank, ranks);
  s.slab.gathers_bonds = bonds_on_root;
  if (whole) parallel::together("observer set-up", [&] {
    whole->reset();
    if (rank != 0) return;
    if (bonds_on_root) {
      whole->emplace(whole_setup(p));
      return;
    }
    // The observers' body: the dimension only (DistributedStepper adds the positions for a
    // library user's observers).
    Setup& w = whole->emplace();
    w.body.points.dim = p.dim;
    w.body.density = p.material.density;
    if (lps) {
      // The model's constants for the run's header; its per-point data stay with the parts.
      Lps m = std::get<Lps>(s.model);
      const std::array<std::int64_t, 1> first{0};
      m.restrict_to(first);
      w.model = std::move(m);
    } else {
      w.model = make_model(p);
    }
    w.time_step = s.time_step;
    w.slab.global_size = s.slab.global_size;
  }, is_input_error);
  return s;
}

}  // namespace peridot
