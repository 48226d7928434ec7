// Checks shared by the single-precision kernels' tests (tests/models/test_*_lean.cpp).
#pragma once
#include <catch2/catch.hpp>
#include <cstddef>

namespace lean_checks {

// Break counts of the single and double paths, `differ` bonds breaking on one only (each
// checked by the caller to lie within the float analysis of the threshold): the counts agree
// up to those, which are at most 1 % of the breaks.
inline void check_break_counts(std::size_t single, std::size_t dbl, std::size_t differ) {
  CHECK(single + differ >= dbl);
  CHECK(single <= dbl + differ);
  CHECK(differ <= dbl / 100);
}

// Whether the AVX2 and AVX-512VL kernels can run here; if not, a warning says only the
// portable one does.
inline bool vector_kernels_run() {
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("bmi2")) return true;
  WARN("this CPU has no AVX2: only the portable kernel runs here");
  return false;
}

}  // namespace lean_checks
