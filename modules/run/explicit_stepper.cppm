export module peridot.run:explicit_stepper;
import peridot.std;
import peridot.problem;
import peridot.analysis;
import peridot.observe;
import :loop;
import :checkpointing;

export namespace peridot {

// The set-up lines of an explicit run, for the report.
// counts: the whole body's, where `s` holds no bond (rank 0 of some N-rank runs).
struct BodyCounts {
  std::size_t points = 0, directed_bonds = 0;
};
template <class Model>
std::vector<std::string> describe_explicit(const Problem& p, const Setup& s, const Model& model, const BodyCounts* counts = nullptr);

// An explicit run on one rank: one velocity-Verlet or central-difference step per advance.
// Offers fields, energies, damage (a model's own, or broken bonds), the stress where the model
// has pair forces, and checkpoints.
template <ForceModel Model>
class ExplicitStepper {
 public:
  // restart: a checkpoint read_restart accepted for this set-up; the run continues from it.
  ExplicitStepper(const Problem& p, Setup& s, const Model& model, std::optional<Checkpoint> restart)
      : p_(p), s_(s), state_(s.body.size()), solver_(prepared(s, model, restart, state_, counters_), model, s.boundaries, s.time_step, p.solver.scheme) {
    if (state_.step > 0) solver_.restore(state_, counters_);
    else solver_.initialize(state_);
  }
  bool done() const { return state_.step >= s_.time_step.steps; }
  void advance() { solver_.step(state_); }
  std::size_t step() const { return state_.step; }
  std::size_t steps() const { return s_.time_step.steps; }
  double time() const { return state_.time; }
  std::size_t broken() const { return solver_.broken_bonds(); }
  Report report(bool) {
    return {&state_, solver_.external_work(), solver_.broken_bonds(), [this] { return solver_.model().strain_energy(s_.body, state_.u); }};
  }
  void checkpoint(const std::filesystem::path& file) const {
    write_checkpoint(file, make_checkpoint(p_, s_, state_, solver_.external_work(), solver_.broken_bonds()));
  }
  // What observers read: the solver's copy of the model, whose caches follow fracture.
  const Body& body() const { return s_.body; }
  Observers::DamageFunction damage_function() const {
    const Model& m = solver_.model();
    if constexpr (requires(std::vector<double>& d) { m.damage(s_.body, state_.u, d); })
      return [&m, this](const VectorField& u, std::vector<double>& d) { m.damage(s_.body, u, d); };
    else return {};
  }
  Observers::StressFunction stress_function() const {
    if constexpr (PairForceModel<Model>) {
      const Model& m = solver_.model();
      return [&m, this](const VectorField& u, StressField& tau) { tau = stress_field(m, s_.body, u); };
    } else return {};
  }
  std::vector<std::string> describe() const { return describe_explicit(p_, s_, solver_.model()); }

 private:
  // Restores a checkpoint into the body and state before the solver copies the model: a model
  // that caches data of the bond mask (LPS's shape tensors) rebuilds it from the restored mask,
  // as its incremental updates would.
  static Body& prepared(Setup& s, const Model& model, std::optional<Checkpoint>& restart, State& state,
                        typename ExplicitSolver<Model>::Counters& counters) {
    if (restart) {
      // Broken bonds counted from the masks, as on N ranks: the directed bonds broken since the
      // set-up (pre-cracks) whatever the checkpoint's pair count rounded away.
      const std::size_t at_setup = s.body.broken_bonds();
      restore_run(*restart, s.body, state);
      counters = {restart->external_work, s.body.broken_bonds() - at_setup};
      restart.reset();
      if constexpr (requires { model.prepare(s.body); }) model.prepare(s.body);
    }
    return s.body;
  }

  const Problem& p_;
  Setup& s_;
  State state_;
  typename ExplicitSolver<Model>::Counters counters_{};
  ExplicitSolver<Model> solver_;
};

// ---- set-up lines ----

inline std::string model_line(const Pmb& pmb) { return fmt::format("  PMB: c = {:.6g}, s0 = {:.6g}", pmb.c, pmb.s0); }
inline std::string model_line(const Osb& m) {
  return fmt::format("  OSB: c_theta = {:.6g}, k_theta = {:.6g} Pa, k_e = {:.6g} Pa{}", m.c_theta, m.k_theta, m.k_e,
                     m.critical_stretch > 0 ? fmt::format(", bonds break at s_c = {:.4e}", m.critical_stretch) : "");
}
inline std::string model_line(const Rnp& m) {
  return fmt::format("  RNP: C = {:.6g}, beta = {:.6g}, r_c = {:.6g}, small-strain micromodulus {:.6g}{}", m.C, m.beta, m.critical_r(),
                     m.micromodulus(), m.break_factor > 0 ? fmt::format(", bonds break at {:g} r_c", m.break_factor) : "");
}

// The header of a dynamic LPS run (explicit or Newmark).
inline std::vector<std::string> describe_lps(const Problem& p, const Body& body, const Lps& model, const BodyCounts* counts = nullptr) {
  const std::size_t points = counts ? counts->points : body.size(), directed = counts ? counts->directed_bonds : body.bonds.size();
  return {fmt::format("peridot: {} ({}D, {}, dynamic LPS)", p.name, p.dim, to_string(p.material.kinematics)),
          fmt::format("  points {}  bonds {} (directed {})  h = {:.4g} m  delta = {:.4g} m  weights: {}", points, directed / 2,
                      directed, p.lattice.spacing, p.horizon, "discretization.quadrature = " + seam_names(Seam::quadrature)[std::size_t(p.quadrature_kind)]),
          fmt::format("  LPS: lambda = {:.6g} Pa, mu = {:.6g} Pa{}; {} traction load(s)", model.lambda.empty() ? 0.0 : model.lambda[0],
                      model.mu.empty() ? 0.0 : model.mu[0], model.s0 > 0 ? fmt::format(", bonds break at s0 = {:.4e}", model.s0) : ", no fracture",
                      model.tractions.size())};
}

template <class Model>
std::vector<std::string> describe_explicit(const Problem& p, const Setup& s, const Model& model, const BodyCounts* counts) {
  std::vector<std::string> lines;
  if constexpr (std::is_same_v<Model, Lps>) {
    lines = describe_lps(p, s.body, model, counts);
    lines.push_back(fmt::format("  velocity Verlet: stable time step estimate {:.4e} s (power iteration); using dt = {:.4e} s for {} steps to t = {:.4e} s",
                                s.time_step.estimate, s.time_step.dt, s.time_step.steps, p.solver.end_time));
  } else {
    lines.push_back(fmt::format("peridot: {} ({}D, {})", p.name, p.dim, to_string(p.material.kinematics)));
    const std::size_t d = counts ? counts->directed_bonds : s.body.directed_bonds();
    lines.push_back(fmt::format("  points {}  bonds {} (directed {}, on a {})  h = {:.4g} m  delta = {:.4g} m", counts ? counts->points : s.body.size(), d / 2, d,
                                s.body.layout_name(), p.lattice.spacing, p.horizon));
    lines.push_back(model_line(model));
    lines.push_back(fmt::format("  stable time step estimate {:.4e} s; using dt = {:.4e} s for {} steps to t = {:.4e} s", s.time_step.estimate,
                                s.time_step.dt, s.time_step.steps, p.solver.end_time));
  }
  return lines;
}

}  // namespace peridot
