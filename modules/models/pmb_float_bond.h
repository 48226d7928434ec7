// PMB's bond in single precision, shared by the lattice stencil (pmb_stencil.cppm) and the
// portable lean-list kernel (lean_kernel.cpp, whose AVX2 kernel does the same operations in
// the same order). From the bond vector xi (length L, L2 = |xi|^2) and eta = u_j - u_i:
//   q = 2 xi.eta + eta.eta = r^2 - L^2, with no cancellation, r = |xi + eta|,
//   s = q / (L (r + L)); the test s > s0 is q > s0 L (r + L), and the pair force factor
//   c w s / r = c w q / (L r (r + L)): one division per bond.
#pragma once
#include <cmath>

struct PmbFloatBond {
  float q, r, lr;  // lr = L (r + L)

  bool breaks(float s0) const { return q > s0 * lr; }
  float force_factor(float cw) const { return cw * q / (lr * r); }  // times (xi + eta) gives the pair force density
};

inline PmbFloatBond pmb_float_bond(float L, float L2, float e0, float e1, float e2, float h0, float h1, float h2) {
  PmbFloatBond b;
  b.q = 2.0f * (e0 * h0 + e1 * h1 + e2 * h2) + (h0 * h0 + h1 * h1 + h2 * h2);
  b.r = std::sqrt(L2 + b.q);
  b.lr = L * (b.r + L);
  return b;
}
