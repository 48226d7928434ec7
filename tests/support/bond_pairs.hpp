#pragma once
// Bond-list properties that tests state about masks.
#include <cstddef>
#include <cstdint>
import peridot.discretization;

namespace bond_pairs {

// Broken bonds i -> j whose reverse j -> i is intact (0 when every bond broke from both ends).
inline std::size_t broken_one_way(const peridot::BondList& bl) {
  std::size_t one_way = 0;
  for (std::size_t i = 0; i + 1 < bl.offset.size(); ++i)
    for (auto b = bl.offset[i]; b < bl.offset[i + 1]; ++b) {
      if (bl.intact[std::size_t(b)]) continue;
      const auto j = std::size_t(bl.neighbor[std::size_t(b)]);
      for (auto c = bl.offset[j]; c < bl.offset[j + 1]; ++c)
        if (std::size_t(bl.neighbor[std::size_t(c)]) == i && bl.intact[std::size_t(c)]) ++one_way;
    }
  return one_way;
}

}  // namespace bond_pairs
