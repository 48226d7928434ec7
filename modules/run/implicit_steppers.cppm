export module peridot.run:implicit_steppers;
import peridot.std;
import peridot.problem;
import peridot.analysis;
import peridot.observe;
import peridot.io;
import :loop;
import :explicit_stepper;

export namespace peridot {

// The header and closing line of a Newmark run, on one rank or N.
inline std::vector<std::string> describe_newmark(const Problem& p, const Body& body, const Lps& model, std::size_t steps,
                                                 const BodyCounts* counts = nullptr) {
  auto lines = describe_lps(p, body, model, counts);
  lines.push_back(fmt::format("  implicit Newmark (beta = 1/4, gamma = 1/2): dt = {:.4e} s for {} steps to t = {:.4e} s; BiCGSTAB tolerance {:g}",
                              p.newmark.dt, steps, p.newmark.end_time, p.newmark.tolerance));
  return lines;
}
inline std::string newmark_work(const NewmarkTotals& t) {
  return fmt::format("  BiCGSTAB: {:.2f} iterations per step (most {}), {} re-solves after breaks",
                     double(t.iterations) / double(std::max<std::size_t>(t.steps, 1)), t.most, t.sub_iterations);
}

// Implicit Newmark (dynamic LPS fracture, seed 000 Sec. 6): one matrix-free solve per step plus
// a re-solve per round of new breaks. Offers fields, energies, damage and the solver's work.
class NewmarkStepper {
 public:
  NewmarkStepper(const Problem& p, NewmarkSetup& s) : p_(p), s_(s), solver_(s.body, s.model, s.boundaries, s.options), state_(s.body.size()) {
    solver_.initialize(state_);
  }
  bool done() const { return state_.step >= solver_.steps(); }
  void advance() { solver_.step(state_); }
  std::size_t step() const { return state_.step; }
  std::size_t steps() const { return solver_.steps(); }
  double time() const { return state_.time; }
  std::size_t broken() const { return solver_.broken_bonds(); }
  Report report(bool) { return {&state_, 0.0, solver_.broken_bonds(), [this] { return solver_.model().strain_energy(s_.body, state_.u); }}; }
  std::pair<long, long> solver_work() const { return {solver_.last().iterations, solver_.last().sub_iterations}; }
  const Body& body() const { return s_.body; }
  std::vector<std::string> describe() const { return describe_newmark(p_, s_.body, s_.model, solver_.steps()); }
  std::vector<std::string> summary() const { return {newmark_work(solver_.totals())}; }

 private:
  const Problem& p_;
  NewmarkSetup& s_;
  NewmarkSolver<Lps> solver_;
  State state_;
};

// The load-step CSV of a quasi-static run: a row per converged increment with the nonlinear
// solve's own figures (iterations, residuals, cuts, the linear solver, the condition number).
// An observer of the stepper's last report, due on every step. The file opens at the first
// observation, so the observer can be made on every rank and writes only where observers run.
// Whole rows only: a row a full disk cuts short is removed and the run fails.
class LoadStepCsv {
 public:
  LoadStepCsv(std::filesystem::path file, const LoadStepReport* last) : file_(std::move(file)), last_(last) {}
  void observe(const Sample& s) {
    if (!csv_) {
      csv_ = std::make_unique<RecordFile>(file_);
      csv_->append("step,load_factor,iterations,residual_0,residual,reference_force,max_damage,softening_bonds,cuts,linear_solver,seconds,"
                      "condition_number\n");
    }
    if (s.state.step == 0) return;  // the start: nothing solved yet
    const auto& r = *last_;
    csv_->append(fmt::format("{},{:.9e},{},{:.6e},{:.6e},{:.6e},{:.9e},{},{},{},{:.4f},{:.6e}\n", r.step, r.load, r.iterations, r.residual0,
                             r.residual, r.reference, r.max_damage, r.softening_bonds, r.cuts, r.linear_solver, r.seconds, r.condition));
  }

 private:
  std::filesystem::path file_;
  const LoadStepReport* last_;
  std::unique_ptr<RecordFile> csv_;
};

// How a quasi-static run goes to its full load, for its header and `peridot check`.
inline std::string load_path_text(const QuasiStaticOptions& o) {
  return o.control == QsControl::arc_length ? fmt::format("arc length, the first arc 1/{} of the load along the tangent", o.steps)
                                            : fmt::format("{} load steps", o.steps);
}

// The header of a quasi-static run, its line per converged increment and its closing lines, on
// one rank or N (`counts`: the whole body's points and directed bonds, where `body` is a part).
inline std::vector<std::string> describe_quasi_static(const Problem& p, const Body& body, const Rnp& m, const BodyCounts* counts = nullptr) {
  const std::size_t points = counts ? counts->points : body.size(), directed = counts ? counts->directed_bonds : body.bonds.size();
  const auto& o = p.quasi_static.options;
  return {fmt::format("peridot: {} ({}D quasi-static RNP, {})", p.name, p.dim, o.nonlinear == QsNonlinear::ceres ? "Ceres" : "Newton"),
          fmt::format("  points {}  bonds {} (directed {})  h = {:.4g} m  delta = {:.4g} m", points, directed / 2, directed, p.lattice.spacing,
                      p.horizon),
          fmt::format("  RNP: C = {:.6g}, beta = {:.6g}, r_c = {:.6g}, small-strain micromodulus {:.6g}; {}", m.C, m.beta, m.critical_r(),
                      m.micromodulus(), load_path_text(o))};
}
inline std::string quasi_static_step_line(const LoadStepReport& r) {
  return fmt::format("  step {:>4}  load {:.6f}  iterations {:>2} ({})  |R| {:.2e} -> {:.2e}  max damage {:.4f}  softening bonds {}{}", r.step, r.load,
                     r.iterations, r.linear_solver, r.residual0, r.residual, r.max_damage, r.softening_bonds,
                     r.cuts ? fmt::format("  ({} cuts)", r.cuts) : "");
}
inline std::vector<std::string> quasi_static_summary(std::size_t steps, long iterations, const std::filesystem::path& file) {
  return {fmt::format("  nonlinear: {} load steps, {} iterations", steps, iterations), fmt::format("  output: {}", file.string())};
}

// Quasi-static load control (seed 002): one converged load increment per advance, with Newton
// (or Ceres). The record's "time" is the load factor. Offers fields, strain energy, RNP's damage,
// the stress, a line per increment and its own CSV of the nonlinear solve.
class QuasiStaticStepper {
 public:
  QuasiStaticStepper(const Problem& p, QuasiStaticSetup& s)
      : p_(p), s_(s), solver_(s.body, s.model, s.boundaries, s.solver.options), state_(s.body.size()) {}
  bool done() const { return solver_.done(); }
  void advance() {
    last_ = solver_.advance(state_.u);
    state_.step = last_.step;
    state_.time = last_.load;
    iterations_ += last_.iterations;
  }
  std::size_t step() const { return state_.step; }
  std::size_t steps() const { return s_.solver.options.steps; }
  double time() const { return state_.time; }
  std::size_t broken() const { return last_.softening_bonds; }
  Report report(bool) { return {&state_, 0.0, last_.softening_bonds, [this] { return s_.model.strain_energy(s_.body, state_.u); }}; }
  // The record's time of a quasi-static run is the load factor.
  std::string abscissa() const { return "load factor"; }
  std::string step_line() const { return quasi_static_step_line(last_); }
  // Its own observer, beside the deck's: the load-step CSV in the output directory.
  std::vector<AnyObserver> observers(const std::filesystem::path& dir) {
    file_ = dir / (p_.name + "_load_steps.csv");
    return {AnyObserver(LoadStepCsv(file_, &last_), 1)};
  }
  const Body& body() const { return s_.body; }
  Observers::DamageFunction damage_function() const {
    return [this](const VectorField& u, std::vector<double>& d) { s_.model.damage(s_.body, u, d); };
  }
  Observers::StressFunction stress_function() const {
    return [this](const VectorField& u, StressField& tau) { tau = stress_field(s_.model, s_.body, u); };
  }
  std::vector<std::string> describe() const { return describe_quasi_static(p_, s_.body, s_.model); }
  std::vector<std::string> summary() const { return quasi_static_summary(state_.step, iterations_, file_); }

 private:
  const Problem& p_;
  QuasiStaticSetup& s_;
  QuasiStaticSolver<Rnp> solver_;
  State state_;
  LoadStepReport last_;
  long iterations_ = 0;
  std::filesystem::path file_;
};

}  // namespace peridot
