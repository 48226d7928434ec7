export module peridot.quadrature:reproducing_space;
import peridot.std;

export namespace peridot {

// The functions a quadrature rule over the ball B_delta(0) must integrate exactly:
//   q_alpha(xi) = xi^alpha / |xi|^radial_power   for every multi-index alpha with
//   min_degree <= |alpha| <= max_degree.
// The default is seed 000's V_h (Theorem 4.1): quintic numerators over |xi|^3 that vanish to
// second order, 18 functions in 2D and 52 in 3D, so one rule serves every LPS operator.
// Operator-specific spaces are cheaper (Remark 4): the nonlocal gradient's
// {xi/|xi| (p(y) + p(x)) : p in P_2} is spanned componentwise by {radial_power = 1,
// min_degree = 1, max_degree = 3}.
struct ReproducingSpace {
  int dim = 0;            // 2 or 3; 0 = take the point cloud's
  int min_degree = 2;     // smallest |alpha|, >= 0
  int max_degree = 5;     // largest |alpha|, <= max_space_degree
  int radial_power = 3;   // p in |xi|^p; min_degree - p + dim > 0 keeps every q integrable
};

inline constexpr int max_space_degree = 10;

// Integral of the monomial w^alpha over the unit sphere S^{dim-1} (the unit circle in 2D):
// 2 prod_k Gamma((a_k + 1)/2) / Gamma((|alpha| + dim)/2) when every a_k is even, else 0.
double sphere_monomial_integral(int dim, const std::array<int, 3>& alpha);

// Integral of xi^alpha / |xi|^p over the ball B_delta(0) in dim dimensions; in polar form
// the radial factor is delta^e / e with e = |alpha| - p + dim, which must be > 0.
double ball_moment(int dim, const std::array<int, 3>& alpha, int radial_power, double delta);

// A validated reproducing space: its multi-indices (by degree, then descending powers of x,
// then of y) and their exact moments over the unit ball.
class ReproducingBasis {
 public:
  // Throws std::invalid_argument naming the offending field; dim must be 2 or 3 here.
  explicit ReproducingBasis(const ReproducingSpace& space);

  const ReproducingSpace& space() const { return space_; }
  std::size_t size() const { return exponent_.size(); }
  const std::vector<std::array<int, 3>>& exponents() const { return exponent_; }
  // Integral of q_alpha over B_1(0), in exponents() order.
  const std::vector<double>& unit_moments() const { return unit_moment_; }
  // Integral of q_alpha over B_delta(0) = delta^(|alpha| - p + dim) * unit moment.
  double moment(std::size_t a, double delta) const;
  // q_alpha(xi) for every alpha, written to out[a * stride]; xi must be non-zero.
  void evaluate(double x, double y, double z, double* out, std::size_t stride = 1) const;

 private:
  ReproducingSpace space_;
  std::vector<std::array<int, 3>> exponent_;
  std::vector<double> unit_moment_;
};

}  // namespace peridot

namespace peridot {

double sphere_monomial_integral(int dim, const std::array<int, 3>& alpha) {
  if (dim != 2 && dim != 3) throw std::invalid_argument(fmt::format("sphere_monomial_integral: dim must be 2 or 3 (got {})", dim));
  double num = 2;
  int degree = 0;
  for (int k = 0; k < dim; ++k) {
    if (alpha[k] < 0) throw std::invalid_argument("sphere_monomial_integral: exponents must be >= 0");
    if (alpha[k] % 2 != 0) return 0.0;  // odd in one coordinate: cancels over the sphere
    num *= std::tgamma(0.5 * (alpha[k] + 1));
    degree += alpha[k];
  }
  return num / std::tgamma(0.5 * (degree + dim));
}

double ball_moment(int dim, const std::array<int, 3>& alpha, int radial_power, double delta) {
  const int degree = alpha[0] + alpha[1] + (dim == 3 ? alpha[2] : 0);
  const int e = degree - radial_power + dim;
  if (e <= 0)
    throw std::invalid_argument(fmt::format(
        "ball_moment: xi^alpha/|xi|^{} with |alpha| = {} is not integrable over the {}D ball (needs |alpha| - p + dim > 0)",
        radial_power, degree, dim));
  const double angular = sphere_monomial_integral(dim, alpha);
  return angular == 0.0 ? 0.0 : angular * std::pow(delta, e) / e;
}

ReproducingBasis::ReproducingBasis(const ReproducingSpace& s) : space_(s) {
  if (s.dim != 2 && s.dim != 3)
    throw std::invalid_argument(fmt::format("reproducing space: dim must be 2 or 3 (got {})", s.dim));
  if (s.min_degree < 0 || s.min_degree > s.max_degree)
    throw std::invalid_argument(
        fmt::format("reproducing space: min_degree must be in [0, max_degree = {}] (got {})", s.max_degree, s.min_degree));
  if (s.max_degree > max_space_degree)
    throw std::invalid_argument(fmt::format("reproducing space: max_degree must be in [min_degree = {}, {}] (got {})",
                                            s.min_degree, max_space_degree, s.max_degree));
  if (s.min_degree - s.radial_power + s.dim <= 0)
    throw std::invalid_argument(fmt::format(
        "reproducing space: radial_power must be < min_degree + dim = {} so every basis function is integrable "
        "over the ball (got {})",
        s.min_degree + s.dim, s.radial_power));
  for (int k = s.min_degree; k <= s.max_degree; ++k)
    for (int a = k; a >= 0; --a) {
      if (s.dim == 2) {
        exponent_.push_back({a, k - a, 0});
        continue;
      }
      for (int b = k - a; b >= 0; --b) exponent_.push_back({a, b, k - a - b});
    }
  unit_moment_.reserve(exponent_.size());
  for (const auto& e : exponent_) unit_moment_.push_back(ball_moment(s.dim, e, s.radial_power, 1.0));
}

double ReproducingBasis::moment(std::size_t a, double delta) const {
  const auto& e = exponent_[a];
  return unit_moment_[a] * std::pow(delta, e[0] + e[1] + e[2] - space_.radial_power + space_.dim);
}

void ReproducingBasis::evaluate(double x, double y, double z, double* out, std::size_t stride) const {
  // Power tables, then one product per function: no pow() calls.
  std::array<double, max_space_degree + 1> px, py, pz;
  px[0] = py[0] = pz[0] = 1;
  for (int k = 1; k <= space_.max_degree; ++k) {
    px[k] = px[k - 1] * x;
    py[k] = py[k - 1] * y;
    pz[k] = pz[k - 1] * z;
  }
  const double r = std::sqrt(x * x + y * y + z * z);
  const double factor = space_.radial_power > 0 ? 1 / r : r;
  double radial = 1;  // |xi|^-p
  for (int k = 0; k < std::abs(space_.radial_power); ++k) radial *= factor;
  for (std::size_t a = 0; a < exponent_.size(); ++a) {
    const auto& e = exponent_[a];
    out[a * stride] = px[e[0]] * py[e[1]] * pz[e[2]] * radial;
  }
}

}  // namespace peridot
