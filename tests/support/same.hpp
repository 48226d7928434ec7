#pragma once
// Compares sequences (or sequences of sequences) element by element without handing
// them to Catch: Catch's failure message would print every element, which for a body's
// fields is megabytes and minutes. `difference` returns "" when equal, else a one-line
// summary (sizes, or the first differing index with both values and the count that differ).
//   CHECK(same::difference(a.u, b.u) == "");
#include <cstddef>
#include <iterator>
#include <ranges>
#include <sstream>
#include <string>
#include <type_traits>

namespace same {

namespace detail {

template <class T>
concept nested = std::ranges::range<std::ranges::range_value_t<T>>;

template <class V>
std::string show(const V& v) {
  std::ostringstream s;
  s.precision(17);
  if constexpr (std::is_integral_v<V> && sizeof(V) == 1)
    s << int(v);
  else
    s << v;
  return s.str();
}

// Counts differing leaves and records the first one's path.
template <class A, class B>
void walk(const A& a, const B& b, const std::string& path, std::size_t& count, std::string& first) {
  const auto na = std::size(a), nb = std::size(b);
  if (na != nb) {
    if (count++ == 0) first = path + ": sizes " + std::to_string(na) + " vs " + std::to_string(nb);
    return;
  }
  auto ia = std::begin(a);
  auto ib = std::begin(b);
  for (std::size_t i = 0; i < na; ++i, ++ia, ++ib) {
    const std::string here = path + "[" + std::to_string(i) + "]";
    if constexpr (nested<A>) {
      walk(*ia, *ib, here, count, first);
    } else if (!(*ia == *ib)) {
      if (count++ == 0) first = here + ": " + show(*ia) + " vs " + show(*ib);
    }
  }
}

}  // namespace detail

template <class A, class B>
std::string difference(const A& a, const B& b, const std::string& name = "") {
  std::size_t count = 0;
  std::string first;
  detail::walk(a, b, name, count, first);
  if (count == 0) return "";
  return first + " (" + std::to_string(count) + " differ)";
}

}  // namespace same
