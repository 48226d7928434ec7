export module peridot.models:elastic;
import peridot.std;

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

// Critical stretch of a 3D bond whose energy release across a plane is matched to G0 [J/m^2]
// for a body of bulk modulus K [Pa] and horizon delta [m]: s0 = sqrt(5 G0 / (9 K delta))
// (Silling & Askari 2005, eq. 29). 3D PMB uses it with K at nu = 1/4 and 3D LPS with
// K = lambda + 2 mu / 3, the form that seed 000's eq. (6.3) takes in 2D with K = lambda + mu.
inline double critical_stretch_3d(double G0, double bulk_modulus, double delta) {
  return std::sqrt(5 * G0 / (9 * bulk_modulus * delta));
}

inline const char* to_string(Kinematics k) {
  switch (k) {
    case Kinematics::plane_stress: return "plane_stress";
    case Kinematics::plane_strain: return "plane_strain";
    case Kinematics::bar: return "bar";
    default: return "solid";
  }
}

}  // namespace peridot
