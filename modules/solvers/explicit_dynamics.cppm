export module peridot.solvers:explicit_dynamics;
import peridot.std;
import peridot.models;
import :boundary;

export namespace peridot {

// Two forms of the same second-order explicit scheme. Velocity Verlet carries v at whole
// steps; central differences (seed 003 eqs. 76-77) carry only displacements, with the
// backward-difference velocity V^k = (U^k - U^{k-1}) / dt, and the k = 0 half step
// U^1 = u0 + dt v0 + dt^2 a0 / 2. Their displacements agree to round-off.
enum class ExplicitScheme { velocity_verlet, central_difference };

struct ExplicitOptions {
  double end_time = 0;   // [s], > 0
  double dt = 0;         // [s]; 0 picks safety * the model's stable estimate
  double safety = 0.8;   // fraction of the stable estimate used when dt = 0, in (0, 1]
  ExplicitScheme scheme = ExplicitScheme::velocity_verlet;
};

// The time step actually used and how it relates to the stability estimate.
struct TimeStep {
  double estimate = 0;   // model's stable time step [s]
  double dt = 0;         // step used [s]
  std::size_t steps = 0; // steps to reach end_time
  bool above_estimate() const { return dt > estimate; }
};

// Runs of more steps than this are refused as input errors (days of wall time at any size).
inline constexpr double max_time_steps = 1e9;

TimeStep choose_time_step(double estimate, const ExplicitOptions& options);

// Velocity Verlet or central differences for rho a = f(u) + b, with body-force, prescribed
// displacement and prescribed velocity regions. The loop is flat: kick, drift, kinematic
// constraints, force pass (and for Verlet the second half kick). Nothing is allocated per step.
template <ForceModel Model>
class ExplicitSolver {
 public:
  ExplicitSolver(Body& body, Model model, std::vector<Boundary> boundaries, TimeStep ts,
                 ExplicitScheme scheme = ExplicitScheme::velocity_verlet)
      : body_(body), model_(std::move(model)), bcs_(std::move(boundaries)), ts_(ts), scheme_(scheme) {
    for (std::size_t c = 0; c < bcs_.size(); ++c) {
      const auto& bc = bcs_[c];
      for (auto i : bc.points) {
        if (i < 0 || std::size_t(i) >= body.size())
          throw std::out_of_range("boundary '" + bc.name + "': point index out of range");
        if (bc.kind == BoundaryKind::body_force) {
          loaded_.push_back(i);
          continue;
        }
        for (int k = 0; k < body.dim(); ++k)
          if (bc.components[k]) kinematic_.push_back({i, k, c, 0.0});
      }
    }
    std::sort(loaded_.begin(), loaded_.end());
    loaded_.erase(std::unique(loaded_.begin(), loaded_.end()), loaded_.end());
    slot_.resize(bcs_.size());
    for (std::size_t c = 0; c < bcs_.size(); ++c)
      if (bcs_[c].kind == BoundaryKind::body_force)
        for (auto i : bcs_[c].points) slot_[c].push_back(std::int32_t(std::lower_bound(loaded_.begin(), loaded_.end(), i) - loaded_.begin()));
    b_ = zero_field(loaded_.size());
    saved_u_ = saved_v_ = b_;
  }

  // On a rank of a distributed run: refreshes the ghost points' displacements from their
  // owners before every force pass (the owned points' bonds read them).
  void set_exchange(std::function<void(VectorField&)> exchange) { exchange_ = std::move(exchange); }

  const TimeStep& time_step() const { return ts_; }
  const Model& model() const { return model_; }
  // Work done on the body by body forces and by kinematic constraints [J] (2D: J/m).
  double external_work() const { return external_work_; }
  // Bonds broken since t = 0: directed ones over 2, so pairs on a symmetric bond list.
  std::size_t broken_bonds() const { return broken_directed_ / 2; }

  // What the solver accumulates over a run besides the State, restored with it on a restart:
  // the work from the checkpoint, the broken bonds from the restored masks.
  struct Counters {
    double external_work = 0;
    std::size_t broken_directed = 0;  // directed bonds broken since t = 0
  };

  // Continues a run instead of initialize(): s holds u, v, f, time and step as they were after
  // a step (with the body's bond mask of that moment), c the counters of that moment.
  void restore(const State& s, const Counters& c) {
    external_work_ = c.external_work;
    broken_directed_ = c.broken_directed;
    body_forces(s.time);
  }

  // Prescribed values, forces and accelerations at t = state.time; call once before stepping.
  void initialize(State& s) {
    for (auto& d : kinematic_) {
      const auto& bc = bcs_[d.bc];
      if (bc.kind == BoundaryKind::displacement) s.u[d.k][d.i] = bc.value[d.k] * bc.history(s.time);
      else s.v[d.k][d.i] = bc.value[d.k] * bc.history(s.time);
    }
    broken_directed_ += force_pass(s, s.time).newly_broken_directed;
    body_forces(s.time);
  }

  void step(State& s) {
    const double dt = ts_.dt, t0 = s.time, t1 = double(s.step + 1) * dt;
    const double inv_rho = 1.0 / body_.density;
    const auto n = static_cast<std::int64_t>(body_.size());
    const int dim = body_.dim();
    for (auto& d : kinematic_) d.v_old = s.v[d.k][d.i];
    // Verlet: v_{k+1/2} = v_k + dt/2 a_k. Central differences: V^{k+1} = V^k + dt a_k, which is
    // U^{k+1} = 2U^k - U^{k-1} + dt^2 a_k, except at k = 0 (eq. 77): V^1 = v0 + dt/2 a_0.
    const bool cd = scheme_ == ExplicitScheme::central_difference;
    const double kick = cd && s.step > 0 ? dt : 0.5 * dt;
    kick_drift(s, n, dim, kick, dt, inv_rho);
    // Constrained components: after this, v holds the mid-step velocity with du = dt v everywhere.
    for (auto& d : kinematic_) {
      const auto& bc = bcs_[d.bc];
      const double u_old = s.u[d.k][d.i] - dt * s.v[d.k][d.i];
      if (bc.kind == BoundaryKind::displacement) {
        s.u[d.k][d.i] = bc.value[d.k] * bc.history(t1);
        s.v[d.k][d.i] = (s.u[d.k][d.i] - u_old) / dt;
      } else {
        s.v[d.k][d.i] = bc.value[d.k] * bc.history(0.5 * (t0 + t1));
        s.u[d.k][d.i] = u_old + dt * s.v[d.k][d.i];
      }
    }
    // Trapezoidal work: loads and reactions at t0 and t1 times the increment dt v_half.
    double work = load_work(s, dt);
    broken_directed_ += force_pass(s, t1).newly_broken_directed;
    body_forces(t1);
    work += load_work(s, dt);
    if (!cd) kick_drift(s, n, dim, 0.5 * dt, 0.0, inv_rho);
    for (auto& d : kinematic_) {
      const auto& bc = bcs_[d.bc];
      if (!cd) s.v[d.k][d.i] = bc.kind == BoundaryKind::velocity ? bc.value[d.k] * bc.history(t1) : s.v[d.k][d.i];
      const double m = body_.density * body_.points.volume[d.i];
      work += 0.5 * m * (s.v[d.k][d.i] * s.v[d.k][d.i] - d.v_old * d.v_old);
    }
    external_work_ += work;
    s.step += 1;
    s.time = t1;
  }

 private:
  // v += kick a, then (with drift > 0) u += drift v, a = (f + b) / rho. Body forces load thin
  // layers, so b is kept for the loaded points only: the sweep over every point reads f alone
  // (on the 512k crack-branching deck a whole b was a third of the sweeps' memory traffic and
  // its zeroing a 12 MB write per step), and the loaded points are then set again from their
  // values before the sweep with b added, the same expression as everywhere.
  void kick_drift(State& s, std::int64_t n, int dim, double kick, double drift, double inv_rho) {
    const std::size_t m = loaded_.size();
    for (std::size_t q = 0; q < m; ++q)
      for (int k = 0; k < dim; ++k) {
        saved_v_[k][q] = s.v[k][std::size_t(loaded_[q])];
        saved_u_[k][q] = s.u[k][std::size_t(loaded_[q])];
      }
    if (drift > 0) {
#pragma omp parallel for schedule(static)
      for (std::int64_t i = 0; i < n; ++i)
        for (int k = 0; k < dim; ++k) {
          s.v[k][i] += kick * s.f[k][i] * inv_rho;
          s.u[k][i] += drift * s.v[k][i];
        }
    } else {
#pragma omp parallel for schedule(static)
      for (std::int64_t i = 0; i < n; ++i)
        for (int k = 0; k < dim; ++k) s.v[k][i] += kick * s.f[k][i] * inv_rho;
    }
    for (std::size_t q = 0; q < m; ++q) {
      const auto i = std::size_t(loaded_[q]);
      for (int k = 0; k < dim; ++k) {
        s.v[k][i] = saved_v_[k][q] + kick * (s.f[k][i] + b_[k][q]) * inv_rho;
        if (drift > 0) s.u[k][i] = saved_u_[k][q] + drift * s.v[k][i];
      }
    }
  }

  // Models with time-dependent loads of their own (LPS's nonlocal tractions) take the time.
  ForceReport force_pass(State& s, double t) {
    if (exchange_) exchange_(s.u);
    if constexpr (requires { model_.forces(body_, s.u, s.f, t); }) return model_.forces(body_, s.u, s.f, t);
    else return model_.forces(body_, s.u, s.f);
  }

  struct KinematicDof {
    std::int32_t i;
    int k;
    std::size_t bc;
    double v_old;
  };

  void body_forces(double t) {
    for (auto& c : b_) std::fill(c.begin(), c.end(), 0.0);
    for (std::size_t c = 0; c < bcs_.size(); ++c) {
      const auto& bc = bcs_[c];
      if (bc.kind != BoundaryKind::body_force) continue;
      const double g = bc.history(t);
      for (auto q : slot_[c])
        for (int k = 0; k < 3; ++k) b_[k][std::size_t(q)] += g * bc.value[k];
    }
  }

  // Half of the trapezoidal work over the step: body forces b, and on constrained
  // components the reaction, which is -f plus the inertia added in step().
  double load_work(const State& s, double dt) const {
    double w = 0;
    for (std::size_t c = 0; c < bcs_.size(); ++c) {
      const auto& bc = bcs_[c];
      if (bc.kind != BoundaryKind::body_force) continue;
      for (std::size_t p = 0; p < bc.points.size(); ++p) {
        const auto i = std::size_t(bc.points[p]);
        const auto q = std::size_t(slot_[c][p]);
        for (int k = 0; k < 3; ++k) w += 0.5 * dt * b_[k][q] * s.v[k][i] * body_.points.volume[i];
      }
    }
    for (const auto& d : kinematic_)
      w -= 0.5 * dt * s.f[d.k][d.i] * s.v[d.k][d.i] * body_.points.volume[d.i];
    return w;
  }

  Body& body_;
  Model model_;
  std::vector<Boundary> bcs_;
  TimeStep ts_;
  ExplicitScheme scheme_;
  std::vector<std::int32_t> loaded_;              // points under a body force, ascending
  std::vector<std::vector<std::int32_t>> slot_;   // per body-force boundary: each point's index in loaded_
  VectorField b_;                                 // body force density per loaded point [N/m^3]
  VectorField saved_u_, saved_v_;                 // the loaded points' u and v before a sweep
  std::vector<KinematicDof> kinematic_;
  double external_work_ = 0;
  std::size_t broken_directed_ = 0;
  std::function<void(VectorField&)> exchange_;
};

}  // namespace peridot

namespace peridot {

TimeStep choose_time_step(double estimate, const ExplicitOptions& o) {
  if (!(o.end_time > 0) || !std::isfinite(o.end_time)) throw std::invalid_argument("solver.end_time must be a finite number > 0");
  if (!(o.dt >= 0) || !std::isfinite(o.dt)) throw std::invalid_argument("solver.dt must be >= 0 (0 = automatic)");
  if (!(o.safety > 0 && o.safety <= 1)) throw std::invalid_argument("solver.safety must be in (0, 1]");
  if (!(estimate > 0) || !std::isfinite(estimate)) throw std::invalid_argument("stable time step estimate is not positive: the body has no bonds");
  TimeStep ts;
  ts.estimate = estimate;
  ts.dt = o.dt > 0 ? o.dt : o.safety * estimate;
  // An end time that is a whole number of steps up to round-off takes exactly that many.
  const double steps = o.end_time / ts.dt;
  // Guard the double -> integer conversion: an absurd end time or a tiny dt would overflow it.
  if (!(steps <= max_time_steps))
    throw std::invalid_argument(fmt::format("solver.end_time = {:g} s with dt = {:g} s gives {:.3g} steps; at most {:.0e} are allowed "
                                            "(reduce end_time, or check density and moduli, which set the stable dt)",
                                            o.end_time, ts.dt, steps, max_time_steps));
  ts.steps = static_cast<std::size_t>(std::abs(steps - std::round(steps)) < 1e-6 * steps ? std::round(steps) : std::ceil(steps));
  return ts;
}

}  // namespace peridot
