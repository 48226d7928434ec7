module;
#include "lean_kernel.h"

export module peridot.models:lps;
import peridot.std;
import :body;
import :elastic;
import :lean_records;

export namespace peridot {

// Moments of a point's missing interactions (w^ bonds) that (4.6) reads: every w^ sum there
// is a contraction of S1 = sum K w xi or T3 = sum K w xi (x) xi (x) xi / |xi|^2 with n (the
// tangential sums follow from these two, see Lps::missing_theta), so the sums survive a
// change of normal and can be kept for bonds that no longer exist.
struct MissingMoments {
  std::array<double, 3> s1{0, 0, 0};
  std::array<double, 10> t3{};  // xxx xxy xxz xyy xyz xzz yyy yyz yzz zzz (z entries stay 0 in 2D)
  double weight = 0;            // sum |w|
  bool any = false;

  void add(double Kw, double w, const std::array<double, 3>& xi, double r2) {
    weight += std::abs(w);
    for (int a = 0; a < 3; ++a) s1[std::size_t(a)] += Kw * xi[std::size_t(a)];
    const double c = Kw / r2;
    std::size_t k = 0;
    for (std::size_t a = 0; a < 3; ++a)
      for (std::size_t b = a; b < 3; ++b)
        for (std::size_t d = b; d < 3; ++d) t3[k++] += c * xi[a] * xi[b] * xi[d];
    any = any || Kw != 0.0;
  }
  MissingMoments& operator+=(const MissingMoments& o) {
    for (std::size_t k = 0; k < 3; ++k) s1[k] += o.s1[k];
    for (std::size_t k = 0; k < 10; ++k) t3[k] += o.t3[k];
    weight += o.weight;
    any = any || o.any;
    return *this;
  }
  // T3(n, n, n): each stored entry counts once per distinct permutation of its indices.
  double nnn(const std::array<double, 3>& n) const {
    double v = 0;
    std::size_t k = 0;
    for (std::size_t a = 0; a < 3; ++a)
      for (std::size_t b = a; b < 3; ++b)
        for (std::size_t d = b; d < 3; ++d) {
          const double permutations = (a == b && b == d) ? 1 : (a == b || b == d) ? 3 : 6;
          v += permutations * t3[k++] * n[a] * n[b] * n[d];
        }
    return v;
  }
  double s1n(const std::array<double, 3>& n) const { return s1[0] * n[0] + s1[1] * n[1] + s1[2] * n[2]; }
};

struct LpsFrame;

// Linear peridynamic solid of Yu, You & Trask (CMAME 2021), eqs. (2.1)-(2.2), (4.5)-(4.9),
// kernel K = 1/r. 2D: C_alpha = 2, C_beta = 16, analytic m(delta) = 2 pi delta^3 / 3.
// 3D: C_alpha = 3, C_beta = 30, m(delta) = pi delta^4 (the paper's constants for d = 3; its
// traction terms extended to 3D as Lps::missing_theta explains).
// The bond mask `intact` is gamma: 1 for partners in Omega (or the Dirichlet collar) with an
// unbroken bond; 0 for exterior Neumann points and broken bonds. With weights w_ji:
// w~ = w gamma (intact sums), w^ = w (1 - gamma) (missing-interaction sums).
struct Lps {
  int dim = 2;
  double delta = 0;                 // horizon [m]
  double m = 0;                     // weighted volume m(delta) [m^4 in 2D, m^5 in 3D]
  double c_alpha = 2, c_beta = 16;
  // n_i (4.9) exists when |sum xi w~| > normal_threshold delta sum |w^|: a flat surface gives
  // 0.42 (a half ball) to 1 (a thin cap); symmetric damage (both sides of a crack tip or of a
  // ligament) gives about 0, has no direction to load, and its w^ terms are skipped.
  double normal_threshold = 0.15;
  std::vector<double> lambda, mu;   // per point Lame constants [Pa]

  // Homogeneous or heterogeneous body; one (lambda, mu) per point.
  static Lps make(int dim, double delta, std::vector<double> lambda, std::vector<double> mu);
  static Lps homogeneous(int dim, double delta, std::size_t points, ElasticConstants c);

  double kernel(double r) const { return 1.0 / r; }
  // Two-point moduli, eqs. (5.3)-(5.5): harmonic means (the common value if homogeneous).
  double lambda_ij(std::size_t i, std::size_t j) const { return harmonic(lambda[i], lambda[j]); }
  double mu_ij(std::size_t i, std::size_t j) const { return harmonic(mu[i], mu[j]); }
  static double harmonic(double a, double b) { return a == b ? a : 2.0 / (1.0 / a + 1.0 / b); }

  // The operator of (4.6), written once for the static, explicit and implicit solvers as the
  // force density -L u + f_N. Per intact bond i -> j with K w = K(|xi|) w~_ji:
  //   f_i += theta_coefficient xi (theta_i + theta_j) + shear_coefficient xi (xi . (u_j - u_i))
  double theta_coefficient(std::size_t i, std::size_t j, double Kw) const { return c_alpha * (lambda_ij(i, j) - mu_ij(i, j)) * Kw / m; }
  double shear_coefficient(std::size_t i, std::size_t j, double Kw, double r2) const { return c_beta * mu_ij(i, j) * Kw / (m * r2); }
  // The w^ terms of (4.6)'s left side, a vector multiplying theta_i (the force carries -a theta_i).
  std::array<double, 3> missing_theta(std::size_t i, const LpsFrame& f) const;
  // f_N's w^ terms: the load of a traction vector T [Pa] over the moments of the loaded
  // partners, split along the frame's normal into T_n n and the tangential rest.
  std::array<double, 3> traction_load(const LpsFrame& f, const MissingMoments& loaded, const std::array<double, 3>& T) const;

  // ---- Dynamic fracture (seed 000 Sec. 6). Empty for the static solver. ----
  // A traction on the exterior points of a region: the vector T [Pa], or with `normal` the
  // normal traction T_n = T[0] along the numerical outward normal (a pressure p is T_n = -p),
  // scaled by history(t).
  struct Traction {
    std::array<double, 3> T{0, 0, 0};
    bool normal = false;
    std::function<double(double)> history;
  };
  double s0 = 0;                              // critical stretch (6.3); 0: nothing breaks
  std::vector<Traction> tractions;
  std::vector<std::int32_t> traction_of;      // per point: index into tractions, -1 for none
  std::vector<MissingMoments> exterior;       // per point: moments of its (removed) exterior partners
  std::vector<MissingMoments> loaded;         // per point: the part of `exterior` in its traction's region

  // 2D: eq. (6.3) with beta = 3 delta / (4 pi) and beta' = 0.23873 delta. 3D: the same energy
  // matching over a ball, critical_stretch_3d with K = lambda + 2 mu / 3.
  static double critical_stretch(double fracture_energy, double delta, ElasticConstants c, int dim = 2);

  // Caches M_i, the w^ theta vector and the unit-history traction load of every point;
  // call once the bonds, masks and tractions are final, before any force evaluation.
  void prepare(const Body& body) const;
  // Keeps the per-point data (moduli, traction regions, missing-partner moments) of the listed
  // points, in that order, and drops the caches: prepare() again on the body of those points.
  void restrict_to(std::span<const std::int64_t> ids);
  // Linear part -L u (no loads, no breaking): the operator the implicit solver inverts.
  void internal_forces(const Body& body, const VectorField& u, VectorField& f) const;
  // Adds the traction loads at time t.
  void add_loads(double t, VectorField& f) const;
  // Breaks every intact bond with s > s0 (6.2), both directions together, and refreshes the
  // cached frames of the points that lost a bond. Returns the directed bonds broken (a pair
  // counts twice).
  std::size_t break_bonds(Body& body, const VectorField& u) const;
  // Explicit step: break, then -L u + f_N(t) on the new masks.
  ForceReport forces(Body& body, const VectorField& u, VectorField& f, double t) const;
  ForceReport forces(Body& body, const VectorField& u, VectorField& f) const { return forces(body, u, f, 0.0); }
  // (1/2) sum_i V_i u_i . (L u)_i, the discrete operator's quadratic form [J/m].
  double strain_energy(const Body& body, const VectorField& u) const;
  // Each point's share of it, -V_i u_i . f_i / 2 with f = -L u, whose point_sum it is. On a
  // rank's part it is right for the owned points (their forces read the ghosts' dilatations).
  void point_energies(const Body& body, const VectorField& u, std::vector<double>& e) const;
  // 2 / omega_max from the largest |eigenvalue| of L / rho by power iteration [s]. On N ranks
  // (parts, with global ids) the iteration runs on the whole operator through the ghosts, from
  // the one-rank start vector and with exact norms, so every rank gets the one-rank step.
  double stable_time_step(const Body& body, const BodyParts& parts = {}) const;
  // Jacobi diagonal of L (the shear part), per component: a preconditioner for implicit steps.
  void stiffness_diagonal(const Body& body, VectorField& d) const;

  // forces() in single precision (discretization.list_precision: single, explicit steps): the
  // breaking-and-dilatation pass and the force pass run eight bonds at a time on the lean
  // kernel's fixed-point bond vectors and float displacements (lean_kernel.cpp), with M_i and
  // the weights rounded to float (the list keeps its double weights beside them; the bound is
  // in tests/models/test_lps_lean.cpp). Everything else (energies, the stable step, the frames
  // of points that lost a bond, the w^ terms and loads) stays double. A homogeneous body only:
  // prepare() throws std::invalid_argument otherwise, and forces() when the pair constants are
  // no normal floats. lean_vector: -1 the fastest kernel the CPU runs, 0 the portable one, 1 AVX2
  // (all the same bits), for tests.
  bool single_precision = false;
  int lean_vector = -1;
  bool single_precision_fits() const;

 private:
  void refresh(const Body& body, std::size_t i) const;
  void dilatations(const Body& body, const VectorField& u) const;
  // Refreshes the frames of the points marked dirty, clears the marks, returns those points.
  std::vector<std::int64_t> refresh_dirty(const Body& body) const;
  std::size_t break_sweep(Body& body, const VectorField& u, bool keep_theta) const;
  // f = -L u from the cached dilatations theta_.
  void forces_from_dilatations(const Body& body, const VectorField& u, VectorField& f) const;
  // forces() with single_precision: both passes on the lean kernel; returns the bonds broken.
  std::size_t forces_single(Body& body, const VectorField& u, VectorField& f) const;
  mutable std::vector<std::array<double, 6>> M_;   // xx, xy, xz, yy, yz, zz
  mutable std::vector<std::array<double, 3>> a_, g_;
  mutable std::vector<double> theta_;
  mutable std::vector<std::uint8_t> dirty_;
  mutable bool uniform_ = false;  // one (lambda, mu) for every point
  mutable VectorField scratch_;
  mutable std::vector<float> M_float_;              // M_ rounded, six a point (single_precision)
  mutable LargeArray<std::int32_t> lean_packed_;    // the lean kernel's records (single_precision)
};

// Per-point quantities from the intact weights: the dilatation correction M_i (3.2)/(4.8)
// (pseudo-inverse when singular) and the numerical normal n_i (4.9) with its tangent p_i,
// plus the moments of the missing interactions.
struct LpsFrame {
  std::array<double, 9> M{1, 0, 0, 0, 1, 0, 0, 0, 1};  // row-major 3x3 (2D: the upper 2x2 block)
  std::array<double, 3> n{0, 0, 0};
  MissingMoments missing;
  bool has_missing = false;   // some partner has w^ != 0
  bool has_normal = false;    // n_i is defined (the intact first moment does not vanish)
};

// `removed`: moments of missing partners no longer in the bond list (exterior points dropped
// after the weights were built, as in dynamic runs).
LpsFrame lps_frame(const Body& body, const Lps& model, std::size_t i, const MissingMoments* removed = nullptr);

// The corrected dilatation (4.7): theta_i = d/m sum_j K(|xi|) xi . M_i (u_j - u_i) w~_ij over
// intact bonds. Exact for linear u on any ball, truncated or not, where M_i is regular.
double lps_dilatation(const Body& body, const Lps& model, const LpsFrame& frame, std::size_t i, const VectorField& u);

// Moore-Penrose pseudo-inverse of a symmetric 2x2 or 3x3 matrix (the inverse when regular),
// row-major.
std::array<double, 4> pseudo_inverse_sym2(const std::array<double, 4>& a);
std::array<double, 9> pseudo_inverse_sym3(const std::array<double, 9>& a);

}  // namespace peridot

namespace peridot {

Lps Lps::make(int dim, double delta, std::vector<double> lambda, std::vector<double> mu) {
  if (dim != 2 && dim != 3) throw std::invalid_argument("lps: the model is 2D or 3D (d = 2 or 3)");
  if (!(delta > 0)) throw std::invalid_argument("lps: horizon must be > 0");
  if (lambda.size() != mu.size()) throw std::invalid_argument("lps: lambda and mu need one value per point");
  for (std::size_t i = 0; i < mu.size(); ++i)
    if (!(mu[i] > 0) || !std::isfinite(lambda[i])) throw std::invalid_argument("lps: need mu > 0 and a finite lambda at every point");
  Lps l;
  l.dim = dim;
  l.delta = delta;
  // m = int_B K |xi|^2 with K = 1/r: 2 pi int r^2 dr in 2D, 4 pi int r^3 dr in 3D.
  l.m = dim == 2 ? 2 * std::numbers::pi * delta * delta * delta / 3 : std::numbers::pi * delta * delta * delta * delta;
  if (dim == 3) l.c_alpha = 3, l.c_beta = 30;
  l.lambda = std::move(lambda);
  l.mu = std::move(mu);
  return l;
}

Lps Lps::homogeneous(int dim, double delta, std::size_t points, ElasticConstants c) {
  return make(dim, delta, std::vector<double>(points, c.lambda), std::vector<double>(points, c.mu));
}

// The 3x3 eigen-decomposition lives in a plain translation unit (pseudo_inverse.cpp), so that
// Eigen stays out of this module's BMI, which every solver, observer and test imports.
extern "C" void peridot_pseudo_inverse_sym3(const double* a, double* out);

std::array<double, 4> pseudo_inverse_sym2(const std::array<double, 4>& a) {
  const double det = a[0] * a[3] - a[1] * a[2];
  const double scale = std::abs(a[0]) + std::abs(a[3]) + 2 * std::abs(a[1]);
  if (scale == 0) return {0, 0, 0, 0};
  if (std::abs(det) > 1e-12 * scale * scale) return {a[3] / det, -a[1] / det, -a[2] / det, a[0] / det};
  // Rank one (or zero): a = s v v^T, pseudo-inverse = v v^T / s.
  const double s = a[0] + a[3];
  if (std::abs(s) < 1e-300) return {0, 0, 0, 0};
  return {a[0] / (s * s), a[1] / (s * s), a[2] / (s * s), a[3] / (s * s)};
}

std::array<double, 9> pseudo_inverse_sym3(const std::array<double, 9>& a) {
  std::array<double, 9> out{};
  peridot_pseudo_inverse_sym3(a.data(), out.data());
  return out;
}

LpsFrame lps_frame(const Body& body, const Lps& model, std::size_t i, const MissingMoments* removed) {
  const auto& bl = body.bonds;
  const int d = model.dim;
  LpsFrame f;
  std::array<double, 9> S{};
  std::array<double, 3> first{0, 0, 0};
  for (std::int64_t b = bl.offset[i]; b < bl.offset[i + 1]; ++b) {
    const double w = bl.weight[b];
    const BondGeometry g = bond_geometry(body.points, bl, i, b);
    const std::array<double, 3> xi{g.xi[0], g.xi[1], d == 3 ? g.xi[2] : 0.0};
    const double K = model.kernel(g.len);
    if (!bl.intact[b]) {
      if (w != 0.0) f.missing.add(K * w, w, xi, g.len * g.len);
      continue;
    }
    for (int r = 0; r < d; ++r) {
      for (int c = r; c < d; ++c) S[std::size_t(3 * r + c)] += K * xi[std::size_t(r)] * xi[std::size_t(c)] * w;
      first[std::size_t(r)] += xi[std::size_t(r)] * w;
    }
  }
  if (removed) f.missing += *removed;
  f.has_missing = f.missing.any;
  const double scale = model.dim / model.m;
  for (int r = 0; r < d; ++r)
    for (int c = r; c < d; ++c) S[std::size_t(3 * c + r)] = S[std::size_t(3 * r + c)] *= scale;
  if (d == 2) {
    const auto M = pseudo_inverse_sym2({S[0], S[1], S[3], S[4]});
    f.M = {M[0], M[1], 0, M[2], M[3], 0, 0, 0, 0};
  } else {
    f.M = pseudo_inverse_sym3(S);
  }
  const double len = std::sqrt(first[0] * first[0] + first[1] * first[1] + first[2] * first[2]);
  // Guard (4.9): a vanishing first moment (symmetric damage, isolated point) has no normal.
  if (f.has_missing && len > model.normal_threshold * model.delta * f.missing.weight) {
    f.has_normal = true;
    f.n = {-first[0] / len, -first[1] / len, -first[2] / len};
  }
  return f;
}

// (3.3) reads two w^ moments against the frame: A = int K xi_n^3 / |xi|^2 and, in 2D,
// B = int K xi_n xi_p^2 / |xi|^2. Because xi_p^2 = |xi|^2 - xi_n^2 there, B = S1.n - A. In 3D
// the same derivation (the missing shear term of (2.1) under sigma n = T, for a missing region
// symmetric about n) splits the tangential part |xi|^2 - xi_n^2 evenly between two tangents,
// so B = (S1.n - A) / 2 and the tangential load is along the tangential traction; the 2D
// formulas hold with B = (S1.n - A) / (d - 1) and T_p p replaced by T - T_n n.
namespace {
struct FrameMoments {
  double A = 0, B = 0;
};
FrameMoments frame_moments(const MissingMoments& w, const std::array<double, 3>& n, int dim) {
  const double A = w.nnn(n);
  return {A, (w.s1n(n) - A) / (dim - 1)};
}
}  // namespace

std::array<double, 3> Lps::missing_theta(std::size_t i, const LpsFrame& f) const {
  if (!f.has_missing || !f.has_normal) return {0, 0, 0};
  const double lam = lambda[i], mu_i = mu[i];
  const auto [A, B] = frame_moments(f.missing, f.n, dim);
  const double along_n = (-c_beta * (lam + 2 * mu_i) * B + c_beta * lam * A) / 2;
  std::array<double, 3> a{};
  for (std::size_t k = 0; k < 3; ++k) a[k] = (-2 * c_alpha * (lam - mu_i) * f.missing.s1[k] + along_n * f.n[k]) / m;
  return a;
}

std::array<double, 3> Lps::traction_load(const LpsFrame& f, const MissingMoments& w, const std::array<double, 3>& T) const {
  if (!f.has_normal || !w.any) return {0, 0, 0};
  const auto [A, B] = frame_moments(w, f.n, dim);
  const double Tn = T[0] * f.n[0] + T[1] * f.n[1] + T[2] * f.n[2];
  const double ct = c_beta * B / m, cn = c_beta * Tn * (A - B) / (2 * m);
  std::array<double, 3> g{};
  for (std::size_t k = 0; k < 3; ++k) g[k] = ct * (T[k] - Tn * f.n[k]) + cn * f.n[k];
  return g;
}

double Lps::critical_stretch(double G0, double delta, ElasticConstants c, int dim) {
  if (!(G0 > 0) || !(delta > 0)) throw std::invalid_argument("lps: critical stretch needs G0 > 0 and delta > 0");
  if (dim == 3) {
    const double K = c.lambda + 2 * c.mu / 3;
    if (!(K > 0)) throw std::invalid_argument("lps: the bulk modulus lambda + 2 mu / 3 must be > 0 for a critical stretch");
    return critical_stretch_3d(G0, K, delta);
  }
  const double beta = 3 * delta / (4 * std::numbers::pi), beta_prime = 0.23873 * delta;
  const double denominator = 4 * (c.lambda - c.mu) * beta_prime + 8 * c.mu * beta;
  if (!(denominator > 0)) throw std::invalid_argument("lps: 4 (lambda - mu) beta' + 8 mu beta must be > 0 for a critical stretch");
  return std::sqrt(G0 / denominator);
}

void Lps::refresh(const Body& body, std::size_t i) const {
  const auto f = lps_frame(body, *this, i, exterior.empty() ? nullptr : &exterior[i]);
  M_[i] = {f.M[0], f.M[1], f.M[2], f.M[4], f.M[5], f.M[8]};
  if (!M_float_.empty())
    for (std::size_t c = 0; c < 6; ++c) M_float_[6 * i + c] = float(M_[i][c]);
  a_[i] = missing_theta(i, f);
  g_[i] = {0, 0, 0};
  if (!traction_of.empty() && traction_of[i] >= 0) {
    const auto& t = tractions[std::size_t(traction_of[i])];
    // A normal traction T_n = T[0] lies along the numerical normal.
    const std::array<double, 3> T = t.normal ? std::array<double, 3>{t.T[0] * f.n[0], t.T[0] * f.n[1], t.T[0] * f.n[2]} : t.T;
    g_[i] = traction_load(f, loaded[i], T);
  }
}

void Lps::restrict_to(std::span<const std::int64_t> ids) {
  const auto pick = [&](auto& v) {
    if (v.empty()) return;
    std::remove_reference_t<decltype(v)> mine(ids.size());
    for (std::size_t j = 0; j < ids.size(); ++j) mine[j] = v.at(std::size_t(ids[j]));
    v = std::move(mine);
  };
  pick(lambda);
  pick(mu);
  pick(traction_of);
  pick(exterior);
  pick(loaded);
  M_ = {};
  M_float_ = {};
  a_ = {};
  g_ = {};
  theta_ = {};
  dirty_ = {};
  scratch_ = {};
}

void Lps::prepare(const Body& body) const {
  const auto n = body.size();
  if (lambda.size() != n) throw std::invalid_argument("lps: the model needs one (lambda, mu) per point");
  if (!exterior.empty() && exterior.size() != n) throw std::invalid_argument("lps: exterior moments need one entry per point");
  if (body.dim() != dim) throw std::invalid_argument(fmt::format("lps: a {}D model on a {}D body", dim, body.dim()));
  M_.assign(n, {1, 0, 0, 1, 0, 1});
  a_.assign(n, {0, 0, 0});
  g_.assign(n, {0, 0, 0});
  theta_.assign(n, 0.0);
  dirty_.assign(n, 0);
  scratch_ = zero_field(n);
  uniform_ = n > 0 && std::ranges::all_of(lambda, [&](double l) { return l == lambda[0]; }) &&
             std::ranges::all_of(mu, [&](double v) { return v == mu[0]; });
  if (single_precision && n > 0 && !uniform_)
    throw std::invalid_argument("lps: single precision runs a homogeneous body only (one lambda and mu); set discretization.list_precision: double");
  M_float_.clear();  // made again at the next single-precision pass, from these frames
#pragma omp parallel for schedule(dynamic, 256)
  for (std::int64_t i = 0; i < std::int64_t(n); ++i) refresh(body, std::size_t(i));
}

namespace {

// The per-bond loops are templates on the dimension D, so the 2D kernels read and write two
// components only, as before 3D existed.
template <class F>
decltype(auto) with_dimension(int dim, F&& f) {
  if (dim == 3) return f(std::integral_constant<int, 3>{});
  return f(std::integral_constant<int, 2>{});
}

// M_i (packed symmetric) times xi.
template <int D>
inline std::array<double, D> times(const std::array<double, 6>& M, const double* xi) {
  if constexpr (D == 2) return {M[0] * xi[0] + M[1] * xi[1], M[1] * xi[0] + M[3] * xi[1]};
  else
    return {M[0] * xi[0] + M[1] * xi[1] + M[2] * xi[2], M[1] * xi[0] + M[3] * xi[1] + M[4] * xi[2],
            M[2] * xi[0] + M[4] * xi[1] + M[5] * xi[2]};
}

// The one pass over the intact bonds of i: with Break, first marks broken those with stretch
// (6.2) above s0 (neither end in no_fail); then sums the dilatation (4.7) with the cached M_i
// over the bonds left, d/m sum K w xi . M_i (u_j - u_i). Both directions of a bond see
// bit-identical current bond vectors (negated), so they break in the same pass without atomics.
// `broken` counts the bonds broken.
// xi and |xi| of bond b from i to j: from a full list's arrays (Stored) or from the positions (a
// compact list, bond_geometry's bits), here unrolled so that the bond loops keep vectorising.
template <int D, bool Stored>
[[gnu::always_inline]] inline double bond_xi(const Body& body, std::size_t i, std::size_t j, std::int64_t b, double (&xi)[D]) {
  const auto& bl = body.bonds;
  if constexpr (Stored) {
    for (int k = 0; k < D; ++k) xi[k] = bl.xi[k][b];
    return bl.length[b];
  } else {
    double e[3] = {0, 0, 0};
    for (int k = 0; k < D; ++k) xi[k] = e[k] = body.points.x[std::size_t(k)][j] - body.points.x[std::size_t(k)][i];
    return bond_length(e[0], e[1], e[2]);
  }
}

template <int D, bool Break, bool Stored>
inline double sweep_bonds(std::conditional_t<Break, Body&, const Body&> body, const VectorField& u, double s0,
                          const std::array<double, 6>& Mi, double scale, std::size_t i, std::size_t& broken) {
  auto& bl = body.bonds;
  const bool fails_i = Break && s0 > 0 && (body.no_fail.empty() || !body.no_fail[i]);
  const double stretch2 = (1 + s0) * (1 + s0);
  double th = 0;
  for (std::int64_t b = bl.offset[i]; b < bl.offset[i + 1]; ++b) {
    if (!bl.intact[b]) continue;
    const auto j = std::size_t(bl.neighbor[b]);
    double xi[D], du[D];
    const double L = bond_xi<D, Stored>(body, i, j, b, xi);
    for (int k = 0; k < D; ++k) du[k] = u[std::size_t(k)][j] - u[std::size_t(k)][i];
    if constexpr (Break) {
      if (fails_i && (body.no_fail.empty() || !body.no_fail[j])) {
        double y2 = 0;
        for (int k = 0; k < D; ++k) {
          const double y = xi[k] + du[k];
          y2 += y * y;
        }
        if (y2 > stretch2 * L * L) {
          bl.intact[b] = 0;
          ++broken;
          continue;
        }
      }
    }
    const auto Mx = times<D>(Mi, xi);
    double dot = 0;
    for (int k = 0; k < D; ++k) dot += Mx[std::size_t(k)] * du[k];
    th += bl.weight[b] / L * dot;
  }
  return scale * th;
}

template <int D>
inline double dilatation_of(const Body& body, const std::array<double, 6>& Mi, double scale, std::size_t i, const VectorField& u) {
  std::size_t none = 0;
  return body.bonds.stores_geometry() ? sweep_bonds<D, false, true>(body, u, 0, Mi, scale, i, none)
                                      : sweep_bonds<D, false, false>(body, u, 0, Mi, scale, i, none);
}

}  // namespace

void Lps::dilatations(const Body& body, const VectorField& u) const {
  const double scale = dim / m;
  const auto n = static_cast<std::int64_t>(body.size());
  with_dimension(dim, [&]<int D>(std::integral_constant<int, D>) {
#pragma omp parallel for schedule(static)
    for (std::int64_t i = 0; i < n; ++i) theta_[i] = dilatation_of<D>(body, M_[i], scale, std::size_t(i), u);
  });
}

void Lps::internal_forces(const Body& body, const VectorField& u, VectorField& f) const {
  if (M_.size() != body.size()) throw std::logic_error("lps: prepare() was not called for this body");
  dilatations(body, u);
  forces_from_dilatations(body, u, f);
}

void Lps::forces_from_dilatations(const Body& body, const VectorField& u, VectorField& f) const {
  const auto& bl = body.bonds;
  const auto n = static_cast<std::int64_t>(body.size());
  // A homogeneous body (every deck but an inclusion's) has the bond coefficients of
  // theta_coefficient and shear_coefficient as two constants times K w and K w / |xi|^2: no
  // per-bond reads of the partner's (lambda, mu), one division per bond instead of three.
  // (Both at K w = |xi|^2 = 1, bit for bit the constants.)
  const double ct = uniform_ ? theta_coefficient(0, 0, 1.0) : 0, cs = uniform_ ? shear_coefficient(0, 0, 1.0, 1.0) : 0;
  with_dimension(dim, [&]<int D>(std::integral_constant<int, D>) {
    const auto pass = [&]<bool Uniform, bool Stored>(std::bool_constant<Uniform>, std::bool_constant<Stored>) {
#pragma omp parallel for schedule(static)
      for (std::int64_t ii = 0; ii < n; ++ii) {
        const auto i = std::size_t(ii);
        double f0 = 0, f1 = 0, f2 = 0;
        const double ti = theta_[i];
        // Branch-free over a point's bonds (a broken bond adds zero), so the loop vectorises.
#pragma omp simd reduction(+ : f0, f1, f2)
        for (std::int64_t b = bl.offset[i]; b < bl.offset[i + 1]; ++b) {
          const auto j = std::size_t(bl.neighbor[b]);
          double xi[D];
          const double L = bond_xi<D, Stored>(body, i, j, b, xi);
          double xu = 0;
          for (int k = 0; k < D; ++k) xu += xi[k] * (u[std::size_t(k)][j] - u[std::size_t(k)][i]);
          double t, s;
          if constexpr (Uniform) {
            const double inv = 1.0 / L, Kw = bl.weight[b] * inv;
            t = ct * Kw * (ti + theta_[j]);
            s = cs * Kw * inv * inv * xu;
          } else {
            const double Kw = bl.weight[b] / L;
            t = theta_coefficient(i, j, Kw) * (ti + theta_[j]);
            s = shear_coefficient(i, j, Kw, L * L) * xu;
          }
          const double g = bl.intact[b] ? t + s : 0.0;
          f0 += g * xi[0];
          if constexpr (D > 1) f1 += g * xi[1];
          if constexpr (D > 2) f2 += g * xi[2];
        }
        const double fi[3] = {f0, f1, f2};
        for (int k = 0; k < D; ++k) f[std::size_t(k)][i] = fi[k] - a_[i][std::size_t(k)] * ti;
      }
    };
    const bool stored = bl.stores_geometry();
    if (uniform_ && stored) pass(std::true_type{}, std::true_type{});
    else if (uniform_) pass(std::true_type{}, std::false_type{});
    else if (stored) pass(std::false_type{}, std::true_type{});
    else pass(std::false_type{}, std::false_type{});
  });
}

void Lps::add_loads(double t, VectorField& f) const {
  if (tractions.empty()) return;
  std::vector<double> scale(tractions.size());
  for (std::size_t k = 0; k < tractions.size(); ++k) scale[k] = tractions[k].history ? tractions[k].history(t) : 1.0;
  const auto n = static_cast<std::int64_t>(traction_of.size());
  const int d = dim;
#pragma omp parallel for schedule(static)
  for (std::int64_t i = 0; i < n; ++i)
    if (traction_of[i] >= 0) {
      const double h = scale[std::size_t(traction_of[i])];
      for (int k = 0; k < d; ++k) f[std::size_t(k)][i] += h * g_[i][std::size_t(k)];
    }
}

std::vector<std::int64_t> Lps::refresh_dirty(const Body& body) const {
  std::vector<std::int64_t> list;
  for (std::size_t i = 0; i < dirty_.size(); ++i)
    if (dirty_[i]) list.push_back(std::int64_t(i));
#pragma omp parallel for schedule(dynamic, 16)
  for (std::size_t k = 0; k < list.size(); ++k) {
    dirty_[std::size_t(list[k])] = 0;
    refresh(body, std::size_t(list[k]));
  }
  return list;
}

// The breaking pass over every point. With keep_theta it also stores each point's dilatation
// (scale = d/m) and sums it again for the points that lost a bond, whose M_i changed; every
// other point's M_i is unchanged, so the dilatations equal those of a breaking pass followed
// by internal_forces, bit for bit. Points that lost a bond get a new M_i, normal and w^ terms.
std::size_t Lps::break_sweep(Body& body, const VectorField& u, bool keep_theta) const {
  if (M_.size() != body.size()) throw std::logic_error("lps: prepare() was not called for this body");
  const double scale = keep_theta ? dim / m : 0.0;
  const auto n = static_cast<std::int64_t>(body.size());
  std::size_t broken = 0;
  const bool stored = body.bonds.stores_geometry();
  with_dimension(dim, [&]<int D>(std::integral_constant<int, D>) {
#pragma omp parallel for schedule(static) reduction(+ : broken)
    for (std::int64_t i = 0; i < n; ++i) {
      std::size_t k = 0;
      const double th = stored ? sweep_bonds<D, true, true>(body, u, s0, M_[i], scale, std::size_t(i), k)
                               : sweep_bonds<D, true, false>(body, u, s0, M_[i], scale, std::size_t(i), k);
      if (keep_theta) theta_[i] = th;
      if (k) dirty_[i] = 1;
      broken += k;
    }
    if (!broken) return;
    const auto again = refresh_dirty(body);
    if (!keep_theta) return;
#pragma omp parallel for schedule(static)
    for (std::size_t k = 0; k < again.size(); ++k) {
      const auto i = std::size_t(again[k]);
      theta_[i] = dilatation_of<D>(body, M_[i], scale, i, u);
    }
  });
  return broken;
}

std::size_t Lps::break_bonds(Body& body, const VectorField& u) const {
  if (!(s0 > 0)) return 0;
  return break_sweep(body, u, false);
}

// One pass breaks and sums the dilatations, instead of a breaking pass before internal_forces:
// the step reads the bonds twice, not three times.
ForceReport Lps::forces(Body& body, const VectorField& u, VectorField& f, double t) const {
  std::size_t broken = 0;
  if (single_precision) {
    broken = forces_single(body, u, f);
  } else {
    broken = break_sweep(body, u, true);
    forces_from_dilatations(body, u, f);
  }
  add_loads(t, f);
  return {broken};
}

namespace {

// The lean kernel's constants: theta_coefficient and shear_coefficient at K w = |xi|^2 = 1 (the
// unit q cancels in the pair force), and the breaking threshold on |y|^2 - |xi|^2.
PeridotLpsLean lean_constants(const Lps& m, const float* M) {
  const double s2 = m.s0 > 0 ? m.s0 * (2 + m.s0) : std::numeric_limits<double>::infinity();
  return {M, float(s2), float(m.theta_coefficient(0, 0, 1.0)), float(m.shear_coefficient(0, 0, 1.0, 1.0))};
}

}  // namespace

bool Lps::single_precision_fits() const {
  if (lambda.empty()) return true;
  const PeridotLpsLean k = lean_constants(*this, nullptr);
  const auto fits = [](float x) { return std::isfinite(x) && (x == 0 || std::abs(x) >= std::numeric_limits<float>::min()); };
  return fits(k.ct) && fits(k.cs) && k.cs != 0;
}

std::size_t Lps::forces_single(Body& body, const VectorField& u, VectorField& f) const {
  if (M_.size() != body.size()) throw std::logic_error("lps: prepare() was not called for this body");
  if (!single_precision_fits())
    throw std::invalid_argument(fmt::format("lps: the pair constants {:g} and {:g} lie outside single precision; set "
                                            "discretization.list_precision: double",
                                            theta_coefficient(0, 0, 1.0), shear_coefficient(0, 0, 1.0, 1.0)));
  auto& bl = body.bonds;
  if (bl.weight.empty() && bl.size() > 0) throw std::logic_error("lps: single precision needs the list's double weights");
  // The set-up makes the float weights; a list made otherwise gets them at its first pass (an
  // explicit run's weights are final after its set-up). M_i in float are made here after each
  // prepare(); refresh() keeps them with M_i from then on.
  bl.add_float_weights();
  if (M_float_.size() != 6 * M_.size()) {
    M_float_.resize(6 * M_.size());
    for (std::size_t i = 0; i < M_.size(); ++i)
      for (std::size_t c = 0; c < 6; ++c) M_float_[6 * i + c] = float(M_[i][c]);
  }
  pack_lean_records(body, u, delta, lean_packed_, "lps");
  const int vector = lean_vector < 0 ? peridot_pmb_lean_vector() : std::min(lean_vector, peridot_pmb_lean_vector());
  PeridotLpsLean k = lean_constants(*this, M_float_.data());
  const double theta_scale = dim / m * lean_unit(delta);
  const auto n = static_cast<std::int64_t>(body.size());
  const auto pass_over = [&](std::int64_t first, std::int64_t last, double* f0, double* f1, double* f2, std::uint8_t* dirty) {
    return PeridotLeanPass{bl.offset.data(), bl.neighbor.data(), bl.weight_f.data(), bl.intact.data(), lean_packed_.data(), f0, f1, f2,
                           0.0f, 0.0f, first, last, dirty};
  };
  // Pass 1: break, and sum the dilatations over the bonds left.
  constexpr std::int64_t rows_per_chunk = 256;
  const std::int64_t chunks = (n + rows_per_chunk - 1) / rows_per_chunk;
  std::size_t broken = 0;
#pragma omp parallel for schedule(static) reduction(+ : broken)
  for (std::int64_t c = 0; c < chunks; ++c) {
    const PeridotLeanPass pass = pass_over(c * rows_per_chunk, std::min(n, (c + 1) * rows_per_chunk), theta_.data(), nullptr, nullptr, dirty_.data());
    broken += peridot_lps_lean_dilatation_rows(&pass, &k, vector);
  }
  // Points that lost a bond have a new M_i: their frames, then their dilatations again.
  if (broken) {
    const auto again = refresh_dirty(body);
    k.s2 = std::numeric_limits<float>::infinity();
#pragma omp parallel for schedule(static)
    for (std::size_t c = 0; c < again.size(); ++c) {
      const PeridotLeanPass pass = pass_over(again[c], again[c] + 1, theta_.data(), nullptr, nullptr, nullptr);
      peridot_lps_lean_dilatation_rows(&pass, &k, vector);
    }
  }
  // Each record's last word carries its point's dilatation into pass 2.
  std::int32_t* rec = lean_packed_.data();
#pragma omp parallel for simd schedule(static)
  for (std::int64_t i = 0; i < n; ++i) {
    theta_[std::size_t(i)] *= theta_scale;
    rec[8 * i + 7] = std::bit_cast<std::int32_t>(float(theta_[std::size_t(i)]));
  }
  // Pass 2: the pair forces, then the w^ terms in double.
#pragma omp parallel for schedule(static)
  for (std::int64_t c = 0; c < chunks; ++c) {
    const PeridotLeanPass pass =
        pass_over(c * rows_per_chunk, std::min(n, (c + 1) * rows_per_chunk), f[0].data(), f[1].data(), dim == 3 ? f[2].data() : nullptr, nullptr);
    peridot_lps_lean_force_rows(&pass, &k, vector);
  }
  const int d = dim;
#pragma omp parallel for schedule(static)
  for (std::int64_t i = 0; i < n; ++i)
    for (int c = 0; c < d; ++c) f[std::size_t(c)][std::size_t(i)] -= a_[std::size_t(i)][std::size_t(c)] * theta_[std::size_t(i)];
  return broken;
}

double Lps::strain_energy(const Body& body, const VectorField& u) const {
  std::vector<double> per;
  point_energies(body, u, per);
  return point_sum(per);
}

void Lps::point_energies(const Body& body, const VectorField& u, std::vector<double>& e) const {
  if (M_.size() != body.size()) prepare(body);
  internal_forces(body, u, scratch_);
  e.resize(body.size());
  for (std::size_t i = 0; i < body.size(); ++i) {
    double ui_fi = 0;
    for (int k = 0; k < dim; ++k) ui_fi += u[std::size_t(k)][i] * scratch_[std::size_t(k)][i];
    e[i] = -0.5 * body.points.volume[i] * ui_fi;
  }
}

namespace {

// The start vector's generator (Knuth's MMIX LCG) after `draws` draws, by squaring the affine
// step: a rank starts each point where one rank's sequence has reached.
std::uint64_t lcg_after(std::uint64_t draws) {
  std::uint64_t a = 6364136223846793005ull, c = 1442695040888963407ull, A = 1, C = 0;
  for (; draws; draws >>= 1) {
    if (draws & 1) A *= a, C = a * C + c;
    c *= a + 1;
    a *= a;
  }
  return A * 0x9E3779B97F4A7C15ull + C;
}

}  // namespace

double Lps::stable_time_step(const Body& body, const BodyParts& parts) const {
  if (M_.size() != body.size()) prepare(body);
  const auto n = body.size();
  // Every rank takes part in the reductions below, an empty one too.
  const bool none = n == 0 || body.bonds.size() == 0 || !(body.density > 0);
  if (!parts.parted() && none) return std::numeric_limits<double>::infinity();
  // Power iteration on L from a fixed pseudo-random start: deterministic, a few dozen passes.
  VectorField v = zero_field(n), w = zero_field(n);
  for (std::size_t i = 0; i < n; ++i) {
    std::uint64_t state = lcg_after(std::uint64_t(parts.ids.empty() ? std::int64_t(i) : parts.ids[i]) * std::uint64_t(dim));
    for (int k = 0; k < dim; ++k) {
      state = state * 6364136223846793005ull + 1442695040888963407ull;
      v[std::size_t(k)][i] = double(state >> 11) / double(1ull << 53) - 0.5;
    }
  }
  const auto norm = [&](const VectorField& a) { return std::sqrt(owned_dot(parts, a, a, n, dim)); };
  double lambda_max = 0;
  for (int it = 0; it < 80; ++it) {
    const double nv = norm(v);
    if (!(nv > 0)) break;
    for (int k = 0; k < dim; ++k)
      for (auto& x : v[std::size_t(k)]) x /= nv;
    parts.refresh(v);
    internal_forces(body, v, w);
    lambda_max = norm(w);
    std::swap(v, w);
  }
  if (parts.parted() && !(body.density > 0)) return std::numeric_limits<double>::infinity();
  // Power iteration approaches the largest eigenvalue from below: 5 % margin.
  const double omega = std::sqrt(1.05 * lambda_max / body.density);
  return omega > 0 ? 2.0 / omega : std::numeric_limits<double>::infinity();
}

void Lps::stiffness_diagonal(const Body& body, VectorField& d) const {
  const auto& bl = body.bonds;
  const auto n = static_cast<std::int64_t>(body.size());
  with_dimension(dim, [&]<int D>(std::integral_constant<int, D>) {
#pragma omp parallel for schedule(static)
    for (std::int64_t ii = 0; ii < n; ++ii) {
      const auto i = std::size_t(ii);
      double di[D] = {};
      for (std::int64_t b = bl.offset[i]; b < bl.offset[i + 1]; ++b) {
        if (!bl.intact[b]) continue;
        const BondGeometry g = bond_geometry(body.points, bl, i, b);
        const double L = g.len;
        const double c = shear_coefficient(i, std::size_t(bl.neighbor[b]), bl.weight[b] / L, L * L);
        for (int k = 0; k < D; ++k) di[k] += c * g.xi[k] * g.xi[k];
      }
      for (int k = 0; k < D; ++k) d[std::size_t(k)][i] = di[k];
    }
  });
}

double lps_dilatation(const Body& body, const Lps& model, const LpsFrame& f, std::size_t i, const VectorField& u) {
  const std::array<double, 6> M{f.M[0], f.M[1], f.M[2], f.M[4], f.M[5], f.M[8]};
  return with_dimension(model.dim, [&]<int D>(std::integral_constant<int, D>) { return dilatation_of<D>(body, M, model.dim / model.m, i, u); });
}

}  // namespace peridot
