module;
#include <omp.h>

#include "lean_kernel.h"

export module peridot.models:rnp;
import peridot.std;
import :body;
import :elastic;
import :lean_records;

export namespace peridot {

// d x d blocks of a tangent on a body's bond pattern: one diagonal block per point and one
// block per directed bond (row i, column neighbor[b]), row-major within a block. The
// pattern is the bond list's; only the values change between Newton iterations.
struct TangentBlocks {
  int dim = 2;
  std::vector<double> diagonal;  // n * d * d
  std::vector<double> bond;      // bonds * d * d
  std::size_t block() const { return std::size_t(dim * dim); }
};

// Regularized nonlinear pairwise potential of Diehl & Lipton (seed 002, spec Sec. 1), with
// influence J(|xi| / eps) (1 by default) and g(r) = C (1 - exp(-beta r^2)):
//   bond strain  S = (u_j - u_i) . e / |xi|,  e = xi / |xi|   (small deformation)
//   force        f_ij = P 2 C beta J S exp(-beta |xi| S^2) e w_ij,   P = 2 / (eps^(d+1) omega_d)
//   tangent      A_ij = P J / |xi| g''(sqrt|xi| S) (e (x) e) w_ij,  K_ii = -sum_k A_ik   (eqs. 32-35)
//   energy       sum_i V_i sum_j w_ij (P / 2) J g(sqrt|xi| S)                           (eq. 13)
//   damage       d_i = max_j sqrt|xi| |S_ij| / r_c,  r_c = sqrt(1 / (2 beta))            (eq. 18)
// Bonds soften past d = 1 and are never broken, as in the paper, unless break_factor > 0:
// then a bond breaks for good (both ends) once sqrt|xi| |S| > break_factor r_c, unless an end
// lies in a no-fail region (Body::no_fail).
// Influence J(|xi| / eps) inside the horizon: constant (J = 1, the paper's examples) or
// linear (J = 1 - r).
enum class RnpInfluence { constant, linear };

struct Rnp {
  int dim = 2;
  RnpInfluence influence = RnpInfluence::constant;
  double C = 0;               // [J/m^(d-1)] per the normalisation above
  double beta = 0;            // [1/m]
  double horizon = 0;         // epsilon [m]
  double prefactor = 0;       // P = 2 / (eps^(d+1) omega_d)
  double break_factor = 0;    // 0: bonds only soften

  static Rnp make(int dim, double C, double beta, double horizon, double break_factor = 0,
                  RnpInfluence influence = RnpInfluence::constant);
  // C and beta from E and G_c. Convention (tested by a homogeneous-strain patch): the exact
  // linearisation of the force, whose micromodulus 2 C beta P equals the PMB one for E and
  // the kinematics (2D plane stress: C beta = 9E/4, so mu = C beta / 6, twice NLMech's value;
  // plane strain 12E/5; 3D 4E; 1D bar E). G_c is the energy to soften every bond across a
  // plane completely: G_c = C P m_d with m_d = eps^2/2, 2 eps^3/3, pi eps^4/4 in 1D, 2D, 3D.
  // With J != 1 both relations carry M_J = int_0^1 J(s) s^d ds in place of 1 / (d + 1).
  static Rnp from_elastic(double youngs_modulus, double fracture_energy, double horizon, Kinematics k, int dim,
                          RnpInfluence influence = RnpInfluence::constant);
  // Seed 003 eq. (83), Lipton's convention in 2D: C = pi G_c / (4 M_J), beta = 8E / (5 C M_J),
  // M_J = int_0^1 J(r) r^2 dr. Reproduces the paper, but its small-strain Lame constants are
  // lambda = mu = 4E/5, twice the plane-strain 2E/5: the effective Young's modulus is 2E and
  // wave speeds are sqrt(2) times those of E (spec 003 Sec. 1.5).
  static Rnp lipton(double youngs_modulus, double fracture_energy, double horizon, RnpInfluence influence = RnpInfluence::linear);
  double J(double length) const { return influence == RnpInfluence::constant ? 1.0 : std::max(0.0, 1.0 - length / horizon); }

  double critical_r() const { return std::sqrt(0.5 / beta); }
  double micromodulus() const { return 2 * C * beta * prefactor; }  // small-strain c [N/m^(d+3)]

  ForceReport forces(Body& body, const VectorField& u, VectorField& f) const;
  double strain_energy(const Body& body, const VectorField& u) const;
  // Each point's share of it, whose point_sum it is.
  void point_energies(const Body& body, const VectorField& u, std::vector<double>& e) const;
  double stable_time_step(const Body& body) const;
  // d_i = max_j sqrt|xi| |S_ij| / r_c over intact bonds; bonds with d > 1 are softening.
  void damage(const Body& body, const VectorField& u, std::vector<double>& d) const;
  std::size_t softening_bonds(const Body& body, const VectorField& u) const;  // directed
  // g_b = P 2 C beta J S exp(-beta |xi| S^2) w_b per directed bond (0 when broken): the pair
  // force density on i along the reference direction xi / |xi|, as forces() sums it.
  void pair_forces(const Body& body, const VectorField& u, std::vector<double>& g) const;
  // dL/du at u, with L the internal force density of forces().
  void tangent(const Body& body, const VectorField& u, TangentBlocks& K) const;

  // On a lean list (partner, float weight, state: 9 bytes per bond) forces() runs in single
  // precision, eight bonds at a time, on fixed-point bond vectors and float displacements
  // (lean_kernel.cpp; the bound is in tests/models/test_rnp_lean.cpp); every other reader
  // recomputes xi from the positions in double. lean_vector: -1 the fastest kernel the CPU
  // runs, 0 the portable one, 1 AVX2 (all the same bits), for tests.
  int lean_vector = -1;
  // Whether the single-precision pass's constants (2 P C beta, and beta in the fixed point's
  // unit) are normal floats; forces() on a lean list throws std::invalid_argument if not.
  bool single_precision_fits() const;

  // Scratch for packed displacements, reused across force passes (sized once, never per step).
  mutable std::vector<double> packed_, scratch_;
  mutable LargeArray<std::int32_t> lean_packed_;
};

}  // namespace peridot

namespace peridot {

namespace {

double unit_ball(int d) { return d == 1 ? 2.0 : d == 2 ? std::numbers::pi : 4.0 * std::numbers::pi / 3.0; }

// Reference direction, length and strain of bond b from point i.
struct BondStrain {
  double e[3];
  double len, S;
};


inline BondStrain strain_of(const Body& body, const VectorField& u, int dim, std::int64_t i, std::int64_t b) {
  const auto g = bond_geometry(body.points, body.bonds, std::size_t(i), b);
  BondStrain s{{0, 0, 0}, g.len, 0};
  const auto j = body.bonds.neighbor[b];
  double du_e = 0;
  for (int k = 0; k < dim; ++k) {
    s.e[k] = g.xi[k] / s.len;
    du_e += (u[k][j] - u[k][i]) * s.e[k];
  }
  s.S = du_e / s.len;
  return s;
}

}  // namespace

namespace {
// M_J = int_0^1 J(s) s^d ds.
double influence_moment(RnpInfluence j, int d) { return j == RnpInfluence::constant ? 1.0 / (d + 1) : 1.0 / (d + 1) - 1.0 / (d + 2); }
}  // namespace

Rnp Rnp::make(int dim, double C, double beta, double horizon, double break_factor, RnpInfluence influence) {
  if (dim < 1 || dim > 3) throw std::invalid_argument("rnp: dimension must be 1, 2 or 3");
  if (!(C > 0) || !(beta > 0) || !(horizon > 0) || !(break_factor >= 0))
    throw std::invalid_argument("rnp: need C > 0, beta > 0, horizon > 0 and break_factor >= 0");
  Rnp m;
  m.dim = dim;
  m.C = C;
  m.beta = beta;
  m.horizon = horizon;
  m.break_factor = break_factor;
  m.influence = influence;
  // The one place the prefactor lives. The pair force is 2 P C beta J S exp(..) = 4 C beta J S
  // exp(..) / (omega_d eps^(d+1)) with psi = C (1 - exp(-beta r)): the factor 4 of seed 003
  // eq. (9), which its Algorithm 1 and Sec. 7.1 drop (typo, spec 003 Sec. 2.3) and NLMech keeps;
  // with it, eq. (83)'s G_c is the energy to break every bond across a plane.
  m.prefactor = 2.0 / (std::pow(horizon, dim + 1) * unit_ball(dim));
  return m;
}

Rnp Rnp::from_elastic(double E, double Gc, double eps, Kinematics k, int dim, RnpInfluence influence) {
  if (!(E > 0) || !(Gc > 0) || !(eps > 0)) throw std::invalid_argument("rnp: need E > 0, G_c > 0, horizon > 0");
  const double P = 2.0 / (std::pow(eps, dim + 1) * unit_ball(dim));
  // C beta from the small-strain micromodulus c = 2 C beta P of the matching PMB material.
  double c = 0;
  if (dim == 1) c = 2 * E / (eps * eps);  // 1D: E = c eps^2 / 2
  else if (dim == 2) c = (k == Kinematics::plane_strain ? 48.0 / 5.0 : 9.0) * E / (std::numbers::pi * eps * eps * eps);
  else c = 18 * (E / (3 * (1 - 2 * 0.25))) / (std::numbers::pi * std::pow(eps, 4));
  // Both the moduli and the crossing measure weigh bonds by J(s) s^d: M_J against 1 / (d + 1).
  const double ratio = influence_moment(influence, dim) * (dim + 1);
  const double Cbeta = c / (2 * P) / ratio;
  const double crossing = (dim == 1 ? eps * eps / 2 : dim == 2 ? 2 * eps * eps * eps / 3 : std::numbers::pi * std::pow(eps, 4) / 4) * ratio;
  const double C = Gc / (P * crossing);
  return make(dim, C, Cbeta / C, eps, 0, influence);
}

Rnp Rnp::lipton(double E, double Gc, double eps, RnpInfluence influence) {
  if (!(E > 0) || !(Gc > 0) || !(eps > 0)) throw std::invalid_argument("rnp: need E > 0, G_c > 0, horizon > 0");
  const double MJ = influence_moment(influence, 2);
  const double C = std::numbers::pi * Gc / (4 * MJ);
  return make(2, C, 8 * E / (5 * C * MJ), eps, 0, influence);
}

namespace {

// The force pass. Displacements are packed per point (stride 2 in 1D/2D, 4 in 3D; on a compact
// list the positions follow them, stride 4 or 8) so a partner costs one cache line; each point's
// bonds go through three passes (strains, their exponentials as one vectorised batch, the sum),
// and each point sums only its own bonds, so the result is the same on any thread count. A
// compact list's xi and |xi| come from the packed positions: the same subtraction and
// bond_length as the builders', so the same bits as a full list's.
template <int D>
constexpr int rnp_stride = D == 3 ? 4 : 2;

// exp(x) in place for x[0..n), vectorised (batch_exp.cpp).
extern "C" void peridot_batch_exp(double* x, std::size_t n);

template <int D, bool Linear, bool Stored, bool NoFail>
std::size_t rnp_forces(const Rnp& m, Body& body, const VectorField& u, std::vector<double>& packed, std::vector<double>& scratch,
                       VectorField& f) {
  auto& bl = body.bonds;
  const std::uint8_t* nofail = NoFail ? body.no_fail.data() : nullptr;
  const auto n = static_cast<std::int64_t>(body.size());
  constexpr int X = rnp_stride<D>, St = Stored ? X : 2 * X;  // u at 0, x at X
  packed.resize(std::size_t(n) * St);
  double* up = packed.data();
  std::int64_t most = 0;
#pragma omp parallel for schedule(static) reduction(max : most)
  for (std::int64_t i = 0; i < n; ++i) {
    for (int k = 0; k < D; ++k) up[i * St + k] = u[k][std::size_t(i)];
    if constexpr (!Stored)
      for (int k = 0; k < D; ++k) up[i * St + X + k] = body.points.x[std::size_t(k)][std::size_t(i)];
    most = std::max(most, bl.offset[std::size_t(i) + 1] - bl.offset[std::size_t(i)]);
  }
  // Two rows of `most` per thread: the bonds' force factors and exponents.
  const auto row = std::size_t(most);
  scratch.resize(std::size_t(omp_get_max_threads()) * 2 * row);
  const std::int64_t* off = bl.offset.data();
  const std::int32_t* nb = bl.neighbor.data();
  const double* len = Stored ? bl.length.data() : nullptr;
  const double* w = bl.weight.data();
  const double* xi[3] = {bl.xi[0].data(), bl.xi[1].data(), bl.xi[2].data()};
  std::uint8_t* intact = bl.intact.data();
  const double k0 = m.prefactor * 2 * m.C * m.beta, beta = m.beta, inv_eps = 1.0 / m.horizon;
  const double limit2 = m.break_factor > 0 ? m.break_factor * m.break_factor * 0.5 / m.beta : std::numeric_limits<double>::infinity();
  std::size_t broken = 0;
#pragma omp parallel for schedule(static) reduction(+ : broken)
  for (std::int64_t i = 0; i < n; ++i) {
    double* factor = scratch.data() + std::size_t(omp_get_thread_num()) * 2 * row;
    double* expo = factor + row;
    double ui[D], xq[D] = {}, fi[D] = {};
    for (int k = 0; k < D; ++k) {
      ui[k] = up[i * St + k];
      if constexpr (!Stored) xq[k] = up[i * St + X + k];
    }
    const std::int64_t b0 = off[i], count = off[i + 1] - b0;
    // xi_k of bond b to partner j.
    const auto xi_of = [&](int k, std::int64_t b, std::int64_t j) {
      if constexpr (Stored) return xi[k][b];
      else return up[j * St + X + k] - xq[k];
    };
    // Pass 1: strains. S and the direction both come from xi / |xi|^2 (one division). No branch,
    // so it vectorises over the point's bonds (gathers; one division and square root per lane).
    std::size_t snapped = 0;
#pragma omp simd reduction(+ : snapped)
    for (std::int64_t c = 0; c < count; ++c) {
      const std::int64_t b = b0 + c, j = nb[b];
      double d = 0, e[3] = {};
      for (int k = 0; k < D; ++k) {
        e[k] = xi_of(k, b, j);
        d += (up[j * St + k] - ui[k]) * e[k];
      }
      double L;
      if constexpr (Stored) L = len[b];
      else L = bond_length(e[0], e[1], e[2]);
      const double inv = 1.0 / L;
      const double S = d * inv * inv;   // (u_j - u_i) . e / |xi|
      const double r2 = L * S * S;      // (sqrt|xi| S)^2
      // Both directions see the same |S|, so they break together without communication.
      // A bond with an end in a no-fail region never breaks (it still softens).
      int breakable = 1;
      if constexpr (NoFail) breakable = (nofail[i] | nofail[j]) ^ 1;
      const int alive = intact[b], snap = alive & int(r2 > limit2) & breakable, now = alive & (snap ^ 1);
      intact[b] = std::uint8_t(now);
      snapped += std::size_t(snap);
      double a = now ? k0 * S * w[b] * inv : 0.0;
      if constexpr (Linear) a *= std::max(0.0, 1.0 - L * inv_eps);
      factor[c] = a;
      expo[c] = now ? -beta * r2 : 0.0;
    }
    broken += snapped;
    // Pass 2: the exponentials, vectorised.
    peridot_batch_exp(expo, std::size_t(count));
    // Pass 3: f_i = sum_j a_ij exp(-beta |xi| S^2) xi_ij.
    for (std::int64_t c = 0; c < count; ++c) {
      const double mag = factor[c] * expo[c];
      const std::int64_t b = b0 + c, j = nb[b];
      for (int k = 0; k < D; ++k) fi[k] += mag * xi_of(k, b, j);
    }
    for (int k = 0; k < D; ++k) f[k][std::size_t(i)] = fi[k];
    for (int k = D; k < 3; ++k) f[k][std::size_t(i)] = 0;
  }
  return broken;
}

template <int D>
std::size_t rnp_forces(const Rnp& m, Body& body, const VectorField& u, std::vector<double>& packed, std::vector<double>& scratch,
                       VectorField& f) {
  const bool linear = m.influence == RnpInfluence::linear, stored = body.bonds.stores_geometry();
  // Decks give every body its no-fail flags, mostly all 0: the flagged pass (a byte gathered
  // per bond, 9 % of a step) only where one is set.
  const bool flagged = std::find(body.no_fail.begin(), body.no_fail.end(), std::uint8_t(1)) != body.no_fail.end();
  if (!flagged) {
    if (stored) return linear ? rnp_forces<D, true, true, false>(m, body, u, packed, scratch, f) : rnp_forces<D, false, true, false>(m, body, u, packed, scratch, f);
    return linear ? rnp_forces<D, true, false, false>(m, body, u, packed, scratch, f) : rnp_forces<D, false, false, false>(m, body, u, packed, scratch, f);
  }
  if (stored) return linear ? rnp_forces<D, true, true, true>(m, body, u, packed, scratch, f) : rnp_forces<D, false, true, true>(m, body, u, packed, scratch, f);
  return linear ? rnp_forces<D, true, false, true>(m, body, u, packed, scratch, f) : rnp_forces<D, false, false, true>(m, body, u, packed, scratch, f);
}

}  // namespace

namespace {

// The single-precision pass's constants in the fixed point's unit q (lean_records).
PeridotRnpLean lean_constants(const Rnp& m) {
  const double q = lean_unit(m.horizon);
  const double limit2 = m.break_factor > 0 ? m.break_factor * m.break_factor * 0.5 / m.beta : std::numeric_limits<double>::infinity();
  return {float(m.micromodulus()), float(m.beta * q), float(limit2 / q), float(q / m.horizon), m.influence == RnpInfluence::linear};
}

}  // namespace

bool Rnp::single_precision_fits() const {
  const PeridotRnpLean k = lean_constants(*this);
  const auto normal = [](float x) { return std::isfinite(x) && std::abs(x) >= std::numeric_limits<float>::min(); };
  return normal(k.k0) && normal(k.beta_q) && normal(k.inv_eps_q);
}

// The single-precision pass on a lean list.
std::size_t rnp_lean_forces(const Rnp& m, Body& body, const VectorField& u, LargeArray<std::int32_t>& packed, VectorField& f) {
  if (!m.single_precision_fits())
    throw std::invalid_argument(fmt::format("rnp: the pair force constant 2 P C beta = {:g} or beta q = {:g} lies outside single precision; "
                                            "set discretization.list_precision: double",
                                            m.micromodulus(), m.beta * lean_unit(m.horizon)));
  const PeridotRnpLean k = lean_constants(m);
  pack_lean_records(body, u, m.horizon, packed, "rnp");
  const int vector = m.lean_vector < 0 ? peridot_pmb_lean_vector() : std::min(m.lean_vector, peridot_pmb_lean_vector());
  return lean_rows(body, packed, f, [&](PeridotLeanPass& pass) { return peridot_rnp_lean_rows(&pass, &k, vector); });
}

ForceReport Rnp::forces(Body& body, const VectorField& u, VectorField& f) const {
  if (body.bonds.lean()) return {rnp_lean_forces(*this, body, u, lean_packed_, f)};
  const std::size_t broken = dim == 1   ? rnp_forces<1>(*this, body, u, packed_, scratch_, f)
                             : dim == 2 ? rnp_forces<2>(*this, body, u, packed_, scratch_, f)
                                        : rnp_forces<3>(*this, body, u, packed_, scratch_, f);
  return {broken};
}

double Rnp::strain_energy(const Body& body, const VectorField& u) const {
  std::vector<double> per;
  point_energies(body, u, per);
  return point_sum(per);
}

void Rnp::point_energies(const Body& body, const VectorField& u, std::vector<double>& per) const {
  const auto& bl = body.bonds;
  const auto n = static_cast<std::int64_t>(body.size());
  per.assign(body.size(), 0.0);
#pragma omp parallel for schedule(static)
  for (std::int64_t i = 0; i < n; ++i) {
    double e = 0;
    for (std::int64_t b = bl.offset[i]; b < bl.offset[i + 1]; ++b) {
      if (!bl.intact[b]) continue;
      const auto s = strain_of(body, u, dim, i, b);
      e += 0.5 * prefactor * C * J(s.len) * (1 - std::exp(-beta * s.len * s.S * s.S)) * bl.weight_of(b);
    }
    per[std::size_t(i)] = e * body.points.volume[std::size_t(i)];
  }
}

double Rnp::stable_time_step(const Body& body) const {
  const auto& bl = body.bonds;
  const double c = micromodulus();
  double dt = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < body.size(); ++i) {
    double k = 0;
    for (std::int64_t b = bl.offset[i]; b < bl.offset[i + 1]; ++b) {
      const double len = bond_geometry(body.points, body.bonds, i, b).len;
      k += c * J(len) * bl.weight_of(b) / len;
    }
    if (k > 0) dt = std::min(dt, std::sqrt(2 * body.density / k));
  }
  return dt;
}

void Rnp::damage(const Body& body, const VectorField& u, std::vector<double>& d) const {
  const auto& bl = body.bonds;
  const auto n = static_cast<std::int64_t>(body.size());
  d.assign(body.size(), 0.0);
  const double rc = critical_r();
#pragma omp parallel for schedule(static)
  for (std::int64_t i = 0; i < n; ++i) {
    double m = 0;
    for (std::int64_t b = bl.offset[i]; b < bl.offset[i + 1]; ++b)
      if (bl.intact[b]) {
        const auto s = strain_of(body, u, dim, i, b);
        m = std::max(m, std::sqrt(s.len) * std::abs(s.S) / rc);
      }
    d[std::size_t(i)] = m;
  }
}

std::size_t Rnp::softening_bonds(const Body& body, const VectorField& u) const {
  const auto& bl = body.bonds;
  const double rc2 = 0.5 / beta;
  std::size_t count = 0;
  for (std::size_t i = 0; i < body.size(); ++i)
    for (std::int64_t b = bl.offset[i]; b < bl.offset[i + 1]; ++b)
      if (bl.intact[b]) {
        const auto s = strain_of(body, u, dim, std::int64_t(i), b);
        count += s.len * s.S * s.S > rc2;
      }
  return count;
}

void Rnp::pair_forces(const Body& body, const VectorField& u, std::vector<double>& g) const {
  const auto& bl = body.bonds;
  const auto n = static_cast<std::int64_t>(body.size());
  g.assign(bl.size(), 0.0);
#pragma omp parallel for schedule(static)
  for (std::int64_t i = 0; i < n; ++i)
    for (std::int64_t b = bl.offset[i]; b < bl.offset[i + 1]; ++b) {
      if (!bl.intact[b]) continue;
      const auto s = strain_of(body, u, dim, i, b);
      g[std::size_t(b)] = prefactor * 2 * C * beta * J(s.len) * s.S * std::exp(-beta * s.len * s.S * s.S) * bl.weight_of(b);
    }
}

void Rnp::tangent(const Body& body, const VectorField& u, TangentBlocks& K) const {
  const auto& bl = body.bonds;
  const auto n = static_cast<std::int64_t>(body.size());
  const int d = dim;
  const std::size_t bs = std::size_t(d * d);
  K.dim = d;
  K.diagonal.assign(body.size() * bs, 0.0);
  K.bond.resize(bl.size() * bs);
#pragma omp parallel for schedule(static)
  for (std::int64_t i = 0; i < n; ++i) {
    double* diag = K.diagonal.data() + std::size_t(i) * bs;
    for (std::int64_t b = bl.offset[i]; b < bl.offset[i + 1]; ++b) {
      double* A = K.bond.data() + std::size_t(b) * bs;
      if (!bl.intact[b]) {
        for (std::size_t k = 0; k < bs; ++k) A[k] = 0;
        continue;
      }
      const auto s = strain_of(body, u, d, i, b);
      const double r2 = s.len * s.S * s.S;
      const double g2 = (2 * C * beta - 4 * C * beta * beta * r2) * std::exp(-beta * r2);  // g''(sqrt|xi| S)
      const double a = prefactor * J(s.len) * g2 / s.len * bl.weight_of(b);
      for (int r = 0; r < d; ++r)
        for (int c = 0; c < d; ++c) {
          A[r * d + c] = a * s.e[r] * s.e[c];
          diag[r * d + c] -= A[r * d + c];
        }
    }
  }
}

}  // namespace peridot
