// A plain translation unit, not a module unit: Eigen's headers compiled here stay out of the
// peridot.models BMI (see lps.cppm).
#include <cmath>
#include <Eigen/Dense>

// The pseudo-inverse of the symmetric part of the row-major 3x3 a, into out: eigenvalues below
// 1e-12 of the largest are dropped, so a point whose intact partners all lie in a plane (or on
// a line) gets the pseudo-inverse, as in 2D.
extern "C" void peridot_pseudo_inverse_sym3(const double* a, double* out) {
  Eigen::Matrix3d A;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) A(r, c) = 0.5 * (a[3 * r + c] + a[3 * c + r]);
  for (int k = 0; k < 9; ++k) out[k] = 0;
  if (A.cwiseAbs().maxCoeff() == 0) return;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(A);
  const auto& ev = es.eigenvalues();
  const double top = ev.cwiseAbs().maxCoeff();
  Eigen::Matrix3d P = Eigen::Matrix3d::Zero();
  for (int k = 0; k < 3; ++k)
    if (std::abs(ev(k)) > 1e-12 * top) P += es.eigenvectors().col(k) * es.eigenvectors().col(k).transpose() / ev(k);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) out[3 * r + c] = P(r, c);
}
