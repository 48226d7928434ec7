export module peridot.solvers:newmark;
import peridot.std;
import peridot.models;
import :boundary;
import :explicit_dynamics;

export namespace peridot {

// A model an implicit solver can step: its linear operator -L u, its loads at time t, and a
// fracture test run after each solve (seed 000 Sec. 6: LPS).
template <class M>
concept ImplicitModel = ForceModel<M> && requires(const M& m, Body& body, const Body& cbody, const VectorField& u, VectorField& f, double t) {
  m.internal_forces(cbody, u, f);
  m.add_loads(t, f);
  { m.break_bonds(body, u) } -> std::convertible_to<std::size_t>;
  m.stiffness_diagonal(cbody, f);
};

struct NewmarkOptions {
  double end_time = 0;          // [s]
  double dt = 0;                // [s], > 0
  double tolerance = 1e-8;      // BiCGSTAB: |r| <= tolerance |r_0|, r_0 the predictor's residual
  int max_iterations = 500;     // per linear solve
  int max_sub_iterations = 200; // break / re-solve rounds per step
};

// What one step cost.
struct NewmarkStepReport {
  int iterations = 0;        // BiCGSTAB iterations over all solves of the step
  int sub_iterations = 0;    // re-solves after bonds broke (0: no bond broke)
  std::size_t broken = 0;    // directed bonds broken in the step (a pair counts twice), in this part's rows
};

// The work of a whole run so far.
struct NewmarkTotals {
  std::size_t steps = 0;
  long iterations = 0, sub_iterations = 0;
  int most = 0;  // iterations of the costliest step
};

// How one MPI rank's part joins the others' solve (BodyParts): every rank takes the same step
// lengths as one rank does. The ghosts are refreshed before each operator application and each
// fracture test.
using NewmarkParts = BodyParts;

// Implicit Newmark, average acceleration (beta = 1/4, gamma = 1/2), seed 000 eq. (6.5):
//   (4 rho / dt^2) u^{n+1} + L u^{n+1} = f^{n+1} + (4 rho / dt^2)(u^n + dt v^n + dt^2/4 a^n),
// solved matrix-free by Jacobi-preconditioned BiCGSTAB warm-started from the predictor, with
// the break sub-iteration: solve, break every overstretched bond, re-solve until none breaks.
// Loads are the model's (nonlocal tractions) plus body-force boundaries; kinematic boundaries
// are not supported. Dot products are exact sums rounded once (ExactSum), so the result depends
// neither on the thread count nor, with distribute(), on the rank count.
template <ImplicitModel Model>
class NewmarkSolver {
 public:
  NewmarkSolver(Body& body, Model model, std::vector<Boundary> boundaries, NewmarkOptions options)
      : body_(body), model_(std::move(model)), bcs_(std::move(boundaries)), opt_(options), dim_(body.dim()) {
    if (!(opt_.dt > 0) || !std::isfinite(opt_.dt)) throw std::invalid_argument("solver.dt must be a finite number > 0 for solver.type = 'newmark'");
    if (!(opt_.end_time > 0)) throw std::invalid_argument("solver.end_time must be > 0");
    for (const auto& bc : bcs_)
      if (bc.kind != BoundaryKind::body_force)
        throw std::invalid_argument("boundary '" + bc.name + "': solver.type = 'newmark' takes tractions and body forces, not prescribed motion");
    const std::size_t n = body.size();
    a_ = zero_field(n);
    for (auto* f : {&rhs_, &r_, &r0_, &p_, &v_, &s_, &t_, &y_, &z_, &diag_, &x_}) *f = zero_field(n);
    steps_ = choose_time_step(opt_.dt, {.end_time = opt_.end_time, .dt = opt_.dt}).steps;
  }

  std::size_t steps() const { return steps_; }
  const Model& model() const { return model_; }
  std::size_t broken_bonds() const { return broken_directed_ / 2; }  // since t = 0, in this part's rows
  const NewmarkStepReport& last() const { return last_; }
  const NewmarkTotals& totals() const { return totals_; }

  // Solve as one part of a distributed body (before initialize()).
  void distribute(NewmarkParts parts) { parts_ = std::move(parts); }

  // a^0 = (f(u^0) + loads(0)) / rho.
  void initialize(State& s) {
    if (parts_.exchange) parts_.exchange(s.u);
    model_.internal_forces(body_, s.u, s.f);
    loads(s.time, s.f);
    preconditioner();
    const double inv_rho = 1.0 / body_.density;
    for (int k = 0; k < dim_; ++k)
      for (std::size_t i = 0; i < body_.size(); ++i) a_[k][i] = s.f[k][i] * inv_rho;
  }

  void step(State& s) {
    const double dt = opt_.dt, t1 = double(s.step + 1) * dt;
    const double mass = 4 * body_.density / (dt * dt);
    const std::size_t n = body_.size();
    // Predictor, also the first guess.
    for (int k = 0; k < dim_; ++k)
      for (std::size_t i = 0; i < n; ++i) x_[k][i] = s.u[k][i] + dt * s.v[k][i] + 0.25 * dt * dt * a_[k][i];
    last_ = {};
    for (int round = 0;; ++round) {
      // The right side changes with the masks: tractions follow the numerical normals.
      for (int k = 0; k < dim_; ++k) std::fill(rhs_[k].begin(), rhs_[k].end(), 0.0);
      loads(t1, rhs_);
      for (int k = 0; k < dim_; ++k)
        for (std::size_t i = 0; i < n; ++i)
          rhs_[k][i] += mass * (s.u[k][i] + dt * s.v[k][i] + 0.25 * dt * dt * a_[k][i]);
      last_.iterations += bicgstab(mass);
      refresh(x_);  // ghost rows test their owners' displacements
      const std::size_t broke = model_.break_bonds(body_, x_);
      last_.broken += broke;
      if (!anywhere(broke)) break;
      preconditioner();  // the masks changed
      if (round + 1 >= opt_.max_sub_iterations)
        throw std::runtime_error(fmt::format("newmark: bonds still breaking after {} re-solves at t = {:.4e} s (raise solver.max_sub_iterations)",
                                             opt_.max_sub_iterations, t1));
      ++last_.sub_iterations;
    }
    broken_directed_ += last_.broken;
    totals_.steps += 1;
    totals_.iterations += last_.iterations;
    totals_.sub_iterations += last_.sub_iterations;
    totals_.most = std::max(totals_.most, last_.iterations);
    const double c = 4 / (dt * dt);
    for (int k = 0; k < dim_; ++k)
      for (std::size_t i = 0; i < n; ++i) {
        const double a1 = c * (x_[k][i] - s.u[k][i] - dt * s.v[k][i]) - a_[k][i];
        s.v[k][i] += 0.5 * dt * (a_[k][i] + a1);
        a_[k][i] = a1;
        s.u[k][i] = x_[k][i];
        s.f[k][i] = body_.density * a1;  // the net force density that moved the step
      }
    s.step += 1;
    s.time = t1;
  }

 private:
  // Jacobi diagonal mass + diag(L): it changes only when bonds break.
  void preconditioner() {
    const double mass = 4 * body_.density / (opt_.dt * opt_.dt);
    model_.stiffness_diagonal(body_, diag_);
    for (int k = 0; k < dim_; ++k)
      for (auto& d : diag_[k]) d += mass;
  }

  void loads(double t, VectorField& f) const {
    model_.add_loads(t, f);
    for (const auto& bc : bcs_) {
      const double g = bc.history(t);
      for (auto i : bc.points)
        for (int k = 0; k < dim_; ++k) f[k][i] += g * bc.value[k];
    }
  }

  // y = (mass I + L) x = mass x - f_int(x).
  void apply(double mass, const VectorField& x, VectorField& y) const {
    model_.internal_forces(body_, x, y);
    const auto n = static_cast<std::int64_t>(body_.size());
#pragma omp parallel for schedule(static)
    for (std::int64_t i = 0; i < n; ++i)
      for (int k = 0; k < dim_; ++k) y[k][i] = mass * x[k][i] - y[k][i];
  }

  // Whether any part broke a bond: every rank then re-solves.
  bool anywhere(std::size_t broke) const {
    if (!parts_.reduce) return broke > 0;
    ExactSum count;
    count += double(broke);
    parts_.reduce(count);
    return count.value() > 0;
  }

  double dot(const VectorField& a, const VectorField& b) const { return owned_dot(parts_, a, b, body_.size(), dim_); }

  void refresh(VectorField& x) const { parts_.refresh(x); }

  // Jacobi-preconditioned BiCGSTAB on (mass I + L) x = rhs from the current x_.
  int bicgstab(double mass) {
    const auto n = static_cast<std::int64_t>(body_.size());
    refresh(x_);
    apply(mass, x_, t_);
    for (int k = 0; k < dim_; ++k)
      for (std::int64_t i = 0; i < n; ++i) r_[k][i] = rhs_[k][i] - t_[k][i], r0_[k][i] = r_[k][i], p_[k][i] = 0, v_[k][i] = 0;
    const double norm0 = std::sqrt(dot(r_, r_));
    if (!(norm0 > 0)) return 0;
    const double target = opt_.tolerance * norm0;
    double rho = 1, alpha = 1, omega = 1;
    for (int it = 1; it <= opt_.max_iterations; ++it) {
      const double rho1 = dot(r0_, r_);
      if (rho1 == 0) throw std::runtime_error("newmark: BiCGSTAB broke down (rho = 0)");
      const double beta = (rho1 / rho) * (alpha / omega);
      rho = rho1;
      for (int k = 0; k < dim_; ++k)
        for (std::int64_t i = 0; i < n; ++i) {
          p_[k][i] = r_[k][i] + beta * (p_[k][i] - omega * v_[k][i]);
          y_[k][i] = p_[k][i] / diag_[k][i];
        }
      refresh(y_);
      apply(mass, y_, v_);
      alpha = rho / dot(r0_, v_);
      for (int k = 0; k < dim_; ++k)
        for (std::int64_t i = 0; i < n; ++i) s_[k][i] = r_[k][i] - alpha * v_[k][i];
      if (std::sqrt(dot(s_, s_)) <= target) {
        for (int k = 0; k < dim_; ++k)
          for (std::int64_t i = 0; i < n; ++i) x_[k][i] += alpha * y_[k][i];
        return it;
      }
      for (int k = 0; k < dim_; ++k)
        for (std::int64_t i = 0; i < n; ++i) z_[k][i] = s_[k][i] / diag_[k][i];
      refresh(z_);
      apply(mass, z_, t_);
      const double tt = dot(t_, t_);
      omega = tt > 0 ? dot(t_, s_) / tt : 0;
      for (int k = 0; k < dim_; ++k)
        for (std::int64_t i = 0; i < n; ++i) {
          x_[k][i] += alpha * y_[k][i] + omega * z_[k][i];
          r_[k][i] = s_[k][i] - omega * t_[k][i];
        }
      if (std::sqrt(dot(r_, r_)) <= target) return it;
      if (omega == 0) throw std::runtime_error("newmark: BiCGSTAB broke down (omega = 0)");
    }
    throw std::runtime_error(fmt::format("newmark: BiCGSTAB did not reach tolerance {:g} in {} iterations (raise solver.max_iterations)",
                                         opt_.tolerance, opt_.max_iterations));
  }

  Body& body_;
  Model model_;
  std::vector<Boundary> bcs_;
  NewmarkOptions opt_;
  int dim_ = 2;  // components stepped: the body's dimension
  std::size_t steps_ = 0, broken_directed_ = 0;
  NewmarkStepReport last_;
  NewmarkTotals totals_;
  NewmarkParts parts_;
  VectorField a_, rhs_, r_, r0_, p_, v_, s_, t_, y_, z_, diag_, x_;
};

}  // namespace peridot
