export module peridot.run:static_steppers;
import peridot.std;
import peridot.problem;
import peridot.analysis;
import peridot.observe;
import peridot.render;
import peridot.quadrature;
import :loop;
import :parts;

export namespace peridot {

// A static state as observers read it: u solved, v = 0, f = 0, one step at "time" 1.
inline void take_static(State& s, const VectorField& u) {
  for (int k = 0; k < 3; ++k)
    if (u[std::size_t(k)].size() == s.u[std::size_t(k)].size()) s.u[std::size_t(k)] = u[std::size_t(k)];
  s.step = 1;
  s.time = 1;
}

// Static LPS (seed 000 Sec. 5): one linear solve on UMFPACK or PETSc. Offers u, the strain
// energy, the errors against the deck's reference solution, and a VTU with the reference fields.
// On N ranks (setup_static_part) each rank holds its part, assembles its owned interior rows and
// gets their solution back; the ghosts take their owners' values through the halo. The errors
// and the strain energy are exact sums over the owned points, each rank writes its owned points
// as a VTU piece and rank 0 the .pvtu, and every rank draws its owned points into rank 0's PNGs
// (the one-process image); rank 0's observers hold no point (the history row comes reduced)
// unless a library user observes (then rank 0 gathers the positions once and u and the damage
// per report).
class StaticLpsStepper {
 public:
  // snapshot_points: LiveOptions::snapshot_max_points, the most points a DDS snapshot sends;
  // users_read_fields: a library user's observers read the body and u (Sample), so on N ranks
  // rank 0 gathers them.
  StaticLpsStepper(const Problem& p, StaticSetup& s, double setup_seconds, std::size_t snapshot_points, bool users_read_fields = false)
      : p_(p), s_(s), setup_seconds_(setup_seconds), state_(s.body.size()), users_(users_read_fields) {
    if (!s.slab) return;
    const auto& slab = *s.slab;
    halo_.emplace(parallel::or_abort("halo set-up", [&] {
      return parallel::Halo(slab.local_size(), slab.ghost, slab.ghost_owner, slab.ghost_owner_index);
    }));
    tracked_.emplace(p.output, s.body.points, slab.owned, slab.local_ids, slab.global_size, snapshot_points);
    observed_.emplace(users_ && slab.rank == 0 ? slab.global_size : 0);
    if (users_) whole_points_on_root(s.body.points, slab.owned, slab.local_ids, observers_body_.points);
    observers_body_.points.dim = p.dim;
    observers_body_.density = p.material.density;
  }
  bool done() const { return solved_; }
  void advance() {
    // The assembly and the solve are collective on N ranks: a rank that fails ends them all.
    result_ = parallel::or_abort("static solve", [&] {
      return solve_static_lps(s_.body, s_.model, s_.problem, s_.options, s_.parts ? &*s_.parts : nullptr);
    });
    if (halo_) parallel::or_abort("static solution halo", [&] {
      const std::array<double*, 4> a{result_.u[0].data(), result_.u[1].data(), result_.u[2].data(), result_.theta.data()};
      halo_->exchange(a);
      // The owned points' energies read their partners' displacements, ghosts included.
      std::vector<double> e;
      s_.model.point_energies(s_.body, result_.u, e);
      ExactSum strain;
      for (auto j : s_.slab->owned) strain += e[std::size_t(j)];
      exact_sums_over_ranks({&strain});
      strain_ = strain.value();
      if (p_.output.vtu_every) write_pieces();
    });
    errors_ = static_errors(s_, result_);
    take_static(state_, result_.u);
    if (observed_) observed_->step = state_.step, observed_->time = state_.time;
    solved_ = true;
  }
  // N ranks: the directory every rank writes its VTU piece into.
  void open_outputs(const std::filesystem::path& dir) { dir_ = dir; }
  std::size_t step() const { return solved_ ? 1 : 0; }
  std::size_t steps() const { return 1; }
  double time() const { return state_.time; }
  std::size_t broken() const { return 0; }
  std::string abscissa() const { return "linear solve"; }
  Report report(bool last) {
    if (observed_ && detail::due(p_.output.png_every, state_.step, last)) parallel::or_abort("PNG snapshot", [&] { draw_png(); });
    Observers::Totals totals;
    if (observed_) parts_totals(last, totals);
    if (parallel::rank() != 0) return {};
    if (observed_) {
      const double e = strain_;
      return {&*observed_, 0.0, 0, [e] { return e; }, std::move(totals)};
    }
    return {&state_, 0.0, 0, [this] { return s_.model.strain_energy(s_.body, state_.u); }};
  }
  const Body& body() const { return s_.slab ? observers_body_ : s_.body; }
  // N ranks: this rank's part, for part observers (no gather).
  std::optional<PartView> part() const {
    if (!s_.slab) return std::nullopt;
    return PartView{&s_.body, &state_, s_.slab->owned, s_.slab->local_ids, s_.slab->global_size, s_.slab->rank, s_.slab->ranks};
  }
  // N ranks: rank 0's observers' body holds no bond; the damage comes gathered (no point
  // without a user's observers).
  Observers::DamageFunction damage_function() const {
    if (!s_.slab) return {};
    return [this](const VectorField&, std::vector<double>& d) { d = whole_phi_; };
  }
  std::vector<std::string> describe() const {
    const std::size_t points = s_.slab ? s_.slab->global_size : s_.body.size();
    std::vector<std::string> lines{
        fmt::format("peridot: {} (static LPS, {} points, h = {:.4g} m, delta = {:.4g} m)", p_.name, points, p_.lattice.spacing, p_.horizon),
        fmt::format("  {}", peridot::summary(s_.quadrature))};
    if (s_.slab)
      lines.push_back(fmt::format("  MPI: {} ranks, {}; each rank built bonds and weights of its own "
                                  "neighbourhood only ({} of {} points on rank 0) and assembles its own rows{}",
                                  s_.slab->ranks, cut_name(*s_.slab), s_.slab->local_size(), s_.slab->global_size, tracked_->snapshot_note()));
    return lines;
  }
  std::vector<std::string> summary() const {
    const auto& r = result_;
    std::vector<std::string> lines{fmt::format(
        "  unknowns {}  nonzeros {}  setup {:.3f} s (weights {:.3f} s)  assembly {:.3f} s  solve {:.3f} s  residual {:.2e}", r.unknowns, r.nonzeros,
        setup_seconds_, s_.quadrature.seconds, r.assembly_seconds, r.solve_seconds, r.residual)};
    if (s_.options.solver == LinearSolver::petsc) {
      const auto& k = r.petsc;
      // The solve time above includes the set-up: a factorisation, or BoomerAMG's hierarchy.
      lines.push_back(fmt::format("  PETSc on {} rank{}: {} / {}{}{}, set-up {:.3f} s, {} iteration{} {:.3f} s", k.ranks, k.ranks == 1 ? "" : "s", k.ksp,
                                  k.pc, k.factor_package.empty() ? "" : " / ", k.factor_package, k.setup_seconds, k.iterations,
                                  k.iterations == 1 ? "" : "s", k.solve_seconds));
    }
    lines.push_back(fmt::format("  L2 error vs {}: u {:.6e} (relative {:.3e}), theta {:.6e} (relative {:.3e})", s_.reference.name, errors_.u,
                                errors_.u_relative, errors_.theta, errors_.theta_relative));
    return lines;
  }
  std::vector<std::string> warnings() const {
    std::vector<std::string> w;
    for (const auto& name : result_.petsc.unused_options) w.push_back(fmt::format("PETSc option {} was never read (misspelt?)", name));
    if (!result_.petsc.fallback.empty()) w.push_back(fmt::format("PETSc: {}; solved again by LU", result_.petsc.fallback));
    return w;
  }
  // The one VTU of a static solve, with the reference solution beside the computed one; PNGs
  // are the observers' on one process, drawn here in parts on N ranks.
  bool writes_vtu() const { return true; }
  bool writes_png() const { return s_.slab && p_.output.png_every; }
  std::vector<std::string> final_outputs(const std::filesystem::path& dir) const {
    if (!p_.output.vtu_every || !solved_) return {};
    if (s_.slab) return {fmt::format("  output: {} (one piece per rank)", (dir / (p_.name + ".pvtu")).string())};
    std::vector<std::int64_t> all(s_.body.size());
    std::iota(all.begin(), all.end(), std::int64_t{0});
    const Fields values = fields_of(all);  // the named fields point into it
    const auto fields = values.named();
    std::filesystem::create_directories(dir);
    write_vtu(dir / (p_.name + ".vtu"), s_.body.points, fields);
    return {fmt::format("  output: {}", (dir / (p_.name + ".vtu")).string())};
  }
  const StaticResult& result() const { return result_; }

 private:
  // The fields of the points `ids` (local indices): the solution beside the reference.
  struct Fields {
    std::array<std::vector<double>, 9> v;  // u (3), theta, reference u (3), reference theta, role
    std::vector<NamedField> named() const {
      return {{"displacement", 3, {v[0], v[1], v[2]}},
              {"dilatation", 1, {v[3], {}, {}}},
              {"reference_displacement", 3, {v[4], v[5], v[6]}},
              {"reference_dilatation", 1, {v[7], {}, {}}},
              {"role", 1, {v[8], {}, {}}}};
    }
  };
  Fields fields_of(std::span<const std::int64_t> ids) const {
    const auto& pc = s_.body.points;
    Fields f;
    for (auto& a : f.v) a.resize(ids.size());
    for (std::size_t k = 0; k < ids.size(); ++k) {
      const auto i = std::size_t(ids[k]);
      const auto u0 = s_.reference.displacement(pc.position(i));
      for (std::size_t c = 0; c < 3; ++c) f.v[c][k] = result_.u[c][i], f.v[4 + c][k] = u0[c];
      f.v[3][k] = result_.theta[i];
      f.v[7][k] = pc.role[i] == Role::ghost ? 0.0 : s_.reference.dilatation(pc.position(i));
      f.v[8][k] = double(static_cast<int>(pc.role[i]));
    }
    return f;
  }
  // N ranks: every rank draws its owned points (damage, |u| or |v| = 0, as the observers
  // would), at the square size the one-process image estimates. Collective.
  void draw_png() {
    const auto& o = p_.output;
    const auto& slab = *s_.slab;
    const auto& pc = s_.body.points;
    if (!png_spacing_) png_spacing_ = spacing_of_parts(pc, slab.owned, slab.local_ids, slab.global_size);
    std::array<std::vector<double>, 3> x, u, v;
    std::vector<double> values, phi;
    for (auto j : slab.owned)
      for (std::size_t k = 0; k < 3; ++k) {
        x[k].push_back(pc.x[k].empty() ? 0.0 : pc.x[k][std::size_t(j)]);
        u[k].push_back(result_.u[k].empty() ? 0.0 : result_.u[k][std::size_t(j)]);
        v[k].push_back(0.0);
      }
    std::string label = "damage";
    if (o.png_field == "damage") {
      damage(s_.body, phi);
      for (auto j : slab.owned) values.push_back(phi[std::size_t(j)]);
    } else {
      label = png_magnitudes(o.png_field, {u[0], u[1], u[2]}, {v[0], v[1], v[2]}, values);
    }
    RenderField rf;
    rf.dim = pc.dim;
    rf.x = {x[0], x[1], pc.dim == 3 ? std::span<const double>(x[2]) : std::span<const double>()};
    rf.u = {u[0], u[1], pc.dim == 3 ? std::span<const double>(u[2]) : std::span<const double>()};
    rf.values = values;
    rf.field_name = label;
    rf.time = state_.time;
    rf.time_label = abscissa();
    rf.step = state_.step;
    rf.spacing = png_spacing_->spacing;
    RenderOptions ro = png_options(o);
    ro.point_size = png_spacing_->solid_size;
    render_png(dir_ / fmt::format("{}_{:07d}.png", p_.name, state_.step), rf, ro, mpi_render_parts());
  }
  // N ranks: what rank 0's observers take from the whole body on one process, from the parts:
  // the damage fraction (exact sums over the owned points) and the DDS snapshot's points,
  // gathered. Collective.
  void parts_totals(bool last, Observers::Totals& totals) {
    const auto& owned = s_.slab->owned;
    std::vector<double> phi;
    damage(s_.body, phi);
    if (users_) whole_state_on_root(state_.u, phi, owned, s_.slab->local_ids, observed_->u, whole_phi_);
    auto damaged = damage_fraction_sums(s_.body, phi, owned);
    exact_sums_over_ranks({&damaged[0], &damaged[1]});
    totals.damage_fraction = damage_fraction_of(damaged);
    tracked_->gather(state_.step, last, state_.u, phi, totals);
  }
  // N ranks: this rank's owned points as a piece, then rank 0's .pvtu once every piece exists.
  void write_pieces() const {
    const auto& slab = *s_.slab;
    const Fields f = fields_of(slab.owned);  // the named fields point into it
    auto named = f.named();
    std::vector<double> ids(slab.owned.size());
    for (std::size_t k = 0; k < ids.size(); ++k) ids[k] = double(slab.local_ids[std::size_t(slab.owned[k])]);
    named.push_back({"global_id", 1, {ids, {}, {}}});
    write_vtu(dir_ / fmt::format("{}_{}.vtu", p_.name, slab.rank), subset(s_.body.points, slab.owned), named);
    parallel::barrier();
    if (slab.rank != 0) return;
    std::vector<std::string> pieces;
    for (int r = 0; r < slab.ranks; ++r) pieces.push_back(fmt::format("{}_{}.vtu", p_.name, r));
    write_pvtu(dir_ / (p_.name + ".pvtu"), pieces, named);
  }

  const Problem& p_;
  StaticSetup& s_;
  double setup_seconds_;
  State state_;
  StaticResult result_;
  StaticErrors errors_;
  bool solved_ = false;
  // N ranks: the halo, rank 0's observers' view (no point unless a library user observes),
  // the reduced strain energy, the points DDS snapshots read.
  std::optional<parallel::Halo> halo_;
  std::optional<TrackedPoints> tracked_;
  // N ranks, for a library user's observers: the whole body's u and damage on rank 0.
  bool users_;
  std::vector<double> whole_phi_;
  std::optional<State> observed_;
  Body observers_body_;
  double strain_ = 0;
  std::filesystem::path dir_;
  std::optional<PointSpacing> png_spacing_;
};

// Static OSB (seed 004): one linear solve with fictitious Taylor nodes or conditions on the
// outermost nodes, or a sequentially linear fracture run, one re-solve per advance (each removes
// the most stretched bonds). The record's "time" is the solve count, so the history has a row per
// re-solve. Offers u, damage, the strain energy, the stress (51) and a VTU and PNG of the result.
// On N ranks (setup_osb_static_part) every rank holds its part and assembles its rows; the
// strain energy and damage fraction are exact sums over the owned points, the errors extremes
// over them, fragments are joined from the ranks' shares; each rank writes its owned points as a
// VTU piece and draws them into rank 0's PNG, and rank 0's observers hold no point (unless a
// library user observes, as for static LPS).
class OsbStaticStepper {
 public:
  // snapshot_points and users_read_fields: as for StaticLpsStepper.
  OsbStaticStepper(const Problem& p, OsbStaticSetup& s, std::size_t snapshot_points, bool users_read_fields = false)
      : p_(p), s_(s), solver_(s.body, s.model, s.problem, s.options, s.parts ? &*s.parts : nullptr), state_(s.body.size()), users_(users_read_fields) {
    if (!s.parts) return;
    observed_.emplace(users_ && s.parts->rank == 0 ? s.global_points : 0);
    observers_body_.points.dim = 2;
    observers_body_.density = s.body.density;
    const auto& parts = *s.parts;
    for (std::size_t i = 0; i < s.body.size(); ++i) {
      owned_flag_.push_back(parts.owns(i) ? 1 : 0);
      if (parts.owns(i)) owned_.push_back(std::int64_t(i));
    }
    tracked_.emplace(p.output, s.body.points, owned_, parts.global_id, s.global_points, snapshot_points);
    if (users_) whole_points_on_root(s.body.points, owned_, parts.global_id, observers_body_.points);
  }
  bool done() const { return solver_.done(); }
  void advance() {
    solver_.advance();
    take_static(state_, solver_.result().u);
    state_.step = solver_.result().solves;
    state_.time = double(state_.step);
    if (observed_) observed_->step = state_.step, observed_->time = state_.time;
  }
  // N ranks: the directory every rank writes its VTU piece into.
  void open_outputs(const std::filesystem::path& dir) { dir_ = dir; }
  std::size_t step() const { return solver_.result().solves; }
  // A fracture run ends when no bond is over s_c, long before max_solves as a rule.
  std::size_t steps() const { return fracture() ? s_.options.max_solves : 1; }
  bool open_ended() const { return fracture(); }
  double time() const { return state_.time; }
  std::size_t broken() const { return solver_.result().broken; }
  std::string abscissa() const { return "linear solve"; }
  Report report(bool last) {
    if (!s_.parts) return {&state_, 0.0, solver_.result().broken, [this] { return s_.model.strain_energy(s_.body, state_.u); }};
    // Collective: every rank reports on the same steps.
    const auto& owned = owned_;
    std::vector<double> e, phi;
    s_.model.point_energies(s_.body, state_.u, e);
    damage(s_.body, phi);
    if (users_) whole_state_on_root(state_.u, phi, owned, s_.parts->global_id, observed_->u, whole_phi_);
    ExactSum strain;
    for (auto j : owned) strain += e[std::size_t(j)];
    auto damaged = damage_fraction_sums(s_.body, phi, owned);
    exact_sums_over_ranks({&strain, &damaged[0], &damaged[1]});
    if (last && step() > 0) {
      if (p_.statics.osb.affine_reference) errors_ = osb_errors(p_, s_, solver_.result());
      double lam = 0;
      for (double l : solver_.result().multipliers) lam = std::max(lam, std::abs(l));
      largest_multiplier_ = -parallel::min_over_ranks(-lam);
      parallel::or_abort("static OSB output", [&] { write_outputs(dir_, owned_, phi); });
    }
    Observers::Totals totals{0.0, damage_fraction_of(damaged), std::nullopt};
    if (detail::due(p_.output.fragments_every, step(), last))
      totals.fragments = joined_fragments(s_.body, owned_flag_, *solver_.halo(), {.large_mass_fraction = p_.output.large_fragment_fraction});
    tracked_->gather(step(), last, state_.u, phi, totals);
    if (parallel::rank() != 0) return {};
    const double energy = strain.value();
    return {&*observed_, 0.0, solver_.result().broken, [energy] { return energy; }, std::move(totals)};
  }
  const Body& body() const { return s_.parts ? observers_body_ : s_.body; }
  // N ranks: this rank's part, for part observers (no gather).
  std::optional<PartView> part() const {
    if (!s_.parts) return std::nullopt;
    return PartView{&s_.body, &state_, owned_, s_.parts->global_id, s_.global_points, s_.parts->rank, s_.parts->ranks};
  }
  // N ranks: as StaticLpsStepper's.
  Observers::DamageFunction damage_function() const {
    if (!s_.parts) return {};
    return [this](const VectorField&, std::vector<double>& d) { d = whole_phi_; };
  }
  std::vector<std::string> describe() const {
    const auto& r = solver_.result();
    std::vector<std::string> lines{fmt::format("peridot: {} (static OSB, {}{}, {} real points, {} fictitious, h = {:.4g} m, delta = {:.4g} m = {:g} h)",
                                               p_.name, method(), s_.problem.corrected ? fmt::format(" of order {}", s_.problem.taylor_order) : std::string(),
                                               r.real_points, s_.global_points - r.real_points, p_.lattice.spacing, p_.horizon,
                                               p_.horizon / p_.lattice.spacing)};
    if (s_.options.critical_stretch > 0)
      lines.push_back(fmt::format("  fracture: s_c = {:.4e}, {} most stretched bonds removed per re-solve", s_.options.critical_stretch,
                                  s_.options.bonds_per_solve));
    if (s_.parts)
      lines.push_back(fmt::format("  MPI: {} ranks, bricks of the grown rectangle; each rank built the bonds of its own neighbourhood only ({} of {} "
                                  "points on rank 0) and assembles its own rows{}",
                                  s_.parts->ranks, s_.body.size(), s_.global_points, tracked_->snapshot_note()));
    return lines;
  }
  std::vector<std::string> summary() const {
    const auto& r = solver_.result();
    std::vector<std::string> lines{fmt::format(
        "  unknowns {} (u, v, theta) + {} condition rows  nonzeros {}  assembly {:.3f} s  factorisation and solve {:.3f} s{}  residual {:.2e}",
        3 * r.real_points, r.constraints, r.nonzeros, r.assembly_seconds, r.factor_seconds,
        r.band > 0 ? fmt::format(" (banded LU, half-bandwidth {})", r.band) : std::string(), r.residual)};
    double lam = largest_multiplier_;
    if (!s_.parts)
      for (double l : r.multipliers) lam = std::max(lam, std::abs(l));
    if (r.constraints > 0) lines.push_back(fmt::format("  largest |Lagrange multiplier| {:.3e} N/m^3", lam));
    if (s_.options.critical_stretch > 0)
      lines.push_back(fmt::format("  fracture: {} solves, {} bonds removed{}", r.solves, r.broken,
                                  r.stopped_singular ? ", stopped: equilibrium is no longer possible (singular system)" : ""));
    if (p_.statics.osb.affine_reference) {
      const auto e = s_.parts ? errors_ : osb_errors(p_, s_, r);
      lines.push_back(fmt::format("  relative error (66) over the real points: u {:.4f} .. {:.4f} %, v {:.4f} .. {:.4f} %", e.rel_u_min, e.rel_u_max,
                                  e.rel_v_min, e.rel_v_max));
      lines.push_back(fmt::format("  error (64), |u - u_ref| / max |u_ref|: u {:.4f} %, v {:.4f} %;  max |u| {:.6e} m, max |v| {:.6e} m", e.abs_u_max,
                                  e.abs_v_max, e.max_u, e.max_v));
    }
    return lines;
  }
  // The VTU (with the stress (51) and the role of each point) and a PNG of the real points.
  bool writes_vtu() const { return true; }
  bool writes_png() const { return true; }
  std::vector<std::string> final_outputs(const std::filesystem::path& dir) const;
  const OsbStaticResult& result() const { return solver_.result(); }

 private:
  bool fracture() const { return s_.options.critical_stretch > 0; }
  const char* method() const { return s_.problem.corrected ? "fictitious Taylor nodes" : "uncorrected, conditions on the outermost nodes"; }
  // Every local point's fields for the VTU and PNG, from the last solve.
  struct Fields {
    std::vector<double> role, phi, ref_u, ref_v, von;
    StressField tau;
  };
  Fields fields(const std::vector<double>& phi) const;
  // The VTU and PNG of the last solve from the local points `ids`: every point on one process;
  // on a part the owned ones, as a VTU piece beside rank 0's .pvtu and drawn into rank 0's PNG
  // (collective).
  void write_outputs(const std::filesystem::path& dir, const std::vector<std::int64_t>& ids, const std::vector<double>& phi) const;

  const Problem& p_;
  OsbStaticSetup& s_;
  OsbStaticSolver solver_;
  State state_;
  // N ranks: rank 0's observers' view (no point), the owned points, figures reduced at the end.
  std::optional<State> observed_;
  Body observers_body_;
  std::vector<std::int64_t> owned_;       // local indices
  std::vector<std::uint8_t> owned_flag_;  // per local point
  std::optional<TrackedPoints> tracked_;  // the points the trackers and DDS read
  bool users_;                            // a library user's observers: the whole u and damage on rank 0
  std::vector<double> whole_phi_;
  OsbErrors errors_;
  double largest_multiplier_ = 0;
  std::filesystem::path dir_;
};

}  // namespace peridot

namespace peridot {

OsbStaticStepper::Fields OsbStaticStepper::fields(const std::vector<double>& phi) const {
  const auto& pc = s_.body.points;
  const std::size_t n = pc.size();
  Fields f;
  f.role.resize(n), f.ref_u.resize(n), f.ref_v.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    f.role[i] = double(static_cast<int>(pc.role[i]));
    const auto u0 = osb_reference(p_, pc.position(i));
    f.ref_u[i] = u0[0], f.ref_v[i] = u0[1];
  }
  f.phi = phi;
  // Seed 004 Sec. 4.3: eq. (51) on the grid, from the bond forces of the solve (fictitious
  // points carry their extrapolated displacement and dilatation). On a part, right on the owned
  // points: every bond across their segments is held, from a whole row.
  f.tau = lattice_stress(lattice_grid(pc), s_.body, solver_.result().pair_force);
  von_mises(f.tau, f.von);
  return f;
}

namespace {

// The PNG's colour value of point i.
double png_value(const std::string& field, const OsbStaticResult& r, const std::vector<double>& phi, const StressField& tau, const std::vector<double>& von,
                 std::size_t i) {
  return field == "damage"      ? phi[i]
         : field == "stress_xx" ? tau.xx[i]
         : field == "stress_yy" ? tau.yy[i]
         : field == "stress_xy" ? tau.xy[i]
         : field == "von_mises" ? von[i]
                                : std::hypot(r.u[0][i], r.u[1][i]);
}

std::string png_label(const std::string& field) { return field == "damage" ? "damage" : field == "displacement" ? "|displacement| [m]" : field + " [Pa]"; }

}  // namespace

std::vector<std::string> OsbStaticStepper::final_outputs(const std::filesystem::path& dir) const {
  const auto& p = p_;
  std::vector<std::string> lines;
  if (solver_.result().solves == 0 || (!p.output.vtu_every && !p.output.png_every)) return lines;
  const auto vtu = dir / (p.name + (s_.parts ? ".pvtu" : ".vtu")), png = dir / (p.name + ".png");
  if (!s_.parts) {
    std::filesystem::create_directories(dir);
    std::vector<double> phi;
    damage(s_.body, phi);
    std::vector<std::int64_t> all(s_.body.size());
    std::iota(all.begin(), all.end(), std::int64_t{0});
    write_outputs(dir, all, phi);
  }
  if (p.output.vtu_every) lines.push_back(fmt::format("  output: {}{}", vtu.string(), s_.parts ? " (one piece per rank)" : ""));
  if (p.output.png_every) lines.push_back(fmt::format("  output: {}", png.string()));
  return lines;
}

void OsbStaticStepper::write_outputs(const std::filesystem::path& dir, const std::vector<std::int64_t>& ids, const std::vector<double>& phi) const {
  const auto& p = p_;
  const auto& r = solver_.result();
  const auto& pc = s_.body.points;
  if (!p.output.vtu_every && !p.output.png_every) return;
  const Fields f = fields(phi);
  const auto pick = [&](const std::vector<double>& all, const auto& keep) {
    std::vector<double> v;
    for (auto j : ids)
      if (keep(std::size_t(j))) v.push_back(all[std::size_t(j)]);
    return v;
  };
  const auto any = [](std::size_t) { return true; };
  if (p.output.vtu_every) {
    const auto ux = pick(r.u[0], any), uy = pick(r.u[1], any), th = pick(r.theta, any), ph = pick(f.phi, any), xx = pick(f.tau.xx, any),
               yy = pick(f.tau.yy, any), xy = pick(f.tau.xy, any), role = pick(f.role, any), ru = pick(f.ref_u, any), rv = pick(f.ref_v, any);
    std::vector<NamedField> named{
        {"displacement", 3, {ux, uy, {}}}, {"dilatation", 1, {th, {}, {}}}, {"damage", 1, {ph, {}, {}}},      {"stress_xx", 1, {xx, {}, {}}},
        {"stress_yy", 1, {yy, {}, {}}},    {"stress_xy", 1, {xy, {}, {}}},  {"role", 1, {role, {}, {}}},
    };
    if (p.statics.osb.affine_reference) named.push_back({"reference_displacement", 3, {ru, rv, {}}});
    if (!s_.parts) {
      write_vtu(dir / (p.name + ".vtu"), pc, named);
    } else {
      std::vector<double> global_ids;
      for (auto j : ids) global_ids.push_back(double(s_.parts->global_id[std::size_t(j)]));
      named.push_back({"global_id", 1, {global_ids, {}, {}}});
      write_vtu(dir / fmt::format("{}_{}.vtu", p.name, s_.parts->rank), subset(pc, ids), named);
      parallel::barrier();  // every piece exists before the .pvtu names it
      if (s_.parts->rank == 0) {
        std::vector<std::string> pieces;
        for (int k = 0; k < s_.parts->ranks; ++k) pieces.push_back(fmt::format("{}_{}.vtu", p.name, k));
        write_pvtu(dir / (p.name + ".pvtu"), pieces, named);
      }
    }
  }
  if (p.output.png_every) {
    // Real points only (the fictitious layer is not part of the body); on N ranks each its owned
    // ones, into the image one process draws of the whole body.
    const auto real = [&](std::size_t i) { return pc.role[i] == Role::interior; };
    const auto x = pick(pc.x[0], real), y = pick(pc.x[1], real), ux = pick(r.u[0], real), uy = pick(r.u[1], real);
    std::vector<double> values;
    for (auto j : ids)
      if (real(std::size_t(j))) values.push_back(png_value(p.output.png_field, r, f.phi, f.tau, f.von, std::size_t(j)));
    RenderField rf;
    rf.dim = 2;
    rf.x = {x, y, {}};
    rf.u = {ux, uy, {}};
    rf.values = values;
    rf.field_name = png_label(p.output.png_field);
    rf.spacing = pc.spacing;
    RenderOptions ro = png_options(p.output);
    ro.title = fmt::format("{}  {}  ({})", p.name, rf.field_name, method());
    const auto file = dir / (p.name + ".png");
    if (!s_.parts) {
      render_png(file, rf, ro);
    } else {
      // On a lattice the squares that cover the body without gaps are the spacing's.
      ro.point_size = pc.spacing;
      render_png(file, rf, ro, mpi_render_parts());
    }
  }
}

}  // namespace peridot
