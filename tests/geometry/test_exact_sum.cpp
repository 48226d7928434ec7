// ExactSum against closed forms and against itself in other orders and splits: the total must
// be the exact sum (checked where it is representable) and the same bits however the addends
// are ordered or divided among partial sums, which is what N-rank reductions rely on.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>
import peridot.geometry;

using peridot::ExactSum;

namespace {

double exact_total(const std::vector<double>& v) {
  ExactSum s;
  for (double x : v) s += x;
  return s.value();
}

}  // namespace

TEST_CASE("an exact sum keeps what a rounded sum loses: 1e100 + 1 - 1e100 is 1") {
  CHECK(exact_total({1e100, 1.0, -1e100}) == 1.0);
  CHECK(exact_total({1.0, 1e-30, -1.0}) == 1e-30);
  // The least subnormal and the largest finite double, once each and then cancelled.
  const double tiny = std::numeric_limits<double>::denorm_min(), huge = std::numeric_limits<double>::max();
  CHECK(exact_total({huge, tiny, -huge}) == tiny);
  CHECK(exact_total({huge, huge, -huge}) == huge);
  CHECK(exact_total({-3.5, 1.25}) == -2.25);
  CHECK(exact_total({}) == 0.0);
}

TEST_CASE("the total of integers and of dyadic fractions is exact") {
  // 1 + 2 + ... + 10^6 = 500000500000, and the same divided by 2^40 (exact in binary).
  std::vector<double> v, w;
  for (int i = 1; i <= 1000000; ++i) v.push_back(double(i)), w.push_back(std::ldexp(double(i), -40));
  CHECK(exact_total(v) == 500000500000.0);
  CHECK(exact_total(w) == std::ldexp(500000500000.0, -40));
}

TEST_CASE("the same addends in any order, or split among partial sums, give the same bits") {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> mantissa(-1.0, 1.0);
  std::uniform_int_distribution<int> exponent(-60, 60);
  std::vector<double> v(100000);
  for (auto& x : v) x = std::ldexp(mantissa(rng), exponent(rng));
  const double forward = exact_total(v);
  auto shuffled = v;
  std::shuffle(shuffled.begin(), shuffled.end(), rng);
  CHECK(exact_total(shuffled) == forward);
  std::reverse(shuffled.begin(), shuffled.end());
  CHECK(exact_total(shuffled) == forward);
  // Four "ranks" with interleaved shares, merged as limbs.
  ExactSum part[4];
  for (std::size_t i = 0; i < v.size(); ++i) part[(i * 7) % 4] += v[i];
  ExactSum merged;
  for (auto& p : part) merged.add(p);
  CHECK(merged.value() == forward);
  // Merged word by word, as an MPI sum of the words does.
  ExactSum by_words;
  auto total = by_words.words_for_reduction();
  for (auto& p : part) {
    const auto w = p.words_for_reduction();
    for (std::size_t j = 0; j < w.size(); ++j) total[j] += w[j];
  }
  by_words.normalise();
  CHECK(by_words.value() == forward);
  // A long double sum of the same values is close: the rounding is to about one unit.
  long double reference = 0;
  for (double x : v) reference += x;
  CHECK(std::abs(double(reference) - forward) <= 1e-12 * std::abs(forward) + 1e-15);
}

TEST_CASE("NaN and infinite addends give NaN or infinity, as a plain sum does") {
  const double inf = std::numeric_limits<double>::infinity();
  CHECK(std::isnan(exact_total({1.0, std::nan("")})));
  CHECK(exact_total({1.0, inf}) == inf);
  CHECK(exact_total({-inf, 2.0}) == -inf);
  CHECK(std::isnan(exact_total({inf, -inf})));
}
