export module peridot.analysis:stress;
import peridot.std;
import peridot.models;

export namespace peridot {

// A model that can report its bond forces one directed bond at a time: g_b = the force density
// on i along m_b = xi_b / |xi_b| (tension positive, quadrature weight included, 0 when broken).
// Every stress and flux below is a sum of these, so any such model gets them for free.
template <class M>
concept PairForceModel = requires(const M& m, const Body& body, const VectorField& u, std::vector<double>& g) {
  m.pair_forces(body, u, g);
};

// Peridynamic stress tensor per point [Pa], structure of arrays. zz, yz, xz are filled for 3D
// clouds only (bulk_stress) and stay empty in 2D.
struct StressField {
  std::vector<double> xx, yy, xy;
  std::vector<double> zz, yz, xz;
  std::size_t size() const { return xx.size(); }
};

// Seed 004 eq. (49): tau_i = 1/2 sum_b |xi_b| g_b m_b (x) m_b over i's own bonds. Needs only i's
// bonds, so it works on any cloud (meshes, perturbed points, 3D), but it is the true stress only
// where the neighbourhood is complete and the deformation homogeneous over it (bulk).
StressField bulk_stress(const Body& body, std::span<const double> g);

// Seed 004 eqs. (51)-(52) on a 2D lattice: the forces of all bonds jk (either order, j and k any
// points) that cross the two node segments through x_i, type-A bonds through the segment of
// normal x and type-B bonds through the one of normal y, each times Delta s = h / |cos| or
// h / |sin| (eq. 50). Unlike (49) it sees the missing bonds near a boundary (surface effect).
// Cost per point: every bond starting within the horizon of its segments (no global cache).
StressField lattice_stress(const LatticeGrid& grid, const Body& body, std::span<const double> g);

// Seed 004 eq. (53): traction [Pa] on the cell side `side` (odd line) with outward normal
// normal_sign * e_axis, (1 / h) sum alpha g_jk m_jk V_j over the bonds crossing it along the
// normal. No 1/2 and no Delta s: each bond crosses the side once.
std::array<double, 2> force_flux(const LatticeGrid& grid, const Body& body, std::span<const double> g, GridSegment side, int normal_sign);

// The stress of model `m` at displacement u: eqs. (51)-(52) when the cloud is a 2D lattice
// (valid up to the boundary), else eq. (49).
template <PairForceModel M>
StressField stress_field(const M& m, const Body& body, const VectorField& u) {
  std::vector<double> g;
  m.pair_forces(body, u, g);
  if (body.dim() == 2) {
    LatticeGrid grid;
    bool on_lattice = true;
    try {
      grid = lattice_grid(body.points);
    } catch (const std::invalid_argument&) {
      on_lattice = false;  // off-lattice cloud: no segments to cross
    }
    if (on_lattice) return lattice_stress(grid, body, g);
  }
  return bulk_stress(body, g);
}

}  // namespace peridot

namespace peridot {

namespace {

void check_forces(const Body& body, std::span<const double> g) {
  if (g.size() != body.bonds.size()) throw std::invalid_argument("stress: need one pair force per directed bond");
}

}  // namespace

StressField bulk_stress(const Body& body, std::span<const double> g) {
  check_forces(body, g);
  const auto& bl = body.bonds;
  const std::size_t n = body.size();
  const bool solid = body.dim() == 3;
  StressField s;
  s.xx.assign(n, 0.0), s.yy.assign(n, 0.0), s.xy.assign(n, 0.0);
  if (solid) s.zz.assign(n, 0.0), s.yz.assign(n, 0.0), s.xz.assign(n, 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    double t[6] = {0, 0, 0, 0, 0, 0};
    for (auto b = bl.begin(i); b < bl.end(i); ++b) {
      // 1/2 |xi| g m (x) m = 1/2 g xi (x) xi / |xi|.
      const Vec3 xi = bond_vector(body.points, bl, i, b);
      const double x = xi[0], y = xi[1], z = xi[2];
      const double c = 0.5 * g[std::size_t(b)] / peridot::norm(xi);
      t[0] += c * x * x, t[1] += c * y * y, t[2] += c * x * y;
      t[3] += c * z * z, t[4] += c * y * z, t[5] += c * x * z;
    }
    s.xx[i] = t[0], s.yy[i] = t[1], s.xy[i] = t[2];
    if (solid) s.zz[i] = t[3], s.yz[i] = t[4], s.xz[i] = t[5];
  }
  return s;
}

StressField lattice_stress(const LatticeGrid& grid, const Body& body, std::span<const double> g) {
  check_forces(body, g);
  if (body.dim() != 2 || grid.gx.size() != body.size()) throw std::invalid_argument("lattice stress: need the 2D lattice grid of this body");
  const auto& bl = body.bonds;
  const std::size_t n = body.size();
  StressField s;
  s.xx.assign(n, 0.0), s.yy.assign(n, 0.0), s.xy.assign(n, 0.0);
  // Both orders of each bond are visited: the 1/2 of eq. (51).
  for_each_node_crossing(grid, bl, [&](std::size_t i, std::size_t b, double alpha, std::size_t start, int axis) {
    const Vec3 xi = bond_vector(body.points, bl, start, std::int64_t(b));
    const double x = xi[0], y = xi[1];
    const double L = peridot::norm(xi), xa = std::abs(xi[std::size_t(axis)]);
    // alpha g m (x) m Delta s / 2, Delta s = h |xi| / |xi_axis|, m = xi / |xi|.
    const double c = 0.5 * alpha * g[b] * grid.h / (xa * L);
    s.xx[i] += c * x * x, s.yy[i] += c * y * y, s.xy[i] += c * x * y;
  });
  return s;
}

std::array<double, 2> force_flux(const LatticeGrid& grid, const Body& body, std::span<const double> g, GridSegment side, int normal_sign) {
  check_forces(body, g);
  if (normal_sign != 1 && normal_sign != -1) throw std::invalid_argument("force flux: normal_sign must be +1 or -1");
  if (side.line % 2 == 0) throw std::invalid_argument("force flux: the segment must be a cell side (odd line)");
  const auto& bl = body.bonds;
  std::array<double, 2> t{0, 0};
  for_each_crossing(grid, bl, side, normal_sign, false, [&](std::size_t b, double alpha, std::size_t j) {
    const Vec3 xi = bond_vector(body.points, bl, j, std::int64_t(b));
    const double c = alpha * g[b] * body.points.volume[j] / peridot::norm(xi);
    t[0] += c * xi[0], t[1] += c * xi[1];
  });
  t[0] /= grid.h, t[1] /= grid.h;
  return t;
}

}  // namespace peridot
