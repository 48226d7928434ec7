module;
#include <signal.h>
#include <stdint.h>  // SIZE_MAX

export module peridot.run:distributed;
import peridot.std;
import peridot.problem;
import peridot.analysis;
import peridot.observe;
import peridot.render;
import :loop;
import :parts;
import :checkpointing;
import :stop;
import :explicit_stepper;
import :implicit_steppers;

namespace peridot {

namespace distributed {

// Copies the bond states of points ids[0..count) (point-major, K per point) between a stencil and
// a buffer: into the buffer when `pack`, out of it otherwise.
void copy_states(Stencil& st, const std::int64_t* ids, std::size_t count, std::uint8_t* buffer, bool pack) {
  const std::size_t K = st.offsets(), stride = st.row_length();
#pragma omp parallel for schedule(static)
  for (std::int64_t j = 0; j < std::int64_t(count); ++j) {
    std::uint8_t* at = st.state.data() + st.state_base(std::size_t(ids[j]));
    std::uint8_t* b = buffer + std::size_t(j) * K;
    for (std::size_t k = 0; k < K; ++k)
      if (pack) b[k] = at[k * stride];
      else at[k * stride] = b[k];
  }
}

// The same for a bond list: the rows of points ids[0..count), one after another.
void copy_states(BondList& bl, const std::int64_t* ids, std::size_t count, std::uint8_t* buffer, bool pack) {
  std::size_t at = 0;
  for (std::size_t j = 0; j < count; ++j) {
    const auto i = std::size_t(ids[j]);
    std::uint8_t* row = bl.intact.data() + bl.begin(i);
    if (pack) std::copy(row, row + bl.count(i), buffer + at);
    else std::copy(buffer + at, buffer + at + bl.count(i), row);
    at += bl.count(i);
  }
}

void copy_states(Body& body, const std::int64_t* ids, std::size_t count, std::uint8_t* buffer, bool pack) {
  body.visit_bonds([&](auto& bonds) { copy_states(bonds, ids, count, buffer, pack); });
}


// After a restart has scattered the owned rows' bond states: the ghosts whose rows a rank holds
// (state-based models) take their owners' rows, as fixed-width records through the halo.
void refresh_ghost_rows(const parallel::Halo& halo, const Slab& slab, BondList& bl) {
  std::size_t width = 0;
  for (std::size_t i = 0; i < slab.full_row.size(); ++i) width = std::max(width, bl.count(i));
  width = std::size_t(parallel::max_over_ranks(int(width)));
  std::vector<std::uint8_t> records(slab.local_size() * width, 0);
  for (std::size_t i = 0; i < slab.local_size(); ++i)
    std::copy(bl.intact.data() + bl.begin(i), bl.intact.data() + bl.end(i), records.data() + i * width);
  halo.exchange_records(records, width);
  for (auto g : slab.ghost) {
    const auto i = std::size_t(g);
    std::copy(records.data() + i * width, records.data() + i * width + bl.count(i), bl.intact.data() + bl.begin(i));
  }
}

// Moves owned fields and bond states between a rank's part and rank 0's whole body: each rank
// packs its owned points in order, rank 0 receives them rank after rank (Slab::gather_ids).
// Bond states travel point-major: on a stencil [point][offset] (the two stencils share their
// offsets), on a list the owned rows one after another (a rank's rows are the whole body's).
class Transfer {
 public:
  // states: whether bond states travel too (rank 0 holds the whole bond list).
  Transfer(const Slab& slab, Body& local, Body* whole, bool states = true) : slab_(slab), local_(local), whole_(whole), states_(states) {
    local.visit_bonds(overloaded{[&](const Stencil& st) {
                                   for (auto s : slab.owned_starts) state_starts_.push_back(s * st.offsets());
                                 },
                                 [&](const BondList&) { state_starts_ = slab.bond_starts; }});
    const auto r = std::size_t(slab.rank);
    if (states_) bits_.resize(state_starts_[r + 1] - state_starts_[r]);
    if (whole_ && states_) all_bits_.resize(state_starts_.back());
  }

  void gather(const State& s, State* w) {
    for (int c = 0; c < 3; ++c) {
      gather_field(s.u[c], w ? &w->u[c] : nullptr);
      gather_field(s.v[c], w ? &w->v[c] : nullptr);
      gather_field(s.f[c], w ? &w->f[c] : nullptr);
    }
    if (w) {
      w->time = s.time;
      w->step = s.step;
    }
    if (!states_) return;
    copy_states(local_, slab_.owned.data(), slab_.owned.size(), bits_.data(), true);
    parallel::gather_to_root(bits_, all_bits_, state_starts_);
    if (whole_) copy_states(*whole_, slab_.gather_ids.data(), slab_.gather_ids.size(), all_bits_.data(), false);
  }

  // The inverse, for a restart: owned u, v, f and bond states from rank 0's whole run.
  void scatter(const State* w, State& s) {
    for (int c = 0; c < 3; ++c) {
      scatter_field(w ? &w->u[c] : nullptr, s.u[c]);
      scatter_field(w ? &w->v[c] : nullptr, s.v[c]);
      scatter_field(w ? &w->f[c] : nullptr, s.f[c]);
    }
    if (whole_) copy_states(*whole_, slab_.gather_ids.data(), slab_.gather_ids.size(), all_bits_.data(), true);
    parallel::scatter_from_root(all_bits_, bits_, state_starts_);
    copy_states(local_, slab_.owned.data(), slab_.owned.size(), bits_.data(), false);
    // Step and time from rank 0: the others contribute zeros.
    s.time = parallel::sum_over_ranks(w ? w->time : 0.0);
    s.step = std::size_t(parallel::sum_over_ranks(w ? double(w->step) : 0.0));
  }

  // One per-point field: the owned values of `local` into `whole` (rank 0; null elsewhere), in
  // global order. Collective.
  void gather_field(const std::vector<double>& local, std::vector<double>* whole) {
    mine_.resize(slab_.owned_size());
    for (std::size_t j = 0; j < mine_.size(); ++j) mine_[j] = local[std::size_t(slab_.owned[j])];
    if (whole_ && all_.empty()) all_.resize(slab_.global_size);
    parallel::gather_to_root(mine_, all_, slab_.owned_starts);
    if (whole) whole->resize(slab_.global_size);
    if (whole)
      for (std::size_t j = 0; j < all_.size(); ++j) (*whole)[std::size_t(slab_.gather_ids[j])] = all_[j];
  }
  void scatter_field(const std::vector<double>* whole, std::vector<double>& local) {
    mine_.resize(slab_.owned_size());
    if (whole_ && all_.empty()) all_.resize(slab_.global_size);
    if (whole)
      for (std::size_t j = 0; j < all_.size(); ++j) all_[j] = (*whole)[std::size_t(slab_.gather_ids[j])];
    parallel::scatter_from_root(all_, mine_, slab_.owned_starts);
    for (std::size_t j = 0; j < mine_.size(); ++j) local[std::size_t(slab_.owned[j])] = mine_[j];
  }

 private:
  const Slab& slab_;
  Body& local_;
  Body* whole_;
  bool states_;
  std::vector<std::size_t> state_starts_;
  std::vector<double> mine_, all_;
  std::vector<std::uint8_t> bits_, all_bits_;
};

}  // namespace distributed

}  // namespace peridot


export namespace peridot {

// An explicit run on N MPI ranks, any force model: the one-rank stepper's solver on this rank's
// part of the body (setup_slab: lattice slabs on the stencil, coordinate bisection on a bond
// list), with ghost displacements refreshed through a PetscSF halo before each force pass. Each
// point sums its bonds in the one-rank order, so displacements and damage are bitwise those of
// one rank.
//   - VTU: every rank writes its owned points as one piece, rank 0 the .pvtu and the .pvd.
//   - Other observers and checkpoints: rank 0 gathers the owned pieces of u, v, f and the bond
//     states into `whole` (its one-rank set-up) on the steps they are due and reports from there.
//   - A restart: rank 0 holds the checkpoint (checked against `whole`) and scatters it; ghost
//     rows a rank evaluates (state-based models) take their owners' bond states.
// Each phase before the steps ends every rank when one rank fails in it (parallel::together for
// rank-local work, or_abort where the phase holds collectives).
// Solver NewmarkSolver<Lps>: implicit Newmark on the same parts; its BiCGSTAB refreshes the
// ghosts before each operator application and sums its dot products exactly over the owned
// points, so every rank takes the one-rank step lengths (NewmarkParts). No restart.
// Solver QuasiStaticSolver<Rnp>: quasi-static Newton on the same parts; each rank assembles the
// tangent rows of its owned points and PETSc solves for them. An advance is a converged load
// increment, the record's time the load factor. No restart.
template <ForceModel Model, class Solver = ExplicitSolver<Model>>
class DistributedStepper {
  static constexpr bool newmark = std::is_same_v<Solver, NewmarkSolver<Lps>>;
  static constexpr bool quasi = std::is_same_v<Solver, QuasiStaticSolver<Rnp>>;

 public:
  // users_read_fields: a library user's observers read the state (Sample), so rank 0 gathers it.
  // snapshot_points: LiveOptions::snapshot_max_points, the most points a DDS snapshot sends.
  DistributedStepper(const Problem& p, Setup& local, Setup* whole, std::optional<Checkpoint> restart, bool users_read_fields = false,
                     std::size_t snapshot_points = LiveOptions{}.snapshot_max_points)
      : p_(p), local_(local), whole_(whole), slab_(local.slab), root_(local.slab.rank == 0), lean_(!local.slab.gathers_bonds),
        fields_(!lean_ || users_read_fields), png_(lean_ && p.output.png_every), damage_points_(lean_ && users_read_fields),
        cracks_(lean_ && !users_read_fields && (p.output.crack_tip_every || p.output.crack_front_every)),
        snapshots_(lean_ && !users_read_fields && p.output.dds_snapshot_every), model_(std::get<Model>(local.model)) {
    if (root_ != (whole != nullptr)) throw std::logic_error("DistributedStepper: rank 0, and only rank 0, holds the whole set-up");
    state_.emplace(local.body.size());
    // A lean rank 0 holds positions only where its observers read fields: made from the deck,
    // or for a mesh, which no rank keeps whole past the set-up, gathered from the parts.
    if (lean_ && damage_points_ && p.discretization_kind == DiscretizationKind::mesh) parallel::or_abort("observers' positions", [&] {
      PointCloud all;
      whole_points_on_root(local.body.points, slab_.owned, slab_.local_ids, all);
      if (root_) whole->body.points = std::move(all);
    });
    parallel::together("allocation", [&] {
      if (root_ && lean_ && damage_points_ && whole->body.size() == 0) whole->body.points = positions_of(p);
      if (root_) all_.emplace(fields_ ? slab_.global_size : 0);
      transfer_.emplace(slab_, local.body, root_ ? &whole->body : nullptr, !lean_);
      // Where no field travels to rank 0, neither does its gather order (8 B per point there).
      if (lean_ && !fields_) std::vector<std::int64_t>().swap(local.slab.gather_ids);
    });
    halo_.emplace(parallel::or_abort(
        "halo set-up", [&] { return parallel::Halo(slab_.local_size(), slab_.ghost, slab_.ghost_owner, slab_.ghost_owner_index); }));
    // Broken bonds since t = 0, from the whole body's states: a bond across two slabs breaks on both.
    broken_at_start_ = lean_ ? owned_broken() : root_ ? whole->body.broken_bonds() : 0;
    typename ExplicitSolver<Model>::Counters counters;
    const bool restarting = parallel::max_over_ranks(restart ? 1 : 0) != 0;
    if (restarting && lean_) {
      // Every rank read its owned points from the checkpoint's parts (read_restart_part).
      parallel::together("restart", [&] {
        if (!restart) throw std::logic_error("DistributedStepper: a lean restart gives every rank its points");
        restore_owned(*restart);
        if (root_) counters = {restart->external_work, 0};
        restart.reset();
      });
      parallel::or_abort("restart halo", [&] {
        exchange(state_->u);
        local.body.visit_bonds(overloaded{[](const Stencil&) {}, [&](BondList& bl) { distributed::refresh_ghost_rows(*halo_, slab_, bl); }});
      });
      if constexpr (requires { model_.prepare(local.body); }) model_.prepare(local.body);
    } else if (restarting) {
      parallel::together("restart", [&] {
        if (root_) {
          counters = {restart->external_work, 0};
          restore_run(*restart, whole->body, *all_);
          restart.reset();
        }
      }, is_input_error);
      parallel::or_abort("restart scatter", [&] {
        transfer_->scatter(root_ ? &*all_ : nullptr, *state_);
        exchange(state_->u);
        // A stencil rank holds its ghosts' states as rows of its own; a list rank refreshes them.
        local.body.visit_bonds(overloaded{[](const Stencil&) {}, [&](BondList& bl) { distributed::refresh_ghost_rows(*halo_, slab_, bl); }});
      });
      // A model that caches data of the bond mask (LPS) rebuilds it from the restored mask.
      if constexpr (requires { model_.prepare(local.body); }) model_.prepare(local.body);
    }
    first_step_ = state_->step;
    if constexpr (newmark) {
      solver_.emplace(local.body, model_, local.boundaries, p.newmark);
      solver_->distribute({.owned = slab_.owned, .exchange = [this](VectorField& u) { exchange(u); }, .reduce = [](ExactSum& s) { exact_sums_over_ranks({&s}); }});
      parallel::or_abort("initial forces", [&] { solver_->initialize(*state_); });
    } else if constexpr (quasi) {
      QuasiStaticOptions o = p.quasi_static.options;
      o.condition_number = p.output.condition_number;
      parallel::or_abort("Newton rows", [&] {
        solver_.emplace(local.body, model_, local.boundaries, o,
                        BodyParts{.owned = slab_.owned, .ids = slab_.local_ids, .exchange = [this](VectorField& u) { exchange(u); }, .reduce = [](ExactSum& s) { exact_sums_over_ranks({&s}); }});
      });
    } else {
      solver_.emplace(local.body, model_, local.boundaries, local.time_step, p.solver.scheme);
      solver_->set_exchange([this](VectorField& u) { exchange(u); });
      // The first forces, through the halo.
      parallel::or_abort("initial forces", [&] {
        if (first_step_ > 0) solver_->restore(*state_, counters);
        else solver_->initialize(*state_);
      });
    }
    // Test-only: PERIDOT_INJECT_STOP=<step>@<rank> makes that rank alone ask for a stop after that
    // step, as a SIGTERM delivered to it alone would.
    if (const char* v = std::getenv("PERIDOT_INJECT_STOP")) {
      const std::string spec = v;
      const auto at = spec.find('@');
      if (at != std::string::npos && std::atoi(spec.c_str() + at + 1) == slab_.rank) injected_stop_ = std::size_t(std::atoll(spec.c_str()));
    }
    owned_points_ = subset(local.body.points, slab_.owned);
    if (png_) parallel::or_abort("PNG point size", [&] { png_spacing_ = spacing_of_parts(); });
    if (cracks_ || snapshots_) tracked_.emplace(p.output, local.body.points, slab_.owned, slab_.local_ids, slab_.global_size, snapshot_points);
    ids_.resize(slab_.owned_size());
    for (std::size_t j = 0; j < ids_.size(); ++j) ids_[j] = double(slab_.local_ids[std::size_t(slab_.owned[j])]);
  }

  bool done() const {
    if constexpr (quasi) return solver_->done();
    else return state_->step >= steps();
  }
  void advance() {
    parallel::inject_failure("stepping");
    if constexpr (quasi) {
      last_ = solver_->advance(state_->u);
      state_->step = last_.step;
      state_->time = last_.load;
      iterations_ += last_.iterations;
    } else {
      solver_->step(*state_);
    }
  }
  std::size_t step() const { return state_->step; }
  std::size_t steps() const {
    if constexpr (newmark) return solver_->steps();
    else if constexpr (quasi) return p_.quasi_static.options.steps;
    else return local_.time_step.steps;
  }
  // Quasi-static: the load factor as the record's time, a line per increment, the load-step CSV.
  std::string abscissa() const
    requires quasi
  {
    return "load factor";
  }
  std::string step_line() const
    requires quasi
  {
    return quasi_static_step_line(last_);
  }
  std::vector<AnyObserver> observers(const std::filesystem::path& dir)
    requires quasi
  {
    load_steps_ = dir / (p_.name + "_load_steps.csv");
    return {AnyObserver(LoadStepCsv(load_steps_, &last_), 1)};
  }
  // BiCGSTAB's iterations and re-solves of the last step: the same on every rank.
  std::pair<long, long> solver_work() const
    requires newmark
  {
    return {solver_->last().iterations, solver_->last().sub_iterations};
  }
  double time() const { return state_->time; }
  // Quasi-static: the directed bonds past RNP's inflection point, as on one rank.
  std::size_t broken() const {
    if constexpr (quasi) return last_.softening_bonds;
    else return broken_;
  }
  // Any rank's stop request stops every rank after the same step.
  bool agree(bool stop) const {
    if (!stop && state_->step == injected_stop_) {
      request_stop(SIGTERM);
      stop = true;
    }
    return parallel::max_over_ranks(stop ? 1 : 0) != 0;
  }

  // Collective: gathers to rank 0 and writes this rank's VTU piece when one is due.
  Report report(bool last) {
    const std::size_t n = state_->step;
    if (lean_) {
      // The history row from exact sums over the owned points, reduced over the ranks: the
      // one-rank figures bit for bit, with no whole field on rank 0. Fields travel to rank 0
      // only for the observers that draw or track them.
      if (fields_) transfer_->gather(*state_, root_ ? &*all_ : nullptr);
      else if (root_) all_->time = state_->time, all_->step = state_->step;
      work_ = parallel::sum_over_ranks(external_work());
      broken_ = quasi ? last_.softening_bonds : (owned_broken() - broken_at_start_) / 2;
      local_damage();
      if (damage_points_) transfer_->gather_field(phi_, root_ ? &all_phi_ : nullptr);
      if constexpr (requires(std::vector<double>& e) { model_.point_energies(local_.body, state_->u, e); })
        solver_->model().point_energies(local_.body, state_->u, energy_);
      else throw std::logic_error("DistributedStepper: this model reports no point energies");
      ExactSum strain;
      for (auto j : slab_.owned) strain += energy_[std::size_t(j)];
      auto kinetic = kinetic_energy_sum(local_.body, state_->v, slab_.owned);
      auto damaged = damage_fraction_sums(local_.body, phi_, slab_.owned);
      exact_sums_over_ranks({&strain, &kinetic, &damaged[0], &damaged[1]});
      std::optional<FragmentReport> fragments;
      if (detail::due(p_.output.fragments_every, n, last)) fragments = joined_fragments();
      const bool vtu_due = vtu_ && detail::due(p_.output.vtu_every, n, last), png_due = png_ && detail::due(p_.output.png_every, n, last);
      if ((vtu_due && p_.output.vtu_stress) || (png_due && stress_png(p_.output.png_field))) owned_stress();
      if (vtu_due) write_pieces(n, false);
      if (png_due) draw_png(n);
      Observers::Totals totals{kinetic.value(), damage_fraction_of(damaged), std::move(fragments)};
      if (tracked_) tracked_->gather(n, last, state_->u, phi_, totals);
      if (!root_) return {};
      const double energy = strain.value();
      return {&*all_, work_, broken_, [energy] { return energy; }, std::move(totals)};
    }
    transfer_->gather(*state_, root_ ? &*all_ : nullptr);
    work_ = parallel::sum_over_ranks(external_work());
    if (root_) broken_ = (whole_->body.broken_bonds() - broken_at_start_) / 2;
    // Rank 0's model reports from the gathered mask: one that caches data of it follows.
    const Model* whole_model = root_ ? &std::get<Model>(whole_->model) : nullptr;
    if constexpr (requires { whole_model->prepare(whole_->body); })
      if (root_) whole_model->prepare(whole_->body);
    if (vtu_ && writes_vtu() && detail::due(p_.output.vtu_every, n, last)) write_pieces(n);
    if (!root_) return {};
    return {&*all_, work_, broken_, [this, whole_model] { return whole_model->strain_energy(whole_->body, all_->u); }};
  }
  // Collective. With the whole body on rank 0, rank 0 writes one file; otherwise every rank
  // writes its part and rank 0 the index, last (write_checkpoint_index), and the previous
  // checkpoint's parts go once the new index names the new ones.
  void checkpoint(const std::filesystem::path& file)
    requires(!newmark && !quasi)
  {
    if (!lean_) {
      if (root_) write_checkpoint(file, make_checkpoint(p_, *whole_, *all_, work_, broken_));
      return;
    }
    const auto step = state_->step;
    parallel::together("checkpoint parts", [&] { write_checkpoint_part(file, checkpoint_part(step)); });
    parallel::together("checkpoint index", [&] {
      if (!root_) return;
      State at(0);  // the index holds no field
      at.step = state_->step;
      at.time = state_->time;
      Checkpoint c = make_checkpoint(p_, *whole_, at, work_, broken_);
      c.points = slab_.global_size;
      c.bonds = slab_.bond_starts.back();
      local_.body.visit_bonds(overloaded{[&](const Stencil& st) {
                                           c.bonds = slab_.global_size * st.offsets();
                                           c.bond_layout = "point_offsets";
                                         },
                                         [](const BondList&) {}});
      write_checkpoint_index(file, c, slab_.ranks);
    });
    if (last_checkpoint_ && *last_checkpoint_ != step) {
      std::error_code ignored;
      std::filesystem::remove(checkpoint_part_path(file, slab_.rank, *last_checkpoint_), ignored);
    }
    last_checkpoint_ = step;
  }
  // The VTU series of pieces; every rank, once rank 0's observers made the directory.
  void open_outputs(const std::filesystem::path& dir) {
    dir_ = dir;
    vtu_.emplace(dir, p_.name);
    if (first_step_ && p_.output.vtu_every) vtu_->resume(first_step_);
  }
  // Rank 0's observers read the whole body; the VTU is written here, piece by piece, unless it
  // holds the stress and rank 0 gathers the bonds (a restart from a one-file checkpoint): the
  // stress of a point on a lattice reads bonds of points up to a horizon away. Lean ranks hold
  // those rows whole (ghost_depth) and write the stress of their owned points themselves.
  const Body& body() const { return whole_->body; }
  // This rank's part, as it steps it: part observers read it on every rank, no gather.
  std::optional<PartView> part() const {
    return PartView{&local_.body, &*state_, slab_.owned, slab_.local_ids, slab_.global_size, slab_.rank, slab_.ranks};
  }
  bool writes_vtu() const { return lean_ || !p_.output.vtu_stress; }
  // Lean ranks draw their own points into one image (draw_png); otherwise rank 0's observers do.
  bool writes_png() const { return png_; }
  Observers::DamageFunction damage_function() const {
    if (lean_) return [this](const VectorField&, std::vector<double>& d) { d = all_phi_; };
    const Model& m = std::get<Model>(whole_->model);
    if constexpr (requires(std::vector<double>& d) { m.damage(whole_->body, all_->u, d); })
      return [&m, this](const VectorField& u, std::vector<double>& d) { m.damage(whole_->body, u, d); };
    else return {};
  }
  Observers::StressFunction stress_function() const {
    if (lean_) return {};  // lean ranks write their owned points' stress themselves
    if constexpr (PairForceModel<Model>) {
      const Model& m = std::get<Model>(whole_->model);
      // Composition keeps decks that ask for stress off the stencil.
      return [&m, this](const VectorField& u, StressField& tau) { tau = stress_field(m, whole_->body, u); };
    }
    return {};
  }
  std::vector<std::string> describe() const {
    const BodyCounts counts{slab_.global_size, slab_.bond_starts.empty() ? 0 : slab_.bond_starts.back()};
    std::vector<std::string> lines;
    if constexpr (newmark) lines = describe_newmark(p_, whole_->body, std::get<Lps>(whole_->model), steps(), lean_ ? &counts : nullptr);
    else if constexpr (quasi) lines = describe_quasi_static(p_, whole_->body, std::get<Rnp>(whole_->model), lean_ ? &counts : nullptr);
    else lines = describe_explicit(p_, *whole_, std::get<Model>(whole_->model), lean_ ? &counts : nullptr);
    lines.push_back(fmt::format("  MPI: {} ranks, {}", slab_.ranks, cut_name(slab_)));
    // Where rank 0 held the whole mesh for a while, say why, and the way around it.
    if (p_.discretization_kind == DiscretizationKind::mesh && slab_.axis == -1)
      lines.push_back(p_.mesh.file.empty() ? "  mesh: rank 0 made the structured mesh whole (too few nodes for a grid of ranks) and sent each rank its share"
                      : p_.mesh.file.extension() == ".geo"
                          ? "  mesh: Gmsh, a serial mesher, meshed the .geo whole on rank 0, which sent each rank its share; `peridot mesh` "
                            "writes it once as a .msh that every rank reads in parts"
                          : "  mesh: rank 0 read the .msh whole and sent each rank its share (node_order: file, or nodes that cannot be "
                            "numbered in parts); every rank reads a .msh in parts in spatial node order");
    return lines;
  }
  std::vector<std::string> summary() const {
    std::size_t least = SIZE_MAX, most = 0;
    for (int r = 0; r < slab_.ranks; ++r) {
      const std::size_t m = slab_.owned_starts[std::size_t(r) + 1] - slab_.owned_starts[std::size_t(r)];
      least = std::min(least, m);
      most = std::max(most, m);
    }
    std::vector<std::string> lines{
        fmt::format("  MPI: {} ranks, {}: {} to {} points each, {} ghost points on rank 0", slab_.ranks, cut_name(slab_), least, most, halo_->ghosts())};
    std::string root = !lean_            ? ""
                       : damage_points_ ? "rank 0 holds no bond, its observers read gathered per-point fields"
                                        : "rank 0 holds no bond and no field, its history rows are reductions over the ranks";
    if (lean_ && !damage_points_) {
      if (png_) root += ", every rank draws its points into the PNGs";
      if (cracks_) root += ", crack tracking reads the cracked points only";
      if (snapshots_) root += tracked_->snapshot_note();
    }
    if (slab_.near_points)
      lines.push_back(fmt::format("  set-up: each rank built the bonds of its own neighbourhood only ({} of {} points on rank 0){}{}", slab_.near_points,
                                  slab_.global_size, root.empty() ? "" : "; ", root));
    else if (!root.empty())
      lines.push_back("  observers: " + root);
    if (vtu_steps_) lines.push_back(fmt::format("  output: {} ({} steps, one piece per rank)", vtu_->pvd().string(), vtu_steps_));
    if (pngs_) lines.push_back(fmt::format("  output: {} PNG snapshots, each rank drawing its points (last {})", pngs_, last_png_.string()));
    if constexpr (newmark) lines.insert(lines.begin(), newmark_work(solver_->totals()));
    if constexpr (quasi) {
      const auto work = quasi_static_summary(state_->step, iterations_, load_steps_);
      lines.insert(lines.begin(), work.begin(), work.end());
    }
    return lines;
  }

 private:
  // Newmark does no work on the body through prescribed motion: its loads are forces. A
  // quasi-static record has no work column either.
  double external_work() const {
    if constexpr (newmark || quasi) return 0.0;
    else return solver_->external_work();
  }
  // The components a force pass reads: the body's dimension (in 1D and 2D the others stay zero
  // everywhere, ghosts included).
  void exchange(VectorField& u) const {
    const std::array<double*, 3> a{u[0].data(), u[1].data(), u[2].data()};
    halo_->exchange(std::span<double* const>(a.data(), std::size_t(local_.body.dim())));
  }
  // The fragments of the whole body without it: each rank labels the pieces of its part, the
  // ghosts learn their owners' piece ids through the halo, and rank 0 joins the shares
  // (join_fragment_shares). Collective; the report on rank 0 only.
  std::optional<FragmentReport> joined_fragments() const {
    return peridot::joined_fragments(local_.body, slab_.is_owned, *halo_, {.large_mass_fraction = p_.output.large_fragment_fraction});
  }
  // This rank's part of a checkpoint: its owned points, their state and their bond rows.
  CheckpointPart checkpoint_part(std::size_t step) const {
    CheckpointPart c;
    c.step = step;
    c.part = slab_.rank;
    c.parts = slab_.ranks;
    c.box = owned_box(local_);
    const auto& s = *state_;
    for (int k = 0; k < 3; ++k) c.u[k].reserve(slab_.owned_size()), c.v[k].reserve(slab_.owned_size()), c.f[k].reserve(slab_.owned_size());
    for (auto j : slab_.owned) {
      const auto i = std::size_t(j);
      c.ids.push_back(std::uint64_t(slab_.local_ids[i]));
      for (int k = 0; k < 3; ++k) c.u[k].push_back(s.u[k][i]), c.v[k].push_back(s.v[k][i]), c.f[k].push_back(s.f[k][i]);
      // A stencil's row: one state per offset (point_offsets); a list's: its bonds.
      local_.body.visit_bonds(overloaded{[&](const Stencil& st) {
                                           c.row_bonds.push_back(st.offsets());
                                           for (std::size_t k = 0; k < st.offsets(); ++k) c.bond_state.push_back(st.state[st.state_index(i, k)]);
                                         },
                                         [&](const BondList& bl) {
                                           c.row_bonds.push_back(bl.count(i));
                                           c.bond_state.insert(c.bond_state.end(), bl.intact.data() + bl.begin(i), bl.intact.data() + bl.end(i));
                                         }});
    }
    return c;
  }
  // This rank's owned points from its share of a checkpoint in parts (their u, v, f, and bond
  // rows one after another, in owned order; a stencil's row is one state per offset).
  void restore_owned(Checkpoint& c) {
    auto& s = *state_;
    std::size_t at = 0;
    for (std::size_t q = 0; q < slab_.owned.size(); ++q) {
      const auto i = std::size_t(slab_.owned[q]);
      for (int k = 0; k < 3; ++k) s.u[k][i] = c.u[k][q], s.v[k][i] = c.v[k][q], s.f[k][i] = c.f[k][q];
      local_.body.visit_bonds(overloaded{[&](Stencil& st) {
                                           for (std::size_t k = 0; k < st.offsets(); ++k) st.state[st.state_index(i, k)] = c.bond_state[at + k];
                                           at += st.offsets();
                                         },
                                         [&](BondList& bl) {
                                           std::copy_n(c.bond_state.begin() + std::ptrdiff_t(at), bl.count(i), bl.intact.begin() + bl.begin(i));
                                           at += bl.count(i);
                                         }});
    }
    s.time = c.time;
    s.step = std::size_t(c.step);
  }
  // Directed broken bonds in the owned rows, summed over the ranks (every row is owned once).
  std::size_t owned_broken() const {
    std::uint64_t count = 0;
    local_.body.visit_bonds(overloaded{[&](const Stencil& st) {
                                         for (auto j : slab_.owned)
                                           for (std::size_t k = 0; k < st.offsets(); ++k)
                                             count += st.state[st.state_index(std::size_t(j), k)] == Stencil::exists;
                                       },
                                       [&](const BondList& bl) {
                                         for (auto j : slab_.owned)
                                           for (auto b = bl.begin(std::size_t(j)); b < bl.end(std::size_t(j)); ++b) count += bl.intact[b] == 0;
                                       }});
    parallel::sum_over_ranks(count);
    return std::size_t(count);
  }
  // Damage of the local points (right on the owned ones): the model's own, else broken bonds.
  void local_damage() {
    const auto& s = *state_;
    if constexpr (requires { model_.damage(local_.body, s.u, phi_); }) solver_->model().damage(local_.body, s.u, phi_);
    else damage(local_.body, phi_);
  }
  // The point spacing and square size the one-rank PNG estimates from the whole body: each
  // rank measures its sampled owned points' nearest neighbours among its points, ghosts
  // included, and rank 0 takes the medians of all (estimate_spacing's steps). Collective.
  PointSpacing spacing_of_parts() const { return peridot::spacing_of_parts(local_.body.points, slab_.owned, slab_.local_ids, slab_.global_size); }
  // Every rank draws its owned points; the image is the one rank 0 would draw of the whole
  // body (RenderParts), and only rank 0 holds it. Collective.
  void draw_png(std::size_t n) {
    const auto& o = p_.output;
    const auto& st = *state_;
    // Only what the image reads, for the owned points: the colour values, and u when deformed.
    std::string label = "damage";
    if (stress_png(o.png_field)) {
      const auto v = stress_png_values(o.png_field, owned_stress_, von_mises_, label);
      magnitude_.assign(v.begin(), v.end());
    } else if (o.png_field == "damage") {
      magnitude_.resize(slab_.owned_size());
      for (std::size_t j = 0; j < magnitude_.size(); ++j) magnitude_[j] = phi_[std::size_t(slab_.owned[j])];
    } else {
      label = png_magnitudes(o.png_field, {st.u[0], st.u[1], st.u[2]}, {st.v[0], st.v[1], st.v[2]}, magnitude_);
      // Owned indices ascend, so the owned values move down in place.
      for (std::size_t j = 0; j < slab_.owned_size(); ++j) magnitude_[j] = magnitude_[std::size_t(slab_.owned[j])];
      magnitude_.resize(slab_.owned_size());
    }
    const std::span<const double> values = magnitude_;
    if (o.png_deformed)
      for (int k = 0; k < 3; ++k) {
        piece_[std::size_t(k)].resize(slab_.owned_size());
        for (std::size_t j = 0; j < slab_.owned_size(); ++j) piece_[std::size_t(k)][j] = st.u[std::size_t(k)][std::size_t(slab_.owned[j])];
      }
    RenderField rf;
    rf.dim = local_.body.dim();
    rf.x = {owned_points_.x[0], owned_points_.x[1], owned_points_.x[2]};
    if (o.png_deformed) rf.u = {piece_[0], piece_[1], piece_[2]};
    rf.values = values;
    rf.field_name = label;
    rf.time = state_->time;
    if constexpr (quasi) rf.time_label = abscissa();
    rf.step = n;
    rf.spacing = png_spacing_.spacing;
    RenderOptions ro = png_options(o);
    ro.point_size = png_spacing_.solid_size;
    const RenderParts parts = mpi_render_parts();
    const auto file = dir_ / fmt::format("{}_{:07d}.png", p_.name, n);
    parallel::or_abort("PNG snapshot", [&] { render_png(file, rf, ro, parts); });
    last_png_ = file;
    ++pngs_;
  }
  // The stress of the owned points from the rank's own rows: every bond across an owned point's
  // segments starts at a point whose row is held whole, and its force reads its partner's
  // dilatation, from a row held whole too (ghost_depth), so each is the one-rank value.
  void owned_stress() {
    if constexpr (PairForceModel<Model>) {
      const StressField all = stress_field(solver_->model(), local_.body, state_->u);
      std::vector<double>* to[6] = {&owned_stress_.xx, &owned_stress_.yy, &owned_stress_.xy, &owned_stress_.zz, &owned_stress_.yz, &owned_stress_.xz};
      const std::vector<double>* from[6] = {&all.xx, &all.yy, &all.xy, &all.zz, &all.yz, &all.xz};
      for (int c = 0; c < 6; ++c) {
        to[c]->clear();
        if (from[c]->empty()) continue;
        for (auto j : slab_.owned) to[c]->push_back((*from[c])[std::size_t(j)]);
      }
    } else {
      throw std::logic_error("DistributedStepper: stress output from a model without pair forces");
    }
  }
  void write_pieces(std::size_t n, bool fresh_damage = true) {
    const auto& s = *state_;
    if (fresh_damage) local_damage();
    const std::vector<double>* from[10] = {&s.u[0], &s.u[1], &s.u[2], &s.v[0], &s.v[1], &s.v[2], &s.f[0], &s.f[1], &s.f[2], &phi_};
    for (std::size_t q = 0; q < piece_.size(); ++q) {
      piece_[q].resize(slab_.owned_size());
      for (std::size_t j = 0; j < slab_.owned_size(); ++j) piece_[q][j] = (*from[q])[std::size_t(slab_.owned[j])];
    }
    std::vector<NamedField> fields{
        {"displacement", 3, {piece_[0], piece_[1], piece_[2]}},
        {"velocity", 3, {piece_[3], piece_[4], piece_[5]}},
        {"force", 3, {piece_[6], piece_[7], piece_[8]}},
        {"damage", 1, {piece_[9], {}, {}}},
    };
    if (p_.output.vtu_stress) add_stress_fields(fields, owned_stress_, local_.body.dim());
    fields.push_back({"global_id", 1, {ids_, {}, {}}});
    vtu_->write_piece(n, slab_.rank, owned_points_, fields);
    parallel::barrier();  // every piece exists before the .pvtu names it
    if (root_) vtu_->add_pieces(s.time, n, slab_.ranks, fields);
    ++vtu_steps_;
  }

  const Problem& p_;
  Setup& local_;
  Setup* whole_;
  const Slab& slab_;
  bool root_;
  bool lean_;           // rank 0 holds no bond: observers report from gathered per-point fields
  bool fields_;         // u, v, f travel to rank 0 (for PNG, DDS snapshots, users' observers)
  bool png_;            // lean: every rank draws its points into the PNG snapshots (draw_png)
  bool damage_points_;  // damage travels to rank 0, which holds positions: a library user's observers read the whole body
  bool cracks_;         // lean: crack tips or fronts from the cracked points only, gathered
  bool snapshots_;      // lean: DDS snapshots from every stride-th point, gathered
  const Model& model_;
  std::optional<State> state_, all_;
  std::optional<distributed::Transfer> transfer_;
  std::optional<parallel::Halo> halo_;
  std::optional<Solver> solver_;
  std::optional<PvdSeries> vtu_;
  std::size_t broken_at_start_ = 0, first_step_ = 0, broken_ = 0, vtu_steps_ = 0, pngs_ = 0;
  PointSpacing png_spacing_;
  std::optional<TrackedPoints> tracked_;  // lean, with crack tracking or DDS snapshots
  std::filesystem::path dir_, last_png_;
  std::size_t injected_stop_ = SIZE_MAX;
  std::optional<std::size_t> last_checkpoint_;  // the step of this rank's last checkpoint part
  LoadStepReport last_;                         // quasi-static: the last converged increment, the same on every rank
  long iterations_ = 0;
  std::filesystem::path load_steps_;
  double work_ = 0;
  PointCloud owned_points_;
  std::vector<double> phi_, ids_, energy_, all_phi_, magnitude_;
  std::array<std::vector<double>, 10> piece_;
  StressField owned_stress_;  // lean ranks, on steps that draw or write the stress
  std::vector<double> von_mises_;
};

}  // namespace peridot
