module;
#include <stdexcept>
#include <string>
export module peridot.models:elastic;

export namespace peridot {

// How a 2D problem relates to 3D elasticity; 3D problems use Kinematics::solid.
enum class Kinematics { plane_stress, plane_strain, solid, bar };  // bar: 1D, per unit cross-section

struct ElasticConstants {
  double lambda = 0;  // [Pa] (2D: the effective in-plane Lame constant)
  double mu = 0;      // [Pa]
};

// In-plane Lame constants for isotropic elasticity (plane stress uses the reduced lambda).
inline ElasticConstants lame(double youngs_modulus, double poisson_ratio, Kinematics k) {
  const double E = youngs_modulus, nu = poisson_ratio;
  const double mu = E / (2 * (1 + nu));
  const double lambda = k == Kinematics::plane_stress ? E * nu / (1 - nu * nu) : E * nu / ((1 + nu) * (1 - 2 * nu));
  return {lambda, mu};
}

// Bond-based models fix Poisson's ratio: 1/3 in plane stress, 1/4 in plane strain and 3D.
inline double bond_based_poisson_ratio(Kinematics k) { return k == Kinematics::plane_stress ? 1.0 / 3.0 : 0.25; }

inline const char* to_string(Kinematics k) {
  switch (k) {
    case Kinematics::plane_stress: return "plane_stress";
    case Kinematics::plane_strain: return "plane_strain";
    case Kinematics::bar: return "bar";
    default: return "solid";
  }
}

}  // namespace peridot
