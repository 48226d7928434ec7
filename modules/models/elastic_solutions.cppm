module;
#include <array>
#include <cmath>
#include <functional>
#include <string>
export module peridot.models:elastic_solutions;
import peridot.geometry;
import :elastic;

export namespace peridot {

// Displacement and its gradient at a point, grad[2a + b] = d u_a / d x_b.
struct ElasticSample {
  std::array<double, 2> u{0, 0};
  std::array<double, 4> grad{0, 0, 0, 0};
};

// A closed-form 2D linear elastic solution: reference for convergence studies, Dirichlet
// data, body force f = -div sigma and tractions sigma n. Evaluated once per point, never in
// a hot loop, hence std::function.
struct ElasticSolution {
  std::string name;
  std::function<ElasticSample(const Vec3&)> field;
  std::function<ElasticConstants(const Vec3&)> material;
  std::function<std::array<double, 2>(const Vec3&)> body_force;

  std::array<double, 2> displacement(const Vec3& x) const { return field(x).u; }
  double dilatation(const Vec3& x) const {
    const auto g = field(x).grad;
    return g[0] + g[3];
  }
  // Cauchy stress sigma = lambda tr(eps) I + 2 mu eps, row-major 2x2 [Pa].
  std::array<double, 4> stress(const Vec3& x) const;
  std::array<double, 2> traction(const Vec3& x, const std::array<double, 2>& n) const {
    const auto s = stress(x);
    return {s[0] * n[0] + s[1] * n[1], s[2] * n[0] + s[3] * n[1]};
  }
};

// u = (3x + 2y, -x + 2y): seed 000 Sec. 5.1; f = 0.
ElasticSolution linear_patch(ElasticConstants c);
// u = (sin Ax sin Ay, -cos Ax cos Ay): seed 000 Sec. 5.2.
ElasticSolution manufactured_sine(double A, ElasticConstants c);
// Kirsch plate with a free hole of radius a under far-field sigma0 along x (Sec. 5.3a);
// kappa = (lambda + 3 mu)/(lambda + mu) covers plane strain (3 - 4 nu) and plane stress.
ElasticSolution kirsch_hole(double a, double sigma0, ElasticConstants c);
// Hollow disk R0 < r < R1 under internal pressure p0 (Sec. 5.3b): sigma_rr(R0) = -p0.
ElasticSolution hollow_disk(double R0, double R1, double p0, ElasticConstants c);
// Circular inclusion r < a in a matrix (Sec. 5.4), plane strain: the hydrostatic stress inside
// the inclusion is sigma_rr = sigma_tt = P; the matrix carries u_r = C_B r + C_C / r.
ElasticSolution circular_inclusion(double a, double P, ElasticConstants inclusion, ElasticConstants matrix);

}  // namespace peridot

namespace peridot {

namespace {

ElasticSolution homogeneous(std::string name, ElasticConstants c) {
  ElasticSolution s;
  s.name = std::move(name);
  s.material = [c](const Vec3&) { return c; };
  s.body_force = [](const Vec3&) { return std::array<double, 2>{0, 0}; };
  return s;
}

// u = A x + B x / r^2 (radial), with its gradient.
ElasticSample radial(const Vec3& x, double A, double B) {
  ElasticSample e;
  if (B == 0) {  // pure dilatation; also regular at the origin
    e.u = {A * x[0], A * x[1]};
    e.grad = {A, 0, 0, A};
    return e;
  }
  const double r2 = x[0] * x[0] + x[1] * x[1];
  e.u = {A * x[0] + B * x[0] / r2, A * x[1] + B * x[1] / r2};
  for (int a = 0; a < 2; ++a)
    for (int b = 0; b < 2; ++b) e.grad[2 * a + b] = (a == b ? A + B / r2 : 0.0) - 2 * B * x[a] * x[b] / (r2 * r2);
  return e;
}

}  // namespace

std::array<double, 4> ElasticSolution::stress(const Vec3& x) const {
  const auto g = field(x).grad;
  const auto c = material(x);
  const double tr = g[0] + g[3], shear = 0.5 * (g[1] + g[2]);
  return {c.lambda * tr + 2 * c.mu * g[0], 2 * c.mu * shear, 2 * c.mu * shear, c.lambda * tr + 2 * c.mu * g[3]};
}

ElasticSolution linear_patch(ElasticConstants c) {
  auto s = homogeneous("linear_patch", c);
  s.field = [](const Vec3& x) { return ElasticSample{{3 * x[0] + 2 * x[1], -x[0] + 2 * x[1]}, {3, 2, -1, 2}}; };
  return s;
}

ElasticSolution manufactured_sine(double A, ElasticConstants c) {
  auto s = homogeneous("manufactured_sine", c);
  s.field = [A](const Vec3& x) {
    const double sx = std::sin(A * x[0]), cx = std::cos(A * x[0]), sy = std::sin(A * x[1]), cy = std::cos(A * x[1]);
    return ElasticSample{{sx * sy, -cx * cy}, {A * cx * sy, A * sx * cy, A * sx * cy, A * cx * sy}};
  };
  const double k = 2 * (c.lambda + 2 * c.mu) * A * A;
  s.body_force = [A, k](const Vec3& x) {
    return std::array<double, 2>{k * std::sin(A * x[0]) * std::sin(A * x[1]), -k * std::cos(A * x[0]) * std::cos(A * x[1])};
  };
  return s;
}

ElasticSolution kirsch_hole(double a, double sigma0, ElasticConstants c) {
  auto s = homogeneous("kirsch_hole", c);
  const double kappa = (c.lambda + 3 * c.mu) / (c.lambda + c.mu), pre = sigma0 * a / (8 * c.mu);
  const auto u = [=](double x, double y) {
    const double r = std::hypot(x, y), t = std::atan2(y, x);
    const double ux = (r / a) * (kappa + 1) * std::cos(t) + (2 * a / r) * ((1 + kappa) * std::cos(t) + std::cos(3 * t)) -
                      (2 * a * a * a / (r * r * r)) * std::cos(3 * t);
    const double uy = (r / a) * (kappa - 3) * std::sin(t) + (2 * a / r) * ((1 - kappa) * std::sin(t) + std::sin(3 * t)) -
                      (2 * a * a * a / (r * r * r)) * std::sin(3 * t);
    return std::array<double, 2>{pre * ux, pre * uy};
  };
  s.field = [u, a](const Vec3& x) {
    // Fourth-order central differences: error ~ (1e-3 a)^4, far below any discretisation error.
    const double e = 1e-3 * a;
    ElasticSample out;
    out.u = u(x[0], x[1]);
    for (int b = 0; b < 2; ++b) {
      const auto at = [&](double k) { return b == 0 ? u(x[0] + k * e, x[1]) : u(x[0], x[1] + k * e); };
      const auto p1 = at(1), m1 = at(-1), p2 = at(2), m2 = at(-2);
      for (int c2 = 0; c2 < 2; ++c2) out.grad[2 * c2 + b] = (8 * (p1[c2] - m1[c2]) - (p2[c2] - m2[c2])) / (12 * e);
    }
    return out;
  };
  return s;
}

ElasticSolution hollow_disk(double R0, double R1, double p0, ElasticConstants c) {
  auto s = homogeneous("hollow_disk", c);
  const double d = R1 * R1 - R0 * R0;
  const double A = p0 * R0 * R0 / (2 * (c.lambda + c.mu) * d), B = p0 * R0 * R0 * R1 * R1 / (2 * c.mu * d);
  s.field = [A, B](const Vec3& x) { return radial(x, A, B); };
  return s;
}

ElasticSolution circular_inclusion(double a, double P, ElasticConstants in, ElasticConstants out) {
  ElasticSolution s;
  s.name = "circular_inclusion";
  const double CA = P / (2 * (in.lambda + in.mu));
  const double CB = P * (in.lambda + in.mu + out.mu) / (2 * (in.lambda + in.mu) * (out.lambda + 2 * out.mu));
  const double CC = -P * a * a * (in.lambda - out.lambda + in.mu - out.mu) / (2 * (in.lambda + in.mu) * (out.lambda + 2 * out.mu));
  s.field = [=](const Vec3& x) { return std::hypot(x[0], x[1]) < a ? radial(x, CA, 0.0) : radial(x, CB, CC); };
  s.material = [=](const Vec3& x) { return std::hypot(x[0], x[1]) < a ? in : out; };
  s.body_force = [](const Vec3&) { return std::array<double, 2>{0, 0}; };
  return s;
}

}  // namespace peridot
