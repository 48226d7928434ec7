module;
#include <array>
#include <cstdint>
#include <span>
#include <vector>
export module peridot.discretization:bond_list;

export namespace peridot {

// Directed bonds in compressed sparse row form: the bonds of point i are
// [offset[i], offset[i+1]). Each bond is stored from both ends, so a point owns and
// accumulates its own bonds without atomics, and per-bond data may differ by direction
// (quadrature weights with w_ij != w_ji, nodal-FE V_ij).
struct BondList {
  double horizon = 0;                          // delta [m]
  std::vector<std::int64_t> offset;            // size n + 1
  std::vector<std::int32_t> neighbor;          // partner j
  std::array<std::vector<double>, 3> xi;       // reference bond vector x_j - x_i [m]
  std::vector<double> length;                  // |xi| [m]
  std::vector<double> weight;                  // quadrature weight of j in i's ball [m^3, m^2 in 2D]
  std::vector<std::uint8_t> intact;            // 1 while the bond carries force; fracture clears it

  std::size_t points() const { return offset.empty() ? 0 : offset.size() - 1; }
  std::size_t size() const { return neighbor.size(); }
  std::int64_t begin(std::size_t i) const { return offset[i]; }
  std::int64_t end(std::size_t i) const { return offset[i + 1]; }
  std::size_t count(std::size_t i) const { return std::size_t(offset[i + 1] - offset[i]); }
  std::span<const std::int32_t> neighbors(std::size_t i) const {
    return {neighbor.data() + offset[i], count(i)};
  }
  std::size_t broken() const {
    std::size_t b = 0;
    for (auto v : intact) b += v == 0;
    return b;
  }
  // Resident bytes per directed bond (all per-bond arrays plus the CSR offsets).
  double bytes_per_bond() const {
    const double per = sizeof(std::int32_t) + 3 * sizeof(double) + 2 * sizeof(double) + sizeof(std::uint8_t);
    return size() ? per + double(offset.size() * sizeof(std::int64_t)) / double(size()) : 0.0;
  }
};

}  // namespace peridot
