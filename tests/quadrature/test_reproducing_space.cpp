#include <catch2/catch.hpp>
#include <array>
#include <cmath>
#include <stdexcept>
#include <vector>
import peridot.quadrature;

using namespace peridot;

namespace {

constexpr double pi = 3.14159265358979323846;

// Gauss-Legendre nodes and weights on [-1, 1] by Newton iteration on P_n.
struct Gauss {
  std::vector<double> x, w;
  explicit Gauss(int n) {
    for (int i = 0; i < n; ++i) {
      double t = std::cos(pi * (i + 0.75) / (n + 0.5)), dp = 0;
      for (int it = 0; it < 100; ++it) {
        double p0 = 1, p1 = t;
        for (int k = 2; k <= n; ++k) {
          const double p2 = ((2 * k - 1) * t * p1 - (k - 1) * p0) / k;
          p0 = p1;
          p1 = p2;
        }
        dp = n * (t * p1 - p0) / (t * t - 1);
        const double dt = p1 / dp;
        t -= dt;
        if (std::abs(dt) < 1e-16) break;
      }
      x.push_back(t);
      w.push_back(2 / ((1 - t * t) * dp * dp));
    }
  }
};

// Integral of xi^alpha/|xi|^p over B_delta(0) by Gauss-Legendre in r (and in cos(polar
// angle) in 3D) and the trapezoidal rule in the periodic azimuth.
double polar_quadrature(int dim, std::array<int, 3> a, int p, double delta) {
  const Gauss g(24);
  const int na = 48;
  double sum = 0;
  for (std::size_t ir = 0; ir < g.x.size(); ++ir) {
    const double r = 0.5 * delta * (g.x[ir] + 1), wr = 0.5 * delta * g.w[ir];
    const int k = a[0] + a[1] + a[2];
    const double radial = std::pow(r, k - p + dim - 1) * wr;  // r^k / r^p times the Jacobian r^(dim-1)
    for (int it = 0; it < na; ++it) {
      const double t = 2 * pi * it / na, wt = 2 * pi / na;
      if (dim == 2) {
        sum += radial * wt * std::pow(std::cos(t), a[0]) * std::pow(std::sin(t), a[1]);
        continue;
      }
      for (std::size_t iu = 0; iu < g.x.size(); ++iu) {
        const double u = g.x[iu], s = std::sqrt(1 - u * u);
        sum += radial * wt * g.w[iu] * std::pow(s * std::cos(t), a[0]) * std::pow(s * std::sin(t), a[1]) *
               std::pow(u, a[2]);
      }
    }
  }
  return sum;
}

}  // namespace

TEST_CASE("closed-form ball moments of xi^alpha/|xi|^p agree with polar and spherical quadrature to 1e-8") {
  for (int dim : {2, 3})
    for (int p : {1, 3})
      for (double delta : {1.0, 0.37}) {
        const ReproducingBasis basis({.dim = dim, .min_degree = std::max(0, p - dim + 1), .max_degree = 6, .radial_power = p});
        for (const auto& a : basis.exponents()) {
          const int k = a[0] + a[1] + a[2];
          const double exact = ball_moment(dim, a, p, delta);
          const double numeric = polar_quadrature(dim, a, p, delta);
          // Odd moments vanish: compare against the size of the integrand, |xi|^(k - p) over the ball.
          const double size = (dim == 2 ? 2 * pi : 4 * pi) * std::pow(delta, k - p + dim) / (k - p + dim);
          INFO("dim " << dim << " p " << p << " delta " << delta << " alpha " << a[0] << a[1] << a[2]);
          REQUIRE(std::abs(numeric - exact) <= 1e-8 * size);
        }
      }
}

TEST_CASE("ball moments match hand-computed values and scale as delta^(|alpha| - p + d)") {
  REQUIRE(ball_moment(2, {2, 0, 0}, 3, 1.0) == Approx(pi).epsilon(1e-14));
  REQUIRE(ball_moment(2, {2, 2, 0}, 3, 2.0) == Approx(8.0 / 3 * pi / 4).epsilon(1e-14));  // delta^3/3 * A(2,2) = pi/4
  REQUIRE(ball_moment(3, {2, 0, 0}, 3, 1.0) == Approx(2 * pi / 3).epsilon(1e-14));
  REQUIRE(ball_moment(3, {0, 0, 0}, 0, 1.0) == Approx(4 * pi / 3).epsilon(1e-14));       // volume of the unit ball
  REQUIRE(ball_moment(2, {0, 0, 0}, 0, 2.0) == Approx(4 * pi).epsilon(1e-14));           // area of the radius-2 disk
  REQUIRE(ball_moment(2, {3, 2, 0}, 3, 1.0) == 0.0);
  const ReproducingBasis basis({.dim = 3});
  for (std::size_t a = 0; a < basis.size(); ++a) {
    const auto& e = basis.exponents()[a];
    REQUIRE(basis.moment(a, 0.4) == Approx(ball_moment(3, e, 3, 0.4)).epsilon(1e-13).margin(1e-300));
  }
}

TEST_CASE("the default reproducing space has 18 functions in 2D and 52 in 3D and evaluates xi^alpha/|xi|^3") {
  const ReproducingBasis b2({.dim = 2}), b3({.dim = 3});
  REQUIRE(b2.size() == 18);
  REQUIRE(b3.size() == 52);
  const ReproducingBasis gradient({.dim = 2, .min_degree = 1, .max_degree = 3, .radial_power = 1});
  REQUIRE(gradient.size() == 9);  // Remark 4's cheaper space for the nonlocal gradient
  const double x = 0.31, y = -0.52, z = 0.17, r = std::sqrt(x * x + y * y + z * z);
  std::vector<double> v(b3.size());
  b3.evaluate(x, y, z, v.data());
  for (std::size_t a = 0; a < b3.size(); ++a) {
    const auto& e = b3.exponents()[a];
    const int k = e[0] + e[1] + e[2];
    REQUIRE(k >= 2);
    REQUIRE(k <= 5);
    REQUIRE(v[a] == Approx(std::pow(x, e[0]) * std::pow(y, e[1]) * std::pow(z, e[2]) / (r * r * r)).epsilon(1e-14));
  }
  // Strided output fills one column of a column-major matrix.
  std::vector<double> m(3 * b2.size(), -1.0);
  b2.evaluate(x, y, 0.0, m.data() + 1, 3);
  for (std::size_t a = 0; a < b2.size(); ++a) {
    REQUIRE(m[3 * a] == -1.0);
    REQUIRE(m[3 * a + 2] == -1.0);
    const auto& e = b2.exponents()[a];
    REQUIRE(m[3 * a + 1] == Approx(std::pow(x, e[0]) * std::pow(y, e[1]) / std::pow(std::hypot(x, y), 3)).epsilon(1e-14));
  }
}

TEST_CASE("an invalid or non-integrable reproducing space is rejected with a message naming the field") {
  REQUIRE_THROWS_WITH(ReproducingBasis({.dim = 4}), Catch::Contains("dim must be 2 or 3"));
  REQUIRE_THROWS_WITH(ReproducingBasis({.dim = 2, .min_degree = 4, .max_degree = 3}), Catch::Contains("min_degree"));
  REQUIRE_THROWS_WITH(ReproducingBasis({.dim = 2, .max_degree = 11}), Catch::Contains("max_degree"));
  // Constants over |xi|^3 in 2D: r^-2 is not integrable at the centre.
  REQUIRE_THROWS_WITH(ReproducingBasis({.dim = 2, .min_degree = 0}), Catch::Contains("radial_power"));
  REQUIRE_THROWS_AS(ball_moment(2, {1, 0, 0}, 3, 1.0), std::invalid_argument);
}
