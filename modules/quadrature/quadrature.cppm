// peridot.quadrature: per-point meshfree quadrature weights for nonlocal operators. The
// optimization-based (GMLS) rule of seed 000 eq. (4.4) integrates a reproducing space
// exactly over each full ball; the equal-volume rule stays for comparison.
export module peridot.quadrature;
import peridot.std;
export import peridot.discretization;
export import :reproducing_space;
export import :weights;
export import :element_weights;
export import :mesh_norms;
export import :cell_area;
