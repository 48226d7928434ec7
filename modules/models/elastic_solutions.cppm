export module peridot.models:elastic_solutions;
import peridot.std;
import peridot.geometry;
import :elastic;

export namespace peridot {

// Displacement and its gradient at a point, grad[3a + b] = d u_a / d x_b. 2D solutions leave
// the z row and column zero.
struct ElasticSample {
  std::array<double, 3> u{0, 0, 0};
  std::array<double, 9> grad{};
};

// A closed-form linear elastic solution (2D or 3D): reference for convergence studies,
// Dirichlet data, body force f = -div sigma and tractions sigma n. Evaluated once per point,
// never in a hot loop, hence std::function.
struct ElasticSolution {
  std::string name;
  int dim = 2;
  std::function<ElasticSample(const Vec3&)> field;
  std::function<ElasticConstants(const Vec3&)> material;
  std::function<std::array<double, 3>(const Vec3&)> body_force;

  std::array<double, 3> displacement(const Vec3& x) const { return field(x).u; }
  double dilatation(const Vec3& x) const {
    const auto g = field(x).grad;
    return g[0] + g[4] + g[8];
  }
  // Cauchy stress sigma = lambda tr(eps) I + 2 mu eps, row-major 3x3 [Pa]; in 2D the in-plane
  // block (sigma_zz, which plane strain carries, is not part of any 2D traction).
  std::array<double, 9> stress(const Vec3& x) const;
  std::array<double, 3> traction(const Vec3& x, const std::array<double, 3>& n) const {
    const auto s = stress(x);
    std::array<double, 3> t{0, 0, 0};
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) t[a] += s[3 * a + b] * n[b];
    return t;
  }
};

// u = (3x + 2y, -x + 2y): seed 000 Sec. 5.1; f = 0. In 3D a full gradient,
// u = (3x + 2y + z, -x + 2y - z, x/2 + y + 2z).
ElasticSolution linear_patch(ElasticConstants c, int dim = 2);
// u = (sin Ax sin Ay, -cos Ax cos Ay): seed 000 Sec. 5.2. Its 3D extension (not in the paper)
// u = (sin Ax sin Ay sin Az, -cos Ax cos Ay sin Az, cos Ax sin Ay cos Az) has a non-zero
// dilatation and shear in every plane.
ElasticSolution manufactured_sine(double A, ElasticConstants c, int dim = 2);
// Kirsch plate with a free hole of radius a under far-field sigma0 along x (Sec. 5.3a);
// kappa = (lambda + 3 mu)/(lambda + mu) covers plane strain (3 - 4 nu) and plane stress.
ElasticSolution kirsch_hole(double a, double sigma0, ElasticConstants c);
// Hollow disk R0 < r < R1 under internal pressure p0 (Sec. 5.3b): sigma_rr(R0) = -p0.
ElasticSolution hollow_disk(double R0, double R1, double p0, ElasticConstants c);
// Circular inclusion r < a in a matrix (Sec. 5.4), plane strain: the hydrostatic stress inside
// the inclusion is sigma_rr = sigma_tt = P; the matrix carries u_r = C_B r + C_C / r.
ElasticSolution circular_inclusion(double a, double P, ElasticConstants inclusion, ElasticConstants matrix);
// Spherical inclusion r < a in a matrix, the 3D counterpart (not in the paper): the stress
// inside is hydrostatic, sigma = P I; the matrix carries u_r = C_B r + C_C / r^2.
ElasticSolution spherical_inclusion(double a, double P, ElasticConstants inclusion, ElasticConstants matrix);

}  // namespace peridot

namespace peridot {

namespace {

ElasticSolution homogeneous(std::string name, ElasticConstants c) {
  ElasticSolution s;
  s.name = std::move(name);
  s.material = [c](const Vec3&) { return c; };
  s.body_force = [](const Vec3&) { return std::array<double, 3>{0, 0, 0}; };
  return s;
}

// u = A x + B x / r^2 (radial), with its gradient.
ElasticSample radial(const Vec3& x, double A, double B) {
  ElasticSample e;
  if (B == 0) {  // pure dilatation; also regular at the origin
    e.u = {A * x[0], A * x[1], 0};
    e.grad = {A, 0, 0, 0, A, 0, 0, 0, 0};
    return e;
  }
  const double r2 = x[0] * x[0] + x[1] * x[1];
  e.u = {A * x[0] + B * x[0] / r2, A * x[1] + B * x[1] / r2, 0};
  for (int a = 0; a < 2; ++a)
    for (int b = 0; b < 2; ++b) e.grad[3 * a + b] = (a == b ? A + B / r2 : 0.0) - 2 * B * x[a] * x[b] / (r2 * r2);
  return e;
}

// u = A x + B x / r^3 (radial in 3D), with its gradient.
ElasticSample radial_3d(const Vec3& x, double A, double B) {
  ElasticSample e;
  if (B == 0) {  // pure dilatation; also regular at the origin
    e.u = {A * x[0], A * x[1], A * x[2]};
    e.grad = {A, 0, 0, 0, A, 0, 0, 0, A};
    return e;
  }
  const double r2 = x[0] * x[0] + x[1] * x[1] + x[2] * x[2], r3 = r2 * std::sqrt(r2);
  for (int a = 0; a < 3; ++a) {
    e.u[a] = A * x[a] + B * x[a] / r3;
    for (int b = 0; b < 3; ++b) e.grad[3 * a + b] = (a == b ? A + B / r3 : 0.0) - 3 * B * x[a] * x[b] / (r2 * r3);
  }
  return e;
}

// u_a = prod_b phi_ab(A x_b), every phi sine or cosine (one sign per component), with its
// gradient and Hessian: -div sigma follows in closed form for any such field.
struct TrigProduct {
  double A = 1;
  std::array<std::array<bool, 3>, 3> sine{};  // sine[a][b]: phi_ab = sin, else cos
  std::array<double, 3> sign{1, 1, 1};
  int dim = 3;

  // d^k/dt^k of sin or cos at t.
  static double derivative(bool sine, int k, double t) {
    const double s = std::sin(t), c = std::cos(t);
    static constexpr double sin_d[4][2] = {{0, 1}, {1, 0}, {0, -1}, {-1, 0}};  // (c, s) coefficients
    const int r = (k + (sine ? 0 : 1)) % 4;
    return sin_d[r][0] * c + sin_d[r][1] * s;
  }
  // d^(k0 + k1 + k2) u_a / dx^k0 dy^k1 dz^k2.
  double d(int a, std::array<int, 3> k, const Vec3& x) const {
    double v = sign[std::size_t(a)];
    for (int b = 0; b < dim; ++b) v *= std::pow(A, k[std::size_t(b)]) * derivative(sine[a][b], k[std::size_t(b)], A * x[b]);
    return v;
  }
  ElasticSample sample(const Vec3& x) const {
    ElasticSample e;
    for (int a = 0; a < dim; ++a) {
      e.u[std::size_t(a)] = d(a, {0, 0, 0}, x);
      for (int b = 0; b < dim; ++b) {
        std::array<int, 3> k{0, 0, 0};
        k[std::size_t(b)] = 1;
        e.grad[std::size_t(3 * a + b)] = d(a, k, x);
      }
    }
    return e;
  }
  // f = -div sigma = -(lambda + mu) grad div u - mu laplacian u.
  std::array<double, 3> body_force(const Vec3& x, ElasticConstants c) const {
    std::array<double, 3> f{0, 0, 0};
    for (int a = 0; a < dim; ++a)
      for (int b = 0; b < dim; ++b) {
        std::array<int, 3> ab{0, 0, 0}, bb{0, 0, 0};
        ++ab[std::size_t(a)], ++ab[std::size_t(b)];
        bb[std::size_t(b)] = 2;
        f[std::size_t(a)] -= (c.lambda + c.mu) * d(b, ab, x) + c.mu * d(a, bb, x);
      }
    return f;
  }
};

}  // namespace

std::array<double, 9> ElasticSolution::stress(const Vec3& x) const {
  const auto g = field(x).grad;
  const auto c = material(x);
  const double tr = g[0] + g[4] + g[8];
  std::array<double, 9> s{};
  for (int a = 0; a < dim; ++a)
    for (int b = 0; b < dim; ++b) s[std::size_t(3 * a + b)] = (a == b ? c.lambda * tr : 0.0) + c.mu * (g[std::size_t(3 * a + b)] + g[std::size_t(3 * b + a)]);
  return s;
}

ElasticSolution linear_patch(ElasticConstants c, int dim) {
  auto s = homogeneous("linear_patch", c);
  s.dim = dim;
  if (dim == 3)
    s.field = [](const Vec3& x) {
      return ElasticSample{{3 * x[0] + 2 * x[1] + x[2], -x[0] + 2 * x[1] - x[2], 0.5 * x[0] + x[1] + 2 * x[2]}, {3, 2, 1, -1, 2, -1, 0.5, 1, 2}};
    };
  else
    s.field = [](const Vec3& x) { return ElasticSample{{3 * x[0] + 2 * x[1], -x[0] + 2 * x[1], 0}, {3, 2, 0, -1, 2, 0, 0, 0, 0}}; };
  return s;
}

ElasticSolution manufactured_sine(double A, ElasticConstants c, int dim) {
  auto s = homogeneous("manufactured_sine", c);
  s.dim = dim;
  TrigProduct t;
  t.A = A;
  t.dim = dim;
  t.sine = {{{true, true, true}, {false, false, true}, {false, true, false}}};
  t.sign = {1, -1, 1};
  s.field = [t](const Vec3& x) { return t.sample(x); };
  s.body_force = [t, c](const Vec3& x) { return t.body_force(x, c); };
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
    const auto u0 = u(x[0], x[1]);
    out.u = {u0[0], u0[1], 0};
    for (int b = 0; b < 2; ++b) {
      const auto at = [&](double k) { return b == 0 ? u(x[0] + k * e, x[1]) : u(x[0], x[1] + k * e); };
      const auto p1 = at(1), m1 = at(-1), p2 = at(2), m2 = at(-2);
      for (int c2 = 0; c2 < 2; ++c2) out.grad[std::size_t(3 * c2 + b)] = (8 * (p1[c2] - m1[c2]) - (p2[c2] - m2[c2])) / (12 * e);
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
  s.body_force = [](const Vec3&) { return std::array<double, 3>{0, 0, 0}; };
  return s;
}

ElasticSolution spherical_inclusion(double a, double P, ElasticConstants in, ElasticConstants out) {
  ElasticSolution s;
  s.name = "spherical_inclusion";
  s.dim = 3;
  // Inside u = A x, so sigma = (3 lambda + 2 mu) A I = P I. Outside u = B x + C x / r^3 has
  // sigma_rr = (3 lambda + 2 mu) B - 4 mu C / r^3; u and sigma_rr continuous at r = a give
  // C = (A - B) a^3 and (3 lambda + 6 mu) B = P + 4 mu A (matrix lambda, mu).
  const double A = P / (3 * in.lambda + 2 * in.mu);
  const double B = (P + 4 * out.mu * A) / (3 * out.lambda + 6 * out.mu);
  const double C = (A - B) * a * a * a;
  const auto r = [](const Vec3& x) { return std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]); };
  s.field = [=](const Vec3& x) { return r(x) < a ? radial_3d(x, A, 0.0) : radial_3d(x, B, C); };
  s.material = [=](const Vec3& x) { return r(x) < a ? in : out; };
  s.body_force = [](const Vec3&) { return std::array<double, 3>{0, 0, 0}; };
  return s;
}

}  // namespace peridot
