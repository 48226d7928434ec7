module;
#include <omp.h>
#include <Eigen/Core>
#include <Eigen/Householder>
export module peridot.quadrature:weights;
import peridot.std;
import peridot.discretization;
import :reproducing_space;

export namespace peridot {

enum class QuadratureRule {
  volume,  // w_ji = volume of j (h^d on a lattice): the paper's naive comparison rule
  gmls,    // optimization-based quadrature, seed 000 eq. (4.4)
};

struct QuadratureOptions {
  QuadratureRule rule = QuadratureRule::gmls;
  ReproducingSpace space{};  // space.dim = 0 takes the cloud's
  // A point is not unisolvent when a pivot |R_kk| of the column-pivoted QR of its moment
  // matrix falls to rank_tolerance * |R_00| or below (condition estimate >= 1/rank_tolerance).
  double rank_tolerance = 1e-10;
  // Points that get the rule's weights, one flag per point; empty = all. The others get
  // equal-volume weights and no diagnostics. Meant for points whose ball the cloud does not
  // cover (the outer half of a 2 delta Dirichlet collar): no operator reads their weights
  // and they cannot be unisolvent.
  std::span<const std::uint8_t> active{};
};

// Per-point diagnostics; entries of points not active are 0.
struct QuadratureReport {
  QuadratureRule rule = QuadratureRule::gmls;
  std::size_t basis_size = 0;             // dim V_h
  std::size_t points = 0;                 // active points
  std::size_t bonds = 0;                  // bonds of the active points
  std::vector<double> residual;           // max_alpha |P w - g|_alpha / max_alpha |g|_alpha, unit-ball scaling
  std::vector<double> condition;          // |R_00| / |R_mm| of the pivoted QR of P^T (gmls only)
  std::vector<std::uint32_t> negative;    // negative weights of the point's ball
  std::size_t total_negative = 0;
  double max_residual = 0, max_condition = 0;
  double seconds = 0;                     // wall time of compute_weights
};

// Writes one weight per directed bond i->j into bonds.weight: the weight of partner j in the
// ball of i. GMLS weights minimise sum_j w_ji^2 subject to sum_j q(xi_ij) w_ji = the integral
// of q over B_delta(0) for every q in options.space, so they are computed over the full ball
// from every bond of i, whatever its role or intact flag: do it once, in the reference
// configuration, before anything breaks. Each point's problem is scaled to the unit ball and
// solved for the minimum-norm solution through a column-pivoted Householder QR of P^T.
// Throws std::invalid_argument for inconsistent inputs and std::runtime_error, naming the
// first failing point, when a point is not unisolvent; bonds.weight is then unspecified.
QuadratureReport compute_weights(const PointCloud& points, BondList& bonds, const QuadratureOptions& options = {});

// One line: rule, points, worst residual and condition, negative weights, time.
std::string summary(const QuadratureReport& report);

}  // namespace peridot

namespace peridot {

namespace {

using Eigen::Index;
using MatMap = Eigen::Map<Eigen::MatrixXd>;
using VecMap = Eigen::Map<Eigen::VectorXd>;
using ConstVecMap = Eigen::Map<const Eigen::VectorXd>;

enum class Status : std::uint8_t { ok, too_few, rank_deficient, coincident };

// One thread's scratch, a slice of a pool allocated before the parallel region.
struct Workspace {
  double* basis;   // P^T: n x m, column-major, kept for the residual
  double* qr;      // P^T factored in place
  double* w;       // n weights on the unit ball
  double* rhs;     // m
  double* tau;     // m Householder coefficients
  double* scratch; // m
  double* norm;    // 2 m column norms
  int* perm;       // m column transpositions
};

// Rows of P^T at the scaled bond vectors xi / delta of point i. False if two points coincide.
bool fill_basis(const ReproducingBasis& basis, const BondList& bl, std::size_t i, double inv_delta, MatMap& P) {
  const std::int64_t b0 = bl.begin(i);
  const Index n = P.rows();
  for (Index j = 0; j < n; ++j) {
    const double x = bl.xi[0][b0 + j] * inv_delta, y = bl.xi[1][b0 + j] * inv_delta, z = bl.xi[2][b0 + j] * inv_delta;
    if (x * x + y * y + z * z < 1e-24) return false;
    basis.evaluate(x, y, z, P.data() + j, std::size_t(n));
  }
  return true;
}

// Householder QR with column pivoting in place, A Pi = Q R (R in the upper triangle, the
// reflectors' essential parts below it). Stops at the first pivot that is not above
// tol * |R_00| and returns the numerical rank; condition = |R_00| / |R_{m-1,m-1}|.
// Column norms are downdated after each step and recomputed once cancellation has eaten
// half their digits (LAPACK xGEQP3's rule); they only choose pivots.
Index pivoted_qr(MatMap& A, const Workspace& ws, double tol, double& condition) {
  const Index n = A.rows(), m = A.cols();
  double* norm = ws.norm;       // squared norms of the trailing columns
  double* ref = ws.norm + m;    // their value at the last recomputation
  for (Index c = 0; c < m; ++c) norm[c] = ref[c] = A.col(c).squaredNorm();
  constexpr double recompute_below = 1.5e-8;  // ~sqrt(machine epsilon)
  double r00 = 0;
  for (Index k = 0; k < m; ++k) {
    const Index best = k + Index(std::max_element(norm + k, norm + m) - (norm + k));
    ws.perm[k] = int(best);
    if (best != k) {
      A.col(k).swap(A.col(best));
      std::swap(norm[k], norm[best]);
      std::swap(ref[k], ref[best]);
    }
    double beta;
    A.col(k).tail(n - k).makeHouseholderInPlace(ws.tau[k], beta);
    A(k, k) = beta;
    if (k == 0) r00 = std::abs(beta);
    if (!(std::abs(beta) > tol * r00)) {  // also catches a zero or NaN first pivot
      condition = std::numeric_limits<double>::infinity();
      return k;
    }
    if (k + 1 == m) break;
    A.block(k, k + 1, n - k, m - k - 1).applyHouseholderOnTheLeft(A.col(k).tail(n - k - 1), ws.tau[k], ws.scratch);
    for (Index c = k + 1; c < m; ++c) {
      norm[c] -= A(k, c) * A(k, c);
      if (norm[c] <= recompute_below * ref[c]) norm[c] = ref[c] = A.col(c).tail(n - k - 1).squaredNorm();
    }
  }
  condition = r00 / std::abs(A(m - 1, m - 1));
  return m;
}

// Minimum-norm w with P w = g, from A Pi = Q R where A = P^T: R^T (Q^T w) = Pi^T g, so
// w = Q [R^-T Pi^T g; 0].
void min_norm_solve(const MatMap& A, const Workspace& ws, const std::vector<double>& g, VecMap& w) {
  const Index n = A.rows(), m = A.cols();
  VecMap z(ws.rhs, m);
  z = ConstVecMap(g.data(), m);
  for (Index k = 0; k < m; ++k) std::swap(z[k], z[ws.perm[k]]);
  A.topLeftCorner(m, m).triangularView<Eigen::Upper>().transpose().solveInPlace(z);
  w.head(m) = z;
  w.tail(n - m).setZero();
  for (Index k = m - 1; k >= 0; --k) w.tail(n - k).applyHouseholderOnTheLeft(A.col(k).tail(n - k - 1), ws.tau[k], ws.scratch);
}

// max_alpha |(P w - g)_alpha| / max_alpha |g_alpha|.
double relative_residual(const MatMap& P, const VecMap& w, const std::vector<double>& g) {
  double r = 0, gmax = 0;
  for (Index a = 0; a < P.cols(); ++a) {
    r = std::max(r, std::abs(P.col(a).dot(w) - g[std::size_t(a)]));
    gmax = std::max(gmax, std::abs(g[std::size_t(a)]));
  }
  return gmax > 0 ? r / gmax : r;
}

void validate(const PointCloud& pc, const BondList& bl, const QuadratureOptions& o) {
  const auto fail = [](const std::string& what) { throw std::invalid_argument("quadrature: " + what); };
  if (pc.dim != 2 && pc.dim != 3) fail(fmt::format("point cloud dim must be 2 or 3 (got {})", pc.dim));
  if (bl.points() != pc.size())
    fail(fmt::format("the bond list covers {} points but the cloud has {}", bl.points(), pc.size()));
  if (!(bl.horizon > 0) || !std::isfinite(bl.horizon)) fail("bond list horizon must be a finite number > 0");
  for (const auto& v : bl.xi)
    if (v.size() != bl.size()) fail("bond vectors xi must have one entry per bond");
  if (bl.neighbor.size() != bl.size() || pc.volume.size() != pc.size()) fail("bond list or cloud arrays are inconsistent");
  if (o.space.dim != 0 && o.space.dim != pc.dim)
    fail(fmt::format("reproducing space dim must be 0 or the cloud's {} (got {})", pc.dim, o.space.dim));
  if (!(o.rank_tolerance > 0 && o.rank_tolerance < 1))
    fail(fmt::format("rank_tolerance must be in (0, 1) (got {})", o.rank_tolerance));
  if (!o.active.empty() && o.active.size() != pc.size())
    fail(fmt::format("active must be empty or have one flag per point ({}), got {}", pc.size(), o.active.size()));
}

std::string describe_point(const PointCloud& pc, std::size_t i) {
  const auto p = pc.position(i);
  return pc.dim == 3 ? fmt::format("point {} at ({:.6g}, {:.6g}, {:.6g})", i, p[0], p[1], p[2])
                     : fmt::format("point {} at ({:.6g}, {:.6g})", i, p[0], p[1]);
}

}  // namespace

QuadratureReport compute_weights(const PointCloud& pc, BondList& bl, const QuadratureOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  validate(pc, bl, o);
  ReproducingSpace space = o.space;
  if (space.dim == 0) space.dim = pc.dim;
  const ReproducingBasis basis(space);
  const std::size_t n = pc.size(), m = basis.size();
  const double delta = bl.horizon, inv_delta = 1 / delta, scale = std::pow(delta, pc.dim);
  const bool gmls = o.rule == QuadratureRule::gmls;
  const auto active = [&](std::size_t i) { return o.active.empty() || o.active[i] != 0; };

  QuadratureReport rep;
  rep.rule = o.rule;
  rep.basis_size = m;
  rep.residual.assign(n, 0.0);
  rep.condition.assign(n, 0.0);
  rep.negative.assign(n, 0);
  bl.weight.resize(bl.size());

  // Too few neighbours is the common failure: find it before any weight is written.
  std::size_t nmax = 0;
  std::vector<Status> status(n, Status::ok);
  for (std::size_t i = 0; i < n; ++i) {
    if (!active(i)) continue;
    ++rep.points;
    rep.bonds += bl.count(i);
    nmax = std::max(nmax, bl.count(i));
    if (gmls && bl.count(i) < m) status[i] = Status::too_few;
  }
  bool failed = std::any_of(status.begin(), status.end(), [](Status s) { return s != Status::ok; });

  const std::size_t per_thread = 2 * nmax * m + nmax + 5 * m;
  const int threads = omp_get_max_threads();
  std::vector<double> pool(failed ? 0 : std::size_t(threads) * per_thread);
  std::vector<int> perm_pool(failed ? 0 : std::size_t(threads) * m);
  const auto workspace = [&](int t) {
    double* p = pool.data() + std::size_t(t) * per_thread;
    double* small = p + 2 * nmax * m + nmax;  // the m-sized arrays
    return Workspace{p, p + nmax * m, p + 2 * nmax * m, small, small + m, small + 2 * m, small + 3 * m,
                     perm_pool.data() + std::size_t(t) * m};
  };
  const std::vector<double>& g = basis.unit_moments();

  if (!failed) {
#pragma omp parallel
    {
      const Workspace ws = workspace(omp_get_thread_num());
#pragma omp for schedule(dynamic, 64)
      for (std::int64_t ii = 0; ii < std::int64_t(n); ++ii) {
        const auto i = std::size_t(ii);
        const std::int64_t b0 = bl.begin(i);
        const Index nb = Index(bl.count(i));
        if (!active(i)) {
          for (Index j = 0; j < nb; ++j) bl.weight[b0 + j] = pc.volume[bl.neighbor[b0 + j]];
          continue;
        }
        MatMap P(ws.basis, nb, Index(m));
        VecMap w(ws.w, nb);
        if (!fill_basis(basis, bl, i, inv_delta, P)) {
          status[i] = Status::coincident;
          continue;
        }
        if (gmls) {
          MatMap A(ws.qr, nb, Index(m));
          A = P;
          if (pivoted_qr(A, ws, o.rank_tolerance, rep.condition[i]) < Index(m)) {
            status[i] = Status::rank_deficient;
            continue;
          }
          min_norm_solve(A, ws, g, w);
        } else {
          for (Index j = 0; j < nb; ++j) w[j] = pc.volume[bl.neighbor[b0 + j]] / scale;
        }
        rep.residual[i] = relative_residual(P, w, g);
        std::uint32_t neg = 0;
        for (Index j = 0; j < nb; ++j) {
          bl.weight[b0 + j] = w[j] * scale;
          neg += w[j] < 0;
        }
        rep.negative[i] = neg;
      }
    }
    failed = std::any_of(status.begin(), status.end(), [](Status s) { return s != Status::ok; });
  }

  if (failed) {
    const auto first = std::size_t(std::find_if(status.begin(), status.end(), [](Status s) { return s != Status::ok; }) -
                                   status.begin());
    const auto count = std::size_t(std::count_if(status.begin(), status.end(), [](Status s) { return s != Status::ok; }));
    const std::string where = describe_point(pc, first);
    const std::string more = count > 1 ? fmt::format(" ({} points fail in all)", count) : "";
    const std::string hint = pc.spacing > 0
                                 ? fmt::format("use a larger horizon_factor (delta/h is {:.4g} now)", delta / pc.spacing)
                                 : std::string("use a larger horizon");
    const std::size_t nb = bl.count(first);
    switch (status[first]) {
      case Status::too_few:
        throw std::runtime_error(fmt::format(
            "quadrature: {} is not unisolvent: it has {} neighbours but the {}-function reproducing space needs at "
            "least {}; {}{}",
            where, nb, m, m, hint, more));
      case Status::rank_deficient:
        throw std::runtime_error(fmt::format(
            "quadrature: {} is not unisolvent: the moment matrix of its {} neighbours is rank-deficient for the "
            "{}-function reproducing space (a QR pivot fell below rank_tolerance = {:g} of the largest; the neighbours "
            "are too few or too regular, e.g. collinear); {}{}",
            where, nb, m, o.rank_tolerance, hint, more));
      default:
        throw std::runtime_error(
            fmt::format("quadrature: {} coincides with one of its {} neighbours (zero bond length); remove duplicate "
                        "points{}",
                        where, nb, more));
    }
  }

  for (std::size_t i = 0; i < n; ++i) {
    rep.total_negative += rep.negative[i];
    rep.max_residual = std::max(rep.max_residual, rep.residual[i]);
    rep.max_condition = std::max(rep.max_condition, rep.condition[i]);
  }
  rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return rep;
}

std::string summary(const QuadratureReport& r) {
  const double share = r.bonds ? 100.0 * double(r.total_negative) / double(r.bonds) : 0.0;
  return fmt::format("{} weights ({}-function space) for {} points, {} bonds: max residual {:.2e}, max condition "
                     "{:.3g}, {} negative weights ({:.3f}%), {:.3f} s",
                     r.rule == QuadratureRule::gmls ? "gmls" : "volume", r.basis_size, r.points, r.bonds,
                     r.max_residual, r.max_condition, r.total_negative, share, r.seconds);
}

}  // namespace peridot
