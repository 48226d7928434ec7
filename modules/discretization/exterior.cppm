export module peridot.discretization:exterior;
import peridot.std;
import peridot.geometry;
import :point_cloud;
import :bond_list;

export namespace peridot {

// A lattice over the domain Omega and an exterior band around it (seed 000, Sec. 3): points in
// Omega are interior; exterior points inside `neumann` are ghosts (bond partners with no
// unknowns, traction side); all other exterior points form the Dirichlet collar. The band is
// `band` wide [m] around Omega's bounding box, aligned with the interior lattice.
struct ExteriorOptions {
  double band = 0;          // [m], e.g. 2 delta for the Dirichlet volume constraint
  Shape neumann;            // may be empty: every exterior point is collar
};

PointCloud lattice_with_exterior(const Shape& omega, const LatticeOptions& lattice, const ExteriorOptions& exterior);
// Its pieces, for a rank that makes only some of the cloud's points: the box whose lattice the
// cloud is (Omega's bounding box grown by the band in whole cells), and each point's role from
// where it is.
Shape exterior_hull(const Shape& omega, double spacing, double band);
void classify_exterior(PointCloud& points, const Shape& omega, const ExteriorOptions& exterior);

// Clears gamma (bonds.intact) for the bonds of interior points that end on a ghost point or
// whose segment passes through the Neumann region (e.g. a chord across a hole).
void break_neumann_bonds(const PointCloud& points, BondList& bonds, const Shape& neumann);

}  // namespace peridot

namespace peridot {

Shape exterior_hull(const Shape& omega, double spacing, double band) {
  const int dim = omega.dimension();
  const Aabb b = omega.bounds();
  // Grow by whole cells so the exterior lattice continues the interior one.
  const double grow = std::ceil(band / spacing - 1e-9) * spacing;
  Vec3 lo = b.lo, hi = b.hi;
  for (int k = 0; k < dim; ++k) {
    lo[k] -= grow;
    hi[k] += grow;
  }
  return dim == 2 ? rectangle(lo, hi) : box(lo, hi);
}

void classify_exterior(PointCloud& pc, const Shape& omega, const ExteriorOptions& ext) {
  // Classify where the point actually is: near a curved boundary a perturbed site can cross it.
  for (std::size_t i = 0; i < pc.size(); ++i) {
    const Vec3 x = pc.position(i);
    if (omega.contains(x)) pc.role[i] = Role::interior;
    else if (!ext.neumann.empty() && ext.neumann.contains(x)) pc.role[i] = Role::ghost;
    else pc.role[i] = Role::collar;
  }
}

PointCloud lattice_with_exterior(const Shape& omega, const LatticeOptions& o, const ExteriorOptions& ext) {
  if (omega.empty()) throw std::invalid_argument("lattice: geometry is empty");
  if (!(o.spacing > 0)) throw std::invalid_argument("lattice: spacing must be a finite number > 0");
  if (!(ext.band >= 0)) throw std::invalid_argument("lattice: exterior band must be >= 0");
  PointCloud pc = lattice(exterior_hull(omega, o.spacing, ext.band), o);
  classify_exterior(pc, omega, ext);
  return pc;
}

void break_neumann_bonds(const PointCloud& pc, BondList& bl, const Shape& neumann) {
  const auto n = static_cast<std::int64_t>(pc.size());
#pragma omp parallel for schedule(dynamic, 256)
  for (std::int64_t i = 0; i < n; ++i) {
    if (pc.role[i] != Role::interior) continue;
    const Vec3 p = pc.position(std::size_t(i));
    for (auto b = bl.offset[i]; b < bl.offset[i + 1]; ++b) {
      const auto j = std::size_t(bl.neighbor[b]);
      bool broken = pc.role[j] == Role::ghost;
      if (!broken && !neumann.empty()) {
        const Vec3 q = pc.position(j);
        for (int s = 1; s < 16 && !broken; ++s) broken = neumann.contains(p + (s / 16.0) * (q - p));
      }
      if (broken) bl.intact[b] = 0;
    }
  }
}

}  // namespace peridot
