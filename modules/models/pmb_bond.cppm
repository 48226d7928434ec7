export module peridot.models:pmb_bond;
import peridot.std;

// One PMB bond outside the force loop (energies, the stable step), written once for the bond
// list and the lattice stencil; the force loops keep their own vectorised forms.
export namespace peridot::pmb_bond {

// s = (|y| - L) / L from y2 = |xi + eta|^2, in double.
inline double stretch(double y2, double L) { return (std::sqrt(y2) - L) / L; }
// w(c s^2 L / 4): the bond's share of point i's energy density [J/m^3], w its partner weight.
inline double energy(double c, double s, double L, double w) { return 0.25 * c * s * s * L * w; }
// c w / L: the bond's stiffness in the point's stable-step sum.
inline double stiffness(double c, double w, double L) { return c * w / L; }
// sqrt(2 rho / sum_b c w_b / L_b), the stable step of a point (Silling and Askari's estimate).
inline double stable_step(double density, double stiffness_sum) { return std::sqrt(2 * density / stiffness_sum); }

}  // namespace peridot::pmb_bond
