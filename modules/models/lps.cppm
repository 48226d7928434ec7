module;
#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <stdexcept>
#include <vector>
export module peridot.models:lps;
import :body;
import :elastic;

export namespace peridot {

// Linear peridynamic solid of Yu, You & Trask (CMAME 2021), eqs. (2.1)-(2.2), (4.5)-(4.9),
// in 2D: kernel K = 1/r, C_alpha = 2, C_beta = 16, analytic m(delta) = 2 pi delta^3 / 3.
// The bond mask `intact` is gamma: 1 for partners in Omega (or the Dirichlet collar) with an
// unbroken bond; 0 for exterior Neumann points and broken bonds. With weights w_ji:
// w~ = w gamma (intact sums), w^ = w (1 - gamma) (missing-interaction sums).
struct Lps {
  int dim = 2;
  double delta = 0;                 // horizon [m]
  double m = 0;                     // weighted volume m(delta) [m^4 in 2D]
  double c_alpha = 2, c_beta = 16;
  std::vector<double> lambda, mu;   // per point Lame constants [Pa]

  // Homogeneous or heterogeneous body; one (lambda, mu) per point.
  static Lps make(int dim, double delta, std::vector<double> lambda, std::vector<double> mu);
  static Lps homogeneous(int dim, double delta, std::size_t points, ElasticConstants c);

  double kernel(double r) const { return 1.0 / r; }
  // Two-point moduli, eqs. (5.3)-(5.5): harmonic means (the common value if homogeneous).
  double lambda_ij(std::size_t i, std::size_t j) const { return harmonic(lambda[i], lambda[j]); }
  double mu_ij(std::size_t i, std::size_t j) const { return harmonic(mu[i], mu[j]); }
  static double harmonic(double a, double b) { return a == b ? a : 2.0 / (1.0 / a + 1.0 / b); }
};

// Per-point quantities from the intact weights: the dilatation correction M_i (3.2)/(4.8)
// (pseudo-inverse when singular) and the numerical normal n_i (4.9) with its tangent p_i.
struct LpsFrame {
  std::array<double, 4> M{1, 0, 0, 1};  // row-major 2x2
  std::array<double, 2> n{0, 0}, p{0, 0};
  bool has_missing = false;   // some partner has w^ != 0
  bool has_normal = false;    // n_i is defined (the intact first moment does not vanish)
};

LpsFrame lps_frame(const Body& body, const Lps& model, std::size_t i);

// The corrected dilatation (4.7): theta_i = d/m sum_j K(|xi|) xi . M_i (u_j - u_i) w~_ij over
// intact bonds. Exact for linear u on any ball, truncated or not, where M_i is regular.
double lps_dilatation(const Body& body, const Lps& model, const LpsFrame& frame, std::size_t i, const VectorField& u);

// Moore-Penrose pseudo-inverse of a symmetric 2x2 matrix (the inverse when regular).
std::array<double, 4> pseudo_inverse_sym2(const std::array<double, 4>& a);

}  // namespace peridot

namespace peridot {

Lps Lps::make(int dim, double delta, std::vector<double> lambda, std::vector<double> mu) {
  if (dim != 2) throw std::invalid_argument("lps: only the 2D model (d = 2) is implemented");
  if (!(delta > 0)) throw std::invalid_argument("lps: horizon must be > 0");
  if (lambda.size() != mu.size()) throw std::invalid_argument("lps: lambda and mu need one value per point");
  for (std::size_t i = 0; i < mu.size(); ++i)
    if (!(mu[i] > 0) || !std::isfinite(lambda[i])) throw std::invalid_argument("lps: need mu > 0 and a finite lambda at every point");
  Lps l;
  l.dim = dim;
  l.delta = delta;
  l.m = 2 * std::numbers::pi * delta * delta * delta / 3;
  l.lambda = std::move(lambda);
  l.mu = std::move(mu);
  return l;
}

Lps Lps::homogeneous(int dim, double delta, std::size_t points, ElasticConstants c) {
  return make(dim, delta, std::vector<double>(points, c.lambda), std::vector<double>(points, c.mu));
}

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

LpsFrame lps_frame(const Body& body, const Lps& model, std::size_t i) {
  const auto& bl = body.bonds;
  LpsFrame f;
  std::array<double, 4> S{0, 0, 0, 0};
  double first[2] = {0, 0}, total = 0;
  for (std::int64_t b = bl.offset[i]; b < bl.offset[i + 1]; ++b) {
    const double w = bl.weight[b];
    if (!bl.intact[b]) {
      f.has_missing = f.has_missing || w != 0.0;
      continue;
    }
    const double x = bl.xi[0][b], y = bl.xi[1][b], K = model.kernel(bl.length[b]);
    S[0] += K * x * x * w;
    S[1] += K * x * y * w;
    S[3] += K * y * y * w;
    first[0] += x * w;
    first[1] += y * w;
    total += std::abs(w);
  }
  S[2] = S[1];
  const double scale = model.dim / model.m;
  for (double& s : S) s *= scale;
  f.M = pseudo_inverse_sym2(S);
  const double len = std::hypot(first[0], first[1]);
  // Guard (4.9): a vanishing first moment (symmetric damage, isolated point) has no normal.
  if (f.has_missing && len > 1e-10 * model.delta * total) {
    f.has_normal = true;
    f.n = {-first[0] / len, -first[1] / len};
    f.p = {-f.n[1], f.n[0]};
  }
  return f;
}

double lps_dilatation(const Body& body, const Lps& model, const LpsFrame& f, std::size_t i, const VectorField& u) {
  const auto& bl = body.bonds;
  double th = 0;
  for (auto b = bl.offset[i]; b < bl.offset[i + 1]; ++b) {
    if (!bl.intact[b]) continue;
    const auto j = std::size_t(bl.neighbor[b]);
    const double x = bl.xi[0][b], y = bl.xi[1][b];
    const double mx = f.M[0] * x + f.M[1] * y, my = f.M[2] * x + f.M[3] * y;
    th += model.kernel(bl.length[b]) * (mx * (u[0][j] - u[0][i]) + my * (u[1][j] - u[1][i])) * bl.weight[b];
  }
  return model.dim / model.m * th;
}

}  // namespace peridot
