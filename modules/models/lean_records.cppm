module;
#include "lean_kernel.h"

export module peridot.models:lean_records;
import peridot.std;
import :body;

export namespace peridot {

// [m] The fixed point's unit q = 2^(ilogb(delta) - 24) of a lean pass.
inline double lean_unit(double horizon) { return std::ldexp(1.0, std::ilogb(horizon) - 24); }
// [m] How far from the origin a lean pass's fixed point reaches for this horizon: 2^51 quanta
// q, about 2^27 horizons.
inline double lean_reach(double horizon) { return std::ldexp(lean_unit(horizon), 51); }

}  // namespace peridot

namespace peridot {

// The records of the single-precision lean-list kernels (lean_kernel.h), one per point, for
// PMB and RNP: q = 2^(ilogb(delta) - 24) is a power of two, so x / q and u / q are exact
// scalings; only the rounding to fixed point (x, to q / 2) and to float (u) is inexact. A point
// beyond lean_reach is an input error naming `model`.
void pack_lean_records(const Body& body, const VectorField& u, double horizon, LargeArray<std::int32_t>& packed, std::string_view model);

// A lean pass over every row, in chunks of rows on the threads: `rows` fills in the model's
// constants and runs its kernel on one chunk, returning the bonds it broke. A row's result does
// not depend on the chunks.
template <class Rows>
std::size_t lean_rows(Body& body, const LargeArray<std::int32_t>& packed, VectorField& f, const Rows& rows) {
  const auto n = static_cast<std::int64_t>(body.size());
  auto& bl = body.bonds;
  constexpr std::int64_t rows_per_chunk = 256;
  const std::int64_t chunks = (n + rows_per_chunk - 1) / rows_per_chunk;
  std::size_t broken = 0;
#pragma omp parallel for schedule(static) reduction(+ : broken)
  for (std::int64_t k = 0; k < chunks; ++k) {
    PeridotLeanPass pass{bl.offset.data(), bl.neighbor.data(), bl.weight_f.data(), bl.intact.data(), packed.data(),
                         f[0].data(), f[1].data(), body.dim() == 3 ? f[2].data() : nullptr, 0.0f, 0.0f,
                         k * rows_per_chunk, std::min(n, (k + 1) * rows_per_chunk)};
    broken += rows(pass);
  }
  return broken;
}

namespace {

// The low 32 bits of round(v), for |v| < 2^51: adding 1.5 2^52 leaves round-to-nearest(v) in the
// low bits of the mantissa. No conversion instruction, so the packing loop vectorises anywhere.
inline std::int32_t low_bits_of_round(double v) {
  return std::int32_t(std::uint32_t(std::bit_cast<std::uint64_t>(v + 0x1.8p52)));
}

}  // namespace

void pack_lean_records(const Body& body, const VectorField& u, double horizon, LargeArray<std::int32_t>& packed, std::string_view model) {
  const auto n = static_cast<std::int64_t>(body.size());
  const int dim = body.dim();
  const double q = lean_unit(horizon), per_q = 1 / q, reach = lean_reach(horizon);
  packed.resize(std::size_t(n) * 8);
  const double *x0 = body.points.x[0].data(), *x1 = body.points.x[1].data(), *x2 = body.points.x[2].data();
  const double *u0 = u[0].data(), *u1 = u[1].data(), *u2 = u[2].data();
  const std::uint8_t* nofail = body.no_fail.empty() ? nullptr : body.no_fail.data();
  std::int32_t* r = packed.data();
  int too_far = 0;
  // The fixed-point coordinates' low 32 bits are all the kernel needs: it subtracts them wrapping.
  if (dim == 3) {
#pragma omp parallel for simd schedule(static) reduction(| : too_far)
    for (std::int64_t i = 0; i < n; ++i) {
      too_far |= int(!(std::abs(x0[i]) < reach) | !(std::abs(x1[i]) < reach) | !(std::abs(x2[i]) < reach));
      r[8 * i] = low_bits_of_round(x0[i] * per_q), r[8 * i + 1] = low_bits_of_round(x1[i] * per_q), r[8 * i + 2] = low_bits_of_round(x2[i] * per_q);
      r[8 * i + 4] = std::bit_cast<std::int32_t>(float(u0[i] * per_q)), r[8 * i + 5] = std::bit_cast<std::int32_t>(float(u1[i] * per_q));
      r[8 * i + 6] = std::bit_cast<std::int32_t>(float(u2[i] * per_q)), r[8 * i + 7] = 0;
      r[8 * i + 3] = nofail ? nofail[i] : 0;
    }
  } else {
#pragma omp parallel for simd schedule(static) reduction(| : too_far)
    for (std::int64_t i = 0; i < n; ++i) {
      too_far |= int(!(std::abs(x0[i]) < reach) | !(std::abs(x1[i]) < reach));
      r[8 * i] = low_bits_of_round(x0[i] * per_q), r[8 * i + 1] = low_bits_of_round(x1[i] * per_q), r[8 * i + 2] = 0;
      r[8 * i + 4] = std::bit_cast<std::int32_t>(float(u0[i] * per_q)), r[8 * i + 5] = std::bit_cast<std::int32_t>(float(u1[i] * per_q));
      r[8 * i + 6] = 0, r[8 * i + 7] = 0;
      r[8 * i + 3] = nofail ? nofail[i] : 0;
    }
  }
  if (too_far)
    throw std::invalid_argument(fmt::format("{}: a point lies {:g} m or more from the origin, beyond the single-precision kernel's "
                                            "fixed point for horizon {:g} m; move the body nearer the origin or set discretization.list_precision: double",
                                            model, reach, horizon));
}

}  // namespace peridot
