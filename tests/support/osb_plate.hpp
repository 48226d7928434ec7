#pragma once
// The seed 004 plate (Scabbia et al., Table 1) for the OSB static solver: 0.3 m x 0.2 m centred
// at the origin, E = 1 GPa, nu = 0.2, plane stress, built by the library's osb_rectangle.
import peridot.problem;

namespace osb_plate {

using Plate = peridot::OsbBody;

inline Plate plate(double mbar, bool corrected, double h = 0.01) {
  using namespace peridot;
  return osb_rectangle({-0.15, -0.1, 0}, {0.15, 0.1, 0}, h, mbar * h, 1e9, 0.2, Kinematics::plane_stress, corrected);
}

inline peridot::ComponentCondition disp(double v) { return {true, v}; }
inline peridot::ComponentCondition trac(double v) { return {false, v}; }

}  // namespace osb_plate
