export module peridot.models:osb;
import peridot.std;
import :body;
import :elastic;

export namespace peridot {

// Linearised ordinary state-based peridynamics (seed 004 eqs. (6)-(20), discretised as
// (43)-(46)): Gaussian influence omega = exp(-|xi|^2 / delta^2) truncated at delta, extension
// e = eta . xi / |xi|, dilatation theta_i = (c_theta / m_i) sum_j omega |xi| e w_ij and pairwise
// force density (along +m, tension positive)
//   f_ij = k_theta omega |xi| (theta_i / m_i + theta_j / m_j) + k_e omega (1/m_i + 1/m_j) e,
// so that the force density on i is sum_j f_ij w_ij m_ij, w_ij the bond's quadrature weight
// (beta_ij V_j with the cell-area rule). 2D quantities are per unit thickness: the paper's
// thickness h cancels from every displacement, stress and flux.
// Every solver uses the per-bond pieces below (theta_weight, force_coefficients); the static
// linear system is assembled from them, never from a second copy of the formulas.
struct Osb {
  Kinematics kinematics = Kinematics::plane_stress;
  double delta = 0;                 // horizon [m]
  double c_theta = 0, k_theta = 0, k_e = 0;  // eqs. (16), (18), (19) [-, Pa, Pa]
  double critical_stretch = 0;      // > 0: a bond breaks for good once e / |xi| >= this (eq. 69)
  std::vector<double> m;            // weighted volume per point, eq. (44) [m^4 in 2D]

  // The constants of the paper's table for E and nu; m is left empty (see weigh()).
  static Osb make(double youngs_modulus, double poisson_ratio, Kinematics kinematics, double horizon);

  double influence(double r) const { return std::exp(-(r * r) / (delta * delta)); }
  // m_i = sum_j omega |xi|^2 w_ij over every bond, intact or not (the reference measure).
  void weigh(const Body& body);
  // Keeps the weighted volumes of the listed points, in that order (a rank's points in a
  // distributed run: m_i is a sum over the whole body's row of i, which a rank may not hold).
  void restrict_to(std::span<const std::int64_t> ids);

  // d theta_i / d e_ij for bond b of i.
  double theta_weight(std::size_t i, double r, double w) const { return c_theta * influence(r) * r * w / m[i]; }
  // f_ij = A (theta_i / m_i + theta_j / m_j) + B e_ij.
  struct Coefficients {
    double A, B;
  };
  Coefficients force_coefficients(std::size_t i, std::size_t j, double r) const {
    const double om = influence(r);
    return {k_theta * om * r, k_e * om * (1 / m[i] + 1 / m[j])};
  }

  void dilatation(const Body& body, const VectorField& u, std::vector<double>& theta) const;
  // g_b = f_ij w_ij for every directed bond (0 when broken): the force density on i along m_ij.
  void pair_forces(const Body& body, const VectorField& u, std::vector<double>& g) const;
  // The same with given dilatations (fictitious points carry extrapolated ones, Sec. 3.3).
  void pair_forces_with(const Body& body, const VectorField& u, const std::vector<double>& theta, std::vector<double>& g) const;

  ForceReport forces(Body& body, const VectorField& u, VectorField& f) const;
  // The force densities of the current bond state, breaking nothing.
  void internal_forces(const Body& body, const VectorField& u, VectorField& f) const;
  double strain_energy(const Body& body, const VectorField& u) const;  // [J] (2D: J/m)
  // Each point's share of it, -V_i f_i . u_i / 2, whose point_sum it is. On a rank's part it
  // is right for the owned points (their forces read the ghosts' dilatations).
  void point_energies(const Body& body, const VectorField& u, std::vector<double>& e) const;
  double stable_time_step(const Body& body) const;                     // [s]

  mutable std::vector<double> theta_;  // scratch, sized once
};

// Linearised extension e = (u_j - u_i) . xi / |xi| of bond b = (i, j).
inline double linear_extension(const BondList& bl, const VectorField& u, std::size_t i, std::int64_t b) {
  const auto j = std::size_t(bl.neighbor[b]);
  double e = 0;
  for (int k = 0; k < 3; ++k) e += (u[k][j] - u[k][i]) * bl.xi[k][b];
  return e / bl.length[b];
}

}  // namespace peridot

namespace peridot {

Osb Osb::make(double E, double nu, Kinematics k, double delta) {
  if (!(E > 0) || !std::isfinite(E)) throw std::invalid_argument(fmt::format("osb: youngs_modulus = {:g} Pa must be > 0", E));
  if (!(nu > -1 && nu < 0.5)) throw std::invalid_argument(fmt::format("osb: poisson_ratio = {:g} must be in (-1, 0.5)", nu));
  if (!(delta > 0)) throw std::invalid_argument("osb: horizon must be > 0");
  Osb o;
  o.kinematics = k;
  o.delta = delta;
  switch (k) {
    case Kinematics::solid:
      o.c_theta = 3, o.k_theta = -3 * (1 - 4 * nu) * E / (2 * (1 + nu) * (1 - 2 * nu)), o.k_e = 15 * E / (2 * (1 + nu));
      break;
    case Kinematics::plane_strain:
      o.c_theta = 2, o.k_theta = -(1 - 4 * nu) * E / ((1 + nu) * (1 - 2 * nu)), o.k_e = 4 * E / (1 + nu);
      break;
    case Kinematics::plane_stress:
      o.c_theta = 2 * (1 - 2 * nu) / (1 - nu), o.k_theta = -(1 - 3 * nu) * E / ((1 + nu) * (1 - 2 * nu)), o.k_e = 4 * E / (1 + nu);
      break;
    case Kinematics::bar:
      o.c_theta = 1 - 2 * nu, o.k_theta = nu * E / ((1 + nu) * (1 - 2 * nu)), o.k_e = E / (1 + nu);
      break;
  }
  return o;
}

void Osb::weigh(const Body& body) {
  const auto& bl = body.bonds;
  m.assign(body.size(), 0.0);
  for (std::size_t i = 0; i < body.size(); ++i) {
    double s = 0;
    for (auto b = bl.begin(i); b < bl.end(i); ++b) s += influence(bl.length[b]) * bl.length[b] * bl.length[b] * bl.weight[b];
    m[i] = s;
  }
}

void Osb::restrict_to(std::span<const std::int64_t> ids) {
  std::vector<double> mine(ids.size());
  for (std::size_t j = 0; j < ids.size(); ++j) mine[j] = m.at(std::size_t(ids[j]));
  m = std::move(mine);
  theta_ = {};
}

void Osb::dilatation(const Body& body, const VectorField& u, std::vector<double>& theta) const {
  const auto& bl = body.bonds;
  const auto n = std::int64_t(body.size());
  theta.resize(body.size());
#pragma omp parallel for schedule(static)
  for (std::int64_t ii = 0; ii < n; ++ii) {
    const auto i = std::size_t(ii);
    double t = 0;
    if (m[i] > 0)
      for (auto b = bl.begin(i); b < bl.end(i); ++b)
        if (bl.intact[b]) t += theta_weight(i, bl.length[b], bl.weight[b]) * linear_extension(bl, u, i, b);
    theta[i] = t;
  }
}

void Osb::pair_forces(const Body& body, const VectorField& u, std::vector<double>& g) const {
  dilatation(body, u, theta_);
  pair_forces_with(body, u, theta_, g);
}

void Osb::pair_forces_with(const Body& body, const VectorField& u, const std::vector<double>& theta, std::vector<double>& g) const {
  const auto& bl = body.bonds;
  g.assign(bl.size(), 0.0);
  const auto n = std::int64_t(body.size());
#pragma omp parallel for schedule(static)
  for (std::int64_t ii = 0; ii < n; ++ii) {
    const auto i = std::size_t(ii);
    for (auto b = bl.begin(i); b < bl.end(i); ++b) {
      const auto j = std::size_t(bl.neighbor[b]);
      if (!bl.intact[b] || !(m[i] > 0) || !(m[j] > 0)) continue;
      const auto c = force_coefficients(i, j, bl.length[b]);
      g[b] = (c.A * (theta[i] / m[i] + theta[j] / m[j]) + c.B * linear_extension(bl, u, i, b)) * bl.weight[b];
    }
  }
}

ForceReport Osb::forces(Body& body, const VectorField& u, VectorField& f) const {
  auto& bl = body.bonds;
  const auto n = std::int64_t(body.size());
  std::size_t broken = 0;
  if (critical_stretch > 0) {
    const std::uint8_t* nofail = body.no_fail.empty() ? nullptr : body.no_fail.data();
    // Both directions see the same |e| / |xi|, so they break together.
#pragma omp parallel for schedule(static) reduction(+ : broken)
    for (std::int64_t ii = 0; ii < n; ++ii) {
      const auto i = std::size_t(ii);
      for (auto b = bl.begin(i); b < bl.end(i); ++b) {
        const auto j = std::size_t(bl.neighbor[b]);
        if (!bl.intact[b] || (nofail && (nofail[i] || nofail[j]))) continue;
        if (linear_extension(bl, u, i, b) / bl.length[b] >= critical_stretch) bl.intact[b] = 0, ++broken;
      }
    }
  }
  internal_forces(body, u, f);
  return {broken};
}

void Osb::internal_forces(const Body& body, const VectorField& u, VectorField& f) const {
  const auto& bl = body.bonds;
  const auto n = std::int64_t(body.size());
  dilatation(body, u, theta_);
#pragma omp parallel for schedule(static)
  for (std::int64_t ii = 0; ii < n; ++ii) {
    const auto i = std::size_t(ii);
    double fi[3] = {0, 0, 0};
    for (auto b = bl.begin(i); b < bl.end(i); ++b) {
      const auto j = std::size_t(bl.neighbor[b]);
      if (!bl.intact[b]) continue;
      const auto c = force_coefficients(i, j, bl.length[b]);
      const double g = (c.A * (theta_[i] / m[i] + theta_[j] / m[j]) + c.B * linear_extension(bl, u, i, b)) * bl.weight[b] / bl.length[b];
      for (int k = 0; k < 3; ++k) fi[k] += g * bl.xi[k][b];
    }
    for (int k = 0; k < 3; ++k) f[k][i] = fi[k];
  }
}

double Osb::strain_energy(const Body& body, const VectorField& u) const {
  std::vector<double> per;
  point_energies(body, u, per);
  return point_sum(per);
}

void Osb::point_energies(const Body& body, const VectorField& u, std::vector<double>& per) const {
  // The model is linear, so the stored energy is half the work of the internal forces,
  // -1/2 sum_i V_i f_i . u_i.
  VectorField f = zero_field(body.size());
  internal_forces(body, u, f);
  per.assign(body.size(), 0.0);
  for (std::size_t i = 0; i < body.size(); ++i) {
    double e = 0;
    for (int k = 0; k < 3; ++k) e -= 0.5 * body.points.volume[i] * f[k][i] * u[k][i];
    per[i] = e;
  }
}

double Osb::stable_time_step(const Body& body) const {
  // Gershgorin bound on the stiffness row of each point: the direct e term plus the theta
  // coupling (sum_j A w / m_i) (sum_j c_theta omega |xi| w / m_i).
  const auto& bl = body.bonds;
  double dt = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < body.size(); ++i) {
    double direct = 0, a = 0, t = 0;
    for (auto b = bl.begin(i); b < bl.end(i); ++b) {
      const auto j = std::size_t(bl.neighbor[b]);
      const auto c = force_coefficients(i, j, bl.length[b]);
      direct += c.B * bl.weight[b];
      a += std::abs(c.A) * bl.weight[b] / m[i];
      t += theta_weight(i, bl.length[b], bl.weight[b]);
    }
    const double k = direct + 2 * a * t;
    if (k > 0) dt = std::min(dt, std::sqrt(2 * body.density / k));
  }
  return dt;
}

}  // namespace peridot
