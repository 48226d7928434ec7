#pragma once
// The largest |component| of a field's values (any range of ranges of doubles, such as a
// VectorField): the displacement scale the single-precision kernels' analyses are stated in.
#include <algorithm>
#include <cmath>

template <class Field>
double max_abs(const Field& u) {
  double m = 0;
  for (const auto& c : u)
    for (double v : c) m = std::max(m, std::abs(v));
  return m;
}
