// PMB's and RNP's pair forces and LPS's two passes on a bond list in single precision, eight
// bonds at a time.
//
// A plain translation unit, not a module unit: it holds AVX2 intrinsics, built by target
// attributes for AVX2 (with BMI2 and FMA) and again for AVX-512VL (the same instructions with 32 vector
// registers, 1.4x faster on Zen 4 where the AVX2 build spills), picked at load time, so every
// preset runs the fastest the CPU has. It is compiled with -ffp-contract=off, so no
// multiply-add is fused unless written so (std::fma and vfmadd alike), and the vector kernels
// and the portable one below give the same bits.
//
// Why not the compiler's vectoriser: a bond list's partners are scattered, and a vectorised
// loop fetches them with hardware gathers, one element at a time on AMD Zen 4. Here each
// partner is one 32-byte record, loaded whole and transposed in registers (eight loads and 24
// shuffles per eight bonds), which halves the force pass on this machine kind.
//
// The record of point j (lean_records.cppm packs it each pass): X_j in fixed point, the low 32 bits of
// round(x_j / q) for a power of two q = 2^(ilogb(delta) - 24), its no-fail flag, and u_j / q
// in float. The low 32 bits suffice: x_j - x_i of any bond shorter than 2^31 q (at least 64
// horizons) is exact in wrapping 32-bit arithmetic, whatever the body's size or origin, and q
// depends on the horizon only, so every rank of a run quantises the same way. The bond
// vector is then exact to q per component (about 2^-24 delta) and rounded once to float; the
// stretch is the stencil's s = (2 xi.eta + eta.eta) / (L (r + L)), with no cancellation
// (pmb_float_bond.h, which the portable kernel calls).
//
// RNP (Rnp::forces on a lean list) reads the same records: S = (eta . xi) / |xi|^2, with no
// cancellation beyond eta's own (u_j - u_i in float); r^2 = |xi| S^2 against the break limit;
// the pair force k0 w J S exp(-beta |xi| S^2) xi / |xi|, where the unit q cancels. The
// exponential is exp_neg below (the same operations in both kernels), not libm's or libmvec's,
// whose lane-width variants need not agree in the last bit.
//
// LPS (Lps::forces with single_precision) reads them too, in two passes: the dilatation, with
// the breaking test on |y|^2 - |xi|^2 = 2 xi.eta + eta.eta (no cancellation), from M_i in float;
// then, each record's last word holding its point's dilatation, the pair forces. LPS keeps its
// double weights for the observers and frames; the float copy beside them is what these read.
#include <immintrin.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "lean_kernel.h"
#include "pmb_float_bond.h"

namespace {

constexpr int lanes = 8;

// Partial force sums stay float for two groups of eight bonds (two terms a lane), then join
// double accumulators, so float rounding grows with 2, not with a row's length.
constexpr int groups_per_flush = 2;

// exp(x) for x <= 0 in float: x = n ln2 + r with |r| <= ln2 / 2 (Cody and Waite's two-part ln2,
// whose first part times n is exact), exp(r) by its Taylor polynomial to r^7 (truncation below
// 6e-9 relative), times 2^n built in the exponent bits. The reduction and the polynomial are
// fused multiply-adds (std::fma here, vfmadd in the vector kernels: the same bits), one rounding
// a step where a multiply and an add take two, and half the instructions of RNP's costliest
// part. Relative error a few 2^-24; below x = -87 it returns exp(-87) = 1.6e-38, a force 38
// decades below the bond's scale.
constexpr float exp_floor = -87.0f, log2e = 1.44269504088896341f, ln2_hi = 0.693359375f, ln2_lo = -2.12194440054690583e-4f;
constexpr float taylor[8] = {1.0f / 5040, 1.0f / 720, 1.0f / 120, 1.0f / 24, 1.0f / 6, 0.5f, 1.0f, 1.0f};

float exp_neg(float x) {
  x = x >= exp_floor ? x : exp_floor;  // NaN too, as _mm256_max_ps(x, floor) does
  const float n = std::nearbyint(x * log2e);
  const float r = std::fma(-n, ln2_lo, std::fma(-n, ln2_hi, x));
  float p = taylor[0];
  for (int k = 1; k < 8; ++k) p = std::fma(p, r, taylor[k]);
  return p * std::bit_cast<float>(std::uint32_t(int(n) + 127) << 23);
}

[[gnu::target("avx2,fma"), gnu::always_inline]] inline __m256 exp_neg(__m256 x) {
  x = _mm256_max_ps(x, _mm256_set1_ps(exp_floor));
  const __m256 n = _mm256_round_ps(_mm256_mul_ps(x, _mm256_set1_ps(log2e)), _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
  const __m256 r = _mm256_fnmadd_ps(n, _mm256_set1_ps(ln2_lo), _mm256_fnmadd_ps(n, _mm256_set1_ps(ln2_hi), x));
  __m256 p = _mm256_set1_ps(taylor[0]);
  for (int k = 1; k < 8; ++k) p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(taylor[k]));
  const __m256i scale = _mm256_slli_epi32(_mm256_add_epi32(_mm256_cvtps_epi32(n), _mm256_set1_epi32(127)), 23);
  return _mm256_mul_ps(p, _mm256_castsi256_ps(scale));
}

// a . b, summed as the vector form below does: (a0 b0 + a1 b1) + a2 b2.
inline float dot(float a0, float a1, float a2, float b0, float b1, float b2) { return (a0 * b0 + a1 * b1) + a2 * b2; }

// a . b, summed as the portable forms do: (a0 b0 + a1 b1) + a2 b2.
[[gnu::target("avx2"), gnu::always_inline]] inline __m256 dot(__m256 a0, __m256 a1, __m256 a2, __m256 b0, __m256 b1, __m256 b2) {
  return _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(a0, b0), _mm256_mul_ps(a1, b1)), _mm256_mul_ps(a2, b2));
}

// What a pass sums per bond: kb times the deformed direction e + eta (PMB), times the
// reference direction e (RNP, LPS's forces), or kb alone (LPS's dilatation).
enum class Sum { deformed, reference, scalar };

// A bond law: from the bond vector e and eta = u_j - u_i (both in units of q), the partner's
// record word tj and the row's constants (Row, read once per point), whether the bond breaks
// (`over`) and its term kb for weight w; a bond with an end in a no-fail region never breaks
// under any. Each law has a portable form and an AVX2 form doing the same operations in the
// same order.
struct NoRow {};

struct PmbLaw {
  static constexpr Sum sum = Sum::deformed;
  using Row = NoRow;
  float c, s0;

  Row row(const PeridotLeanPass&, std::int64_t) const { return {}; }
  void bond(const Row&, float e0, float e1, float e2, float h0, float h1, float h2, float w, float, bool& over, float& kb) const {
    const float L2 = e0 * e0 + e1 * e1 + e2 * e2;
    const PmbFloatBond b = pmb_float_bond(std::sqrt(L2), L2, e0, e1, e2, h0, h1, h2);
    over = b.breaks(s0);
    kb = b.force_factor(c * w);
  }
  [[gnu::target("avx2"), gnu::always_inline]] inline void bond(const Row&, __m256 e0, __m256 e1, __m256 e2, __m256 h0, __m256 h1, __m256 h2,
                                                              __m256 w, __m256, __m256& over, __m256& kb) const {
    const __m256 L2 = dot(e0, e1, e2, e0, e1, e2), L = _mm256_sqrt_ps(L2);
    const __m256 ed = dot(e0, e1, e2, h0, h1, h2), hh = dot(h0, h1, h2, h0, h1, h2);
    const __m256 q = _mm256_add_ps(_mm256_add_ps(ed, ed), hh);  // 2 ed + hh (doubling is exact, as pmb_float_bond's product)
    const __m256 rr = _mm256_sqrt_ps(_mm256_add_ps(L2, q));
    const __m256 lr = _mm256_mul_ps(L, _mm256_add_ps(rr, L));
    over = _mm256_cmp_ps(q, _mm256_mul_ps(_mm256_set1_ps(s0), lr), _CMP_GT_OQ);
    kb = _mm256_div_ps(_mm256_mul_ps(_mm256_mul_ps(_mm256_set1_ps(c), w), q), _mm256_mul_ps(lr, rr));
  }
};

// RNP's bond (Rnp in rnp.cppm): S = (eta . e) / |e|^2, r^2 = |e| S^2, kb = k0 w S / |e| J exp(-beta_q r^2).
template <bool Linear>
struct RnpLaw {
  static constexpr Sum sum = Sum::reference;
  using Row = NoRow;
  PeridotRnpLean k;

  Row row(const PeridotLeanPass&, std::int64_t) const { return {}; }
  void bond(const Row&, float e0, float e1, float e2, float h0, float h1, float h2, float w, float, bool& over, float& kb) const {
    const float L2 = e0 * e0 + e1 * e1 + e2 * e2, L = std::sqrt(L2);
    const float S = (e0 * h0 + e1 * h1 + e2 * h2) / L2;
    const float r2 = L * S * S;
    over = r2 > k.limit_q;
    float t = k.k0 * w * S / L;
    if constexpr (Linear) {
      const float J = 1.0f - L * k.inv_eps_q;
      t = t * (J > 0.0f ? J : 0.0f);
    }
    kb = t * exp_neg(-(k.beta_q * r2));
  }
  [[gnu::target("avx2,fma"), gnu::always_inline]] inline void bond(const Row&, __m256 e0, __m256 e1, __m256 e2, __m256 h0, __m256 h1,
                                                                  __m256 h2, __m256 w, __m256, __m256& over, __m256& kb) const {
    const __m256 L2 = dot(e0, e1, e2, e0, e1, e2), L = _mm256_sqrt_ps(L2);
    const __m256 S = _mm256_div_ps(dot(e0, e1, e2, h0, h1, h2), L2);
    const __m256 r2 = _mm256_mul_ps(_mm256_mul_ps(L, S), S);
    over = _mm256_cmp_ps(r2, _mm256_set1_ps(k.limit_q), _CMP_GT_OQ);
    __m256 t = _mm256_div_ps(_mm256_mul_ps(_mm256_mul_ps(_mm256_set1_ps(k.k0), w), S), L);
    if constexpr (Linear) {
      const __m256 J = _mm256_sub_ps(_mm256_set1_ps(1.0f), _mm256_mul_ps(L, _mm256_set1_ps(k.inv_eps_q)));
      t = _mm256_mul_ps(t, _mm256_and_ps(J, _mm256_cmp_ps(J, _mm256_setzero_ps(), _CMP_GT_OQ)));
    }
    kb = _mm256_mul_ps(t, exp_neg(_mm256_xor_ps(_mm256_mul_ps(_mm256_set1_ps(k.beta_q), r2), _mm256_set1_ps(-0.0f))));
  }
};

// LPS's dilatation (Lps::dilatations): kb = w (M_i e) . eta / |e|, summed alone; a bond breaks
// when |e + eta|^2 - |e|^2 = 2 e . eta + eta . eta exceeds s0 (2 + s0) |e|^2, the double path's
// |y| > (1 + s0) |xi| without its cancellation.
struct LpsDilatationLaw {
  static constexpr Sum sum = Sum::scalar;
  struct Row {
    float m[6];
  };
  PeridotLpsLean k;

  Row row(const PeridotLeanPass&, std::int64_t i) const {
    Row r;
    for (int c = 0; c < 6; ++c) r.m[c] = k.M[6 * i + c];
    return r;
  }
  void bond(const Row& r, float e0, float e1, float e2, float h0, float h1, float h2, float w, float, bool& over, float& kb) const {
    const float L2 = dot(e0, e1, e2, e0, e1, e2), L = std::sqrt(L2);
    const float ed = dot(e0, e1, e2, h0, h1, h2), hh = dot(h0, h1, h2, h0, h1, h2);
    over = (ed + ed) + hh > k.s2 * L2;
    const float m0 = dot(r.m[0], r.m[1], r.m[2], e0, e1, e2), m1 = dot(r.m[1], r.m[3], r.m[4], e0, e1, e2), m2 = dot(r.m[2], r.m[4], r.m[5], e0, e1, e2);
    kb = w * dot(m0, m1, m2, h0, h1, h2) / L;
  }
  [[gnu::target("avx2"), gnu::always_inline]] inline void bond(const Row& r, __m256 e0, __m256 e1, __m256 e2, __m256 h0, __m256 h1, __m256 h2,
                                                              __m256 w, __m256, __m256& over, __m256& kb) const {
    const __m256 L2 = dot(e0, e1, e2, e0, e1, e2), L = _mm256_sqrt_ps(L2);
    const __m256 ed = dot(e0, e1, e2, h0, h1, h2), hh = dot(h0, h1, h2, h0, h1, h2);
    over = _mm256_cmp_ps(_mm256_add_ps(_mm256_add_ps(ed, ed), hh), _mm256_mul_ps(_mm256_set1_ps(k.s2), L2), _CMP_GT_OQ);
    const __m256 M0 = _mm256_set1_ps(r.m[0]), M1 = _mm256_set1_ps(r.m[1]), M2 = _mm256_set1_ps(r.m[2]);
    const __m256 M3 = _mm256_set1_ps(r.m[3]), M4 = _mm256_set1_ps(r.m[4]), M5 = _mm256_set1_ps(r.m[5]);
    const __m256 m0 = dot(M0, M1, M2, e0, e1, e2), m1 = dot(M1, M3, M4, e0, e1, e2), m2 = dot(M2, M4, M5, e0, e1, e2);
    kb = _mm256_div_ps(_mm256_mul_ps(w, dot(m0, m1, m2, h0, h1, h2)), L);
  }
};

// LPS's pair force (Lps::forces_from_dilatations, a homogeneous body): kb = w / |e| (ct
// (theta_i + theta_j) + cs e . eta / |e|^2) along e, theta from the records' last word. One
// division: with v = 1 / |e|^3, w / |e| = w |e|^2 v and e . eta / |e|^2 = (e . eta) |e| v, whose
// factors stay far inside float's range in the unit q (|e| < 2^26). Breaks nothing.
struct LpsForceLaw {
  static constexpr Sum sum = Sum::reference;
  struct Row {
    float theta;
  };
  PeridotLpsLean k;

  Row row(const PeridotLeanPass& p, std::int64_t i) const { return {std::bit_cast<float>(p.packed[8 * i + 7])}; }
  void bond(const Row& r, float e0, float e1, float e2, float h0, float h1, float h2, float w, float tj, bool& over, float& kb) const {
    const float L2 = dot(e0, e1, e2, e0, e1, e2), L = std::sqrt(L2);
    const float ed = dot(e0, e1, e2, h0, h1, h2);
    const float v = 1.0f / (L * L2);
    over = false;
    kb = (w * L2 * v) * (k.ct * (r.theta + tj) + k.cs * (ed * L * v));
  }
  [[gnu::target("avx2"), gnu::always_inline]] inline void bond(const Row& r, __m256 e0, __m256 e1, __m256 e2, __m256 h0, __m256 h1, __m256 h2,
                                                              __m256 w, __m256 tj, __m256& over, __m256& kb) const {
    const __m256 L2 = dot(e0, e1, e2, e0, e1, e2), L = _mm256_sqrt_ps(L2);
    const __m256 ed = dot(e0, e1, e2, h0, h1, h2);
    const __m256 v = _mm256_div_ps(_mm256_set1_ps(1.0f), _mm256_mul_ps(L, L2));
    over = _mm256_setzero_ps();
    const __m256 t = _mm256_mul_ps(_mm256_set1_ps(k.ct), _mm256_add_ps(_mm256_set1_ps(r.theta), tj));
    const __m256 s = _mm256_mul_ps(_mm256_set1_ps(k.cs), _mm256_mul_ps(_mm256_mul_ps(ed, L), v));
    kb = _mm256_mul_ps(_mm256_mul_ps(_mm256_mul_ps(w, L2), v), _mm256_add_ps(t, s));
  }
};

// The eight lanes' double sums of a row, added in lane order (the same on both kernels).
double lane_sum(const double* a) {
  double s = 0;
  for (int k = 0; k < lanes; ++k) s += a[k];
  return s;
}

// A row's sums out: f0, f1, f2 (f2 in 3D), or f0 alone for a scalar law.
template <class Law>
void store(const PeridotLeanPass& p, std::int64_t i, double s0, double s1, double s2) {
  p.f0[i] = s0;
  if constexpr (Law::sum != Sum::scalar) {
    p.f1[i] = s1;
    if (p.f2) p.f2[i] = s2;
  }
}

// The portable kernel: the AVX2 kernel's operations lane by lane, in its order.
template <class Law>
std::size_t rows_portable(const PeridotLeanPass& p, const Law& law) {
  const float* rec = reinterpret_cast<const float*>(p.packed);
  std::size_t broken = 0;
  for (std::int64_t i = p.first; i < p.last; ++i) {
    const std::int32_t* ri = p.packed + 8 * i;
    const float* ui = rec + 8 * i + 4;
    const typename Law::Row row = law.row(p, i);
    double acc[3][lanes] = {};
    float part[3][lanes] = {};
    int snapped = 0, group = 0;
    const std::int64_t b0 = p.offset[i], b1 = p.offset[i + 1];
    for (std::int64_t b = b0; b < b1; b += lanes, ++group) {
      const int count = int(b1 - b < lanes ? b1 - b : lanes);
      for (int k = 0; k < lanes; ++k) {
        const std::int64_t j = k < count ? p.neighbor[b + k] : i;
        const std::int32_t* rj = p.packed + 8 * j;
        const float* uj = rec + 8 * j + 4;
        const float e0 = float(std::int32_t(std::uint32_t(rj[0]) - std::uint32_t(ri[0])));
        const float e1 = float(std::int32_t(std::uint32_t(rj[1]) - std::uint32_t(ri[1])));
        const float e2 = float(std::int32_t(std::uint32_t(rj[2]) - std::uint32_t(ri[2])));
        const float h0 = uj[0] - ui[0], h1 = uj[1] - ui[1], h2 = uj[2] - ui[2];
        const float w = k < count ? p.weight[b + k] : 0.0f;
        bool over = false;
        float kb = 0;
        if (k < count) law.bond(row, e0, e1, e2, h0, h1, h2, w, uj[3], over, kb);  // a lane past the row: masked in the AVX2 kernel
        const bool alive = k < count && p.intact[b + k] != 0;
        const bool breakable = (ri[3] | rj[3]) == 0;
        const bool snap = alive && breakable && over;
        const bool now = alive && !snap;
        if (k < count) p.intact[b + k] = std::uint8_t(now);
        snapped += int(snap);
        kb = now ? kb : 0.0f;
        if constexpr (Law::sum == Sum::scalar) {
          part[0][k] += kb;
        } else {
          constexpr bool deformed = Law::sum == Sum::deformed;
          const float d0 = deformed ? e0 + h0 : e0, d1 = deformed ? e1 + h1 : e1, d2 = deformed ? e2 + h2 : e2;
          part[0][k] += kb * d0;
          part[1][k] += kb * d1;
          part[2][k] += kb * d2;
        }
      }
      if (group % groups_per_flush == groups_per_flush - 1 || b + lanes >= b1)
        for (int c = 0; c < (Law::sum == Sum::scalar ? 1 : 3); ++c)
          for (int k = 0; k < lanes; ++k) acc[c][k] += double(part[c][k]), part[c][k] = 0;
    }
    broken += std::size_t(snapped);
    if (snapped && p.dirty) p.dirty[i] = 1;
    store<Law>(p, i, lane_sum(acc[0]), lane_sum(acc[1]), lane_sum(acc[2]));
  }
  return broken;
}

[[gnu::target("avx2"), gnu::always_inline]] inline void transpose(__m256 r[8]) {
  const __m256 t0 = _mm256_unpacklo_ps(r[0], r[1]), t1 = _mm256_unpackhi_ps(r[0], r[1]);
  const __m256 t2 = _mm256_unpacklo_ps(r[2], r[3]), t3 = _mm256_unpackhi_ps(r[2], r[3]);
  const __m256 t4 = _mm256_unpacklo_ps(r[4], r[5]), t5 = _mm256_unpackhi_ps(r[4], r[5]);
  const __m256 t6 = _mm256_unpacklo_ps(r[6], r[7]), t7 = _mm256_unpackhi_ps(r[6], r[7]);
  const __m256 s0 = _mm256_shuffle_ps(t0, t2, 0x44), s1 = _mm256_shuffle_ps(t0, t2, 0xEE);
  const __m256 s2 = _mm256_shuffle_ps(t1, t3, 0x44), s3 = _mm256_shuffle_ps(t1, t3, 0xEE);
  const __m256 s4 = _mm256_shuffle_ps(t4, t6, 0x44), s5 = _mm256_shuffle_ps(t4, t6, 0xEE);
  const __m256 s6 = _mm256_shuffle_ps(t5, t7, 0x44), s7 = _mm256_shuffle_ps(t5, t7, 0xEE);
  r[0] = _mm256_permute2f128_ps(s0, s4, 0x20);
  r[1] = _mm256_permute2f128_ps(s1, s5, 0x20);
  r[2] = _mm256_permute2f128_ps(s2, s6, 0x20);
  r[3] = _mm256_permute2f128_ps(s3, s7, 0x20);
  r[4] = _mm256_permute2f128_ps(s0, s4, 0x31);
  r[5] = _mm256_permute2f128_ps(s1, s5, 0x31);
  r[6] = _mm256_permute2f128_ps(s2, s6, 0x31);
  r[7] = _mm256_permute2f128_ps(s3, s7, 0x31);
}

[[gnu::target("avx2"), gnu::always_inline]] inline void flush(__m256 part, __m256d& lo, __m256d& hi) {
  lo = _mm256_add_pd(lo, _mm256_cvtps_pd(_mm256_castps256_ps128(part)));
  hi = _mm256_add_pd(hi, _mm256_cvtps_pd(_mm256_extractf128_ps(part, 1)));
}

[[gnu::target("avx2"), gnu::always_inline]] inline double lane_sum(__m256d lo, __m256d hi) {
  alignas(32) double a[lanes];
  _mm256_store_pd(a, lo);
  _mm256_store_pd(a + 4, hi);
  return lane_sum(a);
}

// One group of eight bonds b .. b + count of point i (count = 8 unless Tail). Inlined into the
// AVX2 and the AVX-512VL kernels: the same instructions, with 32 vector registers on the second,
// which keeps this loop's ~30 live vectors out of the stack.
struct Point {
  __m256i x0, x1, x2, nofail;
  __m256 u0, u1, u2;
};

template <bool Tail, class Law>
[[gnu::target("avx2,bmi2,fma"), gnu::always_inline]] inline void group(const PeridotLeanPass& p, const Law& law, const typename Law::Row& row,
                                                                   const Point& o, std::int64_t i, std::int64_t b, int count, __m256& p0,
                                                                   __m256& p1, __m256& p2, int& snapped) {
  const float* rec = reinterpret_cast<const float*>(p.packed);
  __m256 r[8];
  for (int k = 0; k < lanes; ++k) r[k] = _mm256_loadu_ps(rec + 8 * (!Tail || k < count ? std::int64_t(p.neighbor[b + k]) : i));
  transpose(r);
  const __m256 e0 = _mm256_cvtepi32_ps(_mm256_sub_epi32(_mm256_castps_si256(r[0]), o.x0));
  const __m256 e1 = _mm256_cvtepi32_ps(_mm256_sub_epi32(_mm256_castps_si256(r[1]), o.x1));
  const __m256 e2 = _mm256_cvtepi32_ps(_mm256_sub_epi32(_mm256_castps_si256(r[2]), o.x2));
  const __m256 h0 = _mm256_sub_ps(r[4], o.u0), h1 = _mm256_sub_ps(r[5], o.u1), h2 = _mm256_sub_ps(r[6], o.u2);
  const __m256 w = Tail ? _mm256_maskload_ps(p.weight + b, _mm256_cmpgt_epi32(_mm256_set1_epi32(count), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7)))
                        : _mm256_loadu_ps(p.weight + b);
  __m256 over_ps, kb;
  law.bond(row, e0, e1, e2, h0, h1, h2, w, r[7], over_ps, kb);

  std::uint64_t bytes = 0;
  if (Tail)
    for (int k = 0; k < count; ++k) bytes |= std::uint64_t(p.intact[b + k]) << (8 * k);
  else
    std::memcpy(&bytes, p.intact + b, 8);
  // Lanes past a tail's count read their own point and an intact byte of 0: never alive.
  const __m256i zero = _mm256_setzero_si256(), ones = _mm256_cmpeq_epi32(zero, zero);
  const __m256i alive = _mm256_xor_si256(_mm256_cmpeq_epi32(_mm256_cvtepu8_epi32(_mm_cvtsi64_si128(std::int64_t(bytes))), zero), ones);
  const __m256i breakable = _mm256_cmpeq_epi32(_mm256_or_si256(o.nofail, _mm256_castps_si256(r[3])), zero);
  const __m256i snap = _mm256_and_si256(_mm256_and_si256(alive, breakable), _mm256_castps_si256(over_ps));
  const __m256i now = _mm256_andnot_si256(snap, alive);
  const auto snap_bits = unsigned(_mm256_movemask_ps(_mm256_castsi256_ps(snap)));
  if (snap_bits) {  // only a break changes a mask byte
    snapped += __builtin_popcount(snap_bits);
    const auto now_bits = std::uint64_t(unsigned(_mm256_movemask_ps(_mm256_castsi256_ps(now))));
    const std::uint64_t out = _pdep_u64(now_bits, 0x0101010101010101ull);
    if (Tail)
      for (int k = 0; k < count; ++k) p.intact[b + k] = std::uint8_t(out >> (8 * k));
    else
      std::memcpy(p.intact + b, &out, 8);
  }
  kb = _mm256_and_ps(kb, _mm256_castsi256_ps(now));
  if constexpr (Law::sum == Sum::scalar) {
    p0 = _mm256_add_ps(p0, kb);
  } else if constexpr (Law::sum == Sum::deformed) {
    p0 = _mm256_add_ps(p0, _mm256_mul_ps(kb, _mm256_add_ps(e0, h0)));
    p1 = _mm256_add_ps(p1, _mm256_mul_ps(kb, _mm256_add_ps(e1, h1)));
    p2 = _mm256_add_ps(p2, _mm256_mul_ps(kb, _mm256_add_ps(e2, h2)));
  } else {
    p0 = _mm256_add_ps(p0, _mm256_mul_ps(kb, e0));
    p1 = _mm256_add_ps(p1, _mm256_mul_ps(kb, e1));
    p2 = _mm256_add_ps(p2, _mm256_mul_ps(kb, e2));
  }
}

template <class Law>
[[gnu::target("avx2,bmi2,fma"), gnu::always_inline]] inline std::size_t rows_vector(const PeridotLeanPass& p, const Law& law) {
  const float* rec = reinterpret_cast<const float*>(p.packed);
  std::size_t broken = 0;
  for (std::int64_t i = p.first; i < p.last; ++i) {
    const std::int32_t* ri = p.packed + 8 * i;
    const Point o{_mm256_set1_epi32(ri[0]), _mm256_set1_epi32(ri[1]), _mm256_set1_epi32(ri[2]), _mm256_set1_epi32(ri[3]),
                  _mm256_set1_ps(rec[8 * i + 4]), _mm256_set1_ps(rec[8 * i + 5]), _mm256_set1_ps(rec[8 * i + 6])};
    __m256d a0l = _mm256_setzero_pd(), a0h = a0l, a1l = a0l, a1h = a0l, a2l = a0l, a2h = a0l;
    const typename Law::Row row = law.row(p, i);
    __m256 p0 = _mm256_setzero_ps(), p1 = p0, p2 = p0;
    int snapped = 0, group_index = 0;
    const std::int64_t b0 = p.offset[i], b1 = p.offset[i + 1];
    for (std::int64_t b = b0; b < b1; b += lanes, ++group_index) {
      if (b + lanes <= b1)
        group<false>(p, law, row, o, i, b, lanes, p0, p1, p2, snapped);
      else
        group<true>(p, law, row, o, i, b, int(b1 - b), p0, p1, p2, snapped);
      if (group_index % groups_per_flush == groups_per_flush - 1 || b + lanes >= b1) {
        flush(p0, a0l, a0h);
        if constexpr (Law::sum != Sum::scalar) flush(p1, a1l, a1h), flush(p2, a2l, a2h);
        p0 = p1 = p2 = _mm256_setzero_ps();
      }
    }
    broken += std::size_t(snapped);
    if (snapped && p.dirty) p.dirty[i] = 1;
    store<Law>(p, i, lane_sum(a0l, a0h), lane_sum(a1l, a1h), lane_sum(a2l, a2h));
  }
  return broken;
}

template <class Law>
[[gnu::target("avx2,bmi2,fma")]] std::size_t rows_avx2(const PeridotLeanPass& p, const Law& law) { return rows_vector(p, law); }
template <class Law>
[[gnu::target("avx2,bmi2,fma,avx512f,avx512vl")]] std::size_t rows_avx512vl(const PeridotLeanPass& p, const Law& law) { return rows_vector(p, law); }

template <class Law>
std::size_t rows(const PeridotLeanPass& p, const Law& law, int vector) {
  return vector >= 2 ? rows_avx512vl(p, law) : vector == 1 ? rows_avx2(p, law) : rows_portable(p, law);
}

}  // namespace

extern "C" int peridot_pmb_lean_vector() {
  if (!__builtin_cpu_supports("avx2") || !__builtin_cpu_supports("bmi2") || !__builtin_cpu_supports("fma")) return 0;
  return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") ? 2 : 1;
}

extern "C" std::size_t peridot_pmb_lean_rows(const PeridotLeanPass* p, int vector) { return rows(*p, PmbLaw{p->c, p->s0}, vector); }

extern "C" std::size_t peridot_rnp_lean_rows(const PeridotLeanPass* p, const PeridotRnpLean* rnp, int vector) {
  return rnp->linear ? rows(*p, RnpLaw<true>{*rnp}, vector) : rows(*p, RnpLaw<false>{*rnp}, vector);
}

extern "C" std::size_t peridot_lps_lean_dilatation_rows(const PeridotLeanPass* p, const PeridotLpsLean* lps, int vector) {
  return rows(*p, LpsDilatationLaw{*lps}, vector);
}

extern "C" std::size_t peridot_lps_lean_force_rows(const PeridotLeanPass* p, const PeridotLpsLean* lps, int vector) {
  return rows(*p, LpsForceLaw{*lps}, vector);
}
