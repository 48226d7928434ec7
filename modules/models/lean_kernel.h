// The C interface between the models (pmb.cppm, rnp.cppm, lean_records.cppm) and the intrinsics
// kernels of lean_kernel.cpp.
#pragma once
#include <cstddef>
#include <cstdint>

// One pass over the rows [first, last) of a lean CSR list. `packed` holds 8 words per point:
// the low 32 bits of round(x / q) for each axis, the no-fail flag, then u / q as 3 floats and
// a pad (2D: z words zero). Forces go to f0, f1 and, in 3D, f2 [N/m^3].
struct PeridotLeanPass {
  const std::int64_t* offset;
  const std::int32_t* neighbor;
  const float* weight;
  std::uint8_t* intact;
  const std::int32_t* packed;
  double *f0, *f1, *f2;
  float c, s0;
  std::int64_t first, last;
  std::uint8_t* dirty = nullptr;  // when set, rows that lost a bond in this pass get 1
};

extern "C" {
// The fastest kernel this CPU runs: 2 AVX-512VL, 1 AVX2 with BMI2, 0 only the portable one.
int peridot_pmb_lean_vector();
// Returns the directed bonds broken. vector: a level above, at most peridot_pmb_lean_vector()'s;
// every level gives the same bits.
std::size_t peridot_pmb_lean_rows(const PeridotLeanPass* pass, int vector);
// RNP's force pass on the same records and list (pass->c and s0 unused), its constants in the
// fixed point's unit q [m]: k0 = P 2 C beta, beta_q = beta q, limit_q = (break_factor r_c)^2 / q
// (+inf: bonds only soften), inv_eps_q = q / eps (linear: J = 1 - |xi| / eps, else J = 1).
struct PeridotRnpLean {
  float k0, beta_q, limit_q, inv_eps_q;
  int linear;
};
std::size_t peridot_rnp_lean_rows(const PeridotLeanPass* pass, const PeridotRnpLean* rnp, int vector);
// LPS's two passes (Lps::forces with single_precision) on the same records and list, in the
// unit q. The dilatation pass sums w (M_i e) . eta / |e| into f0 (theta_i = q d / m times it),
// M_i six floats a point (xx xy xz yy yz zz), after breaking the bonds with
// 2 e . eta + eta . eta > s2 |e|^2, s2 = s0 (2 + s0) (+inf: none break). The force pass reads
// each point's theta from its record's last word and sums the pair forces
// w / |e| (ct (theta_i + theta_j) + cs e . eta / |e|^2) e into f0, f1, f2; it breaks nothing.
struct PeridotLpsLean {
  const float* M;
  float s2, ct, cs;
};
std::size_t peridot_lps_lean_dilatation_rows(const PeridotLeanPass* pass, const PeridotLpsLean* lps, int vector);
std::size_t peridot_lps_lean_force_rows(const PeridotLeanPass* pass, const PeridotLpsLean* lps, int vector);
}
