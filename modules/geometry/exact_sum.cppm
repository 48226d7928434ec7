export module peridot.geometry:exact_sum;
import peridot.std;

export namespace peridot {

// A sum of doubles without rounding. Each addend goes exactly into fixed-point limbs of 32 bits
// that span every finite double (2^-1127 .. 2^2240 with headroom), so the total does not depend
// on the order of the additions, on the thread count, or on how the addends are split among MPI
// ranks, whose limbs add as integers. value() rounds the total once, by a fixed rule: the same
// exact total always gives the same double. That is what makes a reduction over the owned
// points of N ranks (energies, damage fraction) bitwise equal to one rank's.
class ExactSum {
 public:
  static constexpr std::size_t limbs = 70;
  // limbs, then counts of NaN, +inf and -inf addends: what travels between ranks.
  static constexpr std::size_t words = limbs + 3;

  void add(double x);
  void add(const ExactSum& other);
  ExactSum& operator+=(double x) {
    add(x);
    return *this;
  }
  // The total rounded to a double (NaN or infinity when an addend was one).
  double value() const;
  // The words in canonical form (every limb but the top in [0, 2^32)), for a sum over ranks of
  // each word; normalise() again after adding other ranks' words in.
  std::span<std::int64_t> words_for_reduction() {
    normalise();
    return {word_.data(), words};
  }
  void normalise();

 private:
  std::array<std::int64_t, words> word_{};
  std::uint32_t pending_ = 0;  // additions since the last normalise
};

}  // namespace peridot

namespace peridot {

namespace {
constexpr int offset_bits = 1127;  // bit 0 of limb 0 weighs 2^-1127, below the least subnormal's mantissa
constexpr std::uint32_t normalise_every = 1u << 30;  // a limb takes < 2^32 per addition: no int64 overflow
}  // namespace

void ExactSum::add(double x) {
  // The addend's own bits, |x| = mantissa 2^exponent exactly: no library call in the loop
  // that dot products run per point.
  const auto bits = __builtin_bit_cast(std::uint64_t, x);
  const auto biased = int((bits >> 52) & 0x7ff);
  if (biased == 0x7ff) {  // NaN or infinity
    if (bits & ((std::uint64_t(1) << 52) - 1)) ++word_[limbs];
    else ++word_[x > 0 ? limbs + 1 : limbs + 2];
    return;
  }
  std::uint64_t mantissa = bits & ((std::uint64_t(1) << 52) - 1);
  if (biased != 0) mantissa |= std::uint64_t(1) << 52;  // normal; a subnormal has exponent -1074 too
  if (mantissa == 0) return;
  const int position = (biased == 0 ? 1 : biased) - 1075 + offset_bits;  // of the mantissa's bit 0; >= 53
  const auto k = std::size_t(position / 32);
  const unsigned __int128 v = static_cast<unsigned __int128>(mantissa) << (position % 32);
  const std::int64_t parts[3] = {std::int64_t(v & 0xffffffffu), std::int64_t((v >> 32) & 0xffffffffu), std::int64_t(v >> 64)};
  if (bits >> 63)
    for (std::size_t j = 0; j < 3; ++j) word_[k + j] -= parts[j];
  else
    for (std::size_t j = 0; j < 3; ++j) word_[k + j] += parts[j];
  if (++pending_ >= normalise_every) normalise();
}

void ExactSum::add(const ExactSum& other) {
  ExactSum o = other;
  o.normalise();
  normalise();
  for (std::size_t j = 0; j < words; ++j) word_[j] += o.word_[j];
  normalise();
}

void ExactSum::normalise() {
  for (std::size_t j = 0; j + 1 < limbs; ++j) {
    const std::int64_t carry = word_[j] >> 32;  // floor division by 2^32
    word_[j] -= carry * (std::int64_t(1) << 32);
    word_[j + 1] += carry;
  }
  pending_ = 0;
}

double ExactSum::value() const {
  const std::int64_t nan = word_[limbs], pos = word_[limbs + 1], neg = word_[limbs + 2];
  if (nan > 0 || (pos > 0 && neg > 0)) return std::numeric_limits<double>::quiet_NaN();
  if (pos > 0) return std::numeric_limits<double>::infinity();
  if (neg > 0) return -std::numeric_limits<double>::infinity();
  ExactSum s = *this;
  s.normalise();
  // Sign and magnitude, so that the conversion never cancels.
  const bool negative = s.word_[limbs - 1] < 0;
  if (negative) {
    for (std::size_t j = 0; j < limbs; ++j) s.word_[j] = -s.word_[j];
    s.normalise();
  }
  // From the top limb down: a fixed function of the canonical limbs.
  double r = 0;
  for (std::size_t j = limbs; j-- > 0;)
    if (s.word_[j] != 0) r += std::ldexp(double(s.word_[j]), int(32 * j) - offset_bits);
  return negative ? -r : r;
}

}  // namespace peridot
