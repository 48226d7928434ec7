export module peridot.discretization:bond_list;
import peridot.std;
import :large_array;

export namespace peridot {

// |xi| from its components: the one formula that list builders store and that readers of a list
// without stored geometry recompute, so both give the same bits.
inline double bond_length(double dx, double dy, double dz) { return std::sqrt(dx * dx + dy * dy + dz * dz); }

// Directed bonds in compressed sparse row form: the bonds of point i are
// [offset[i], offset[i+1]). Each bond is stored from both ends, so a point owns and
// accumulates its own bonds without atomics, and per-bond data may differ by direction
// (quadrature weights with w_ij != w_ji, nodal-FE V_ij).
//
// A lean list (BondOptions::lean) keeps only what the PMB kernel reads: partner, a
// single-precision weight and the mask, 9 bytes per bond instead of 45. Its xi and |xi| are
// recomputed from the positions when needed: x_j - x_i is one IEEE subtraction either way, so
// the numbers are bitwise those a full list stores. The float weight rounds each pair force
// by at most 2^-24 relative; stretches, and so every break decision, stay in double.
struct BondList {
  double horizon = 0;                          // delta [m]
  LargeArray<std::int64_t> offset;             // size n + 1
  LargeArray<std::int32_t> neighbor;           // partner j
  std::array<std::vector<double>, 3> xi;       // reference bond vector x_j - x_i [m] (full lists)
  std::vector<double> length;                  // |xi| [m] (full lists)
  std::vector<double> weight;                  // quadrature weight of j in i's ball [m^3, m^2 in 2D] (full lists)
  LargeArray<float> weight_f;                  // the same weight in single precision (lean lists)
  LargeArray<std::uint8_t> intact;             // 1 while the bond carries force; fracture clears it

  bool lean() const { return weight.empty() && !weight_f.empty(); }
  // A compact list keeps partner, double weight and mask, 13 bytes per bond: RNP's and LPS's
  // explicit force passes and observers read xi and |xi| from the positions instead (the same
  // bits, since every builder stores x_j - x_i and bond_length of it).
  bool compact() const { return length.empty() && !weight.empty(); }
  bool stores_geometry() const { return !length.empty(); }
  double weight_of(std::int64_t b) const { return weight.empty() ? double(weight_f[std::size_t(b)]) : weight[std::size_t(b)]; }

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
  // Bytes of the list (every per-bond array that is stored, and the CSR offsets), by their
  // sizes: storage past a size is either never written or handed back (release_spare).
  std::size_t bytes() const {
    std::size_t b = offset.size() * sizeof(std::int64_t) + neighbor.size() * sizeof(std::int32_t);
    for (const auto& c : xi) b += c.size() * sizeof(double);
    b += (length.size() + weight.size()) * sizeof(double) + weight_f.size() * sizeof(float);
    return b + intact.size() * sizeof(std::uint8_t);
  }
  double bytes_per_bond() const { return size() ? double(bytes()) / double(size()) : 0.0; }
  // Hands back the pages a list cut down in place keeps past its size (release_spare_pages):
  // the LPS set-up drops the collar's bonds, about half of a 3D cloud's.
  void release_spare() {
    release_spare_pages(offset), release_spare_pages(neighbor), release_spare_pages(length), release_spare_pages(weight);
    release_spare_pages(weight_f), release_spare_pages(intact);
    for (auto& c : xi) release_spare_pages(c);
  }
  // Makes a full list compact once its set-up no longer needs xi and |xi| stored (LPS's weights
  // and moments are built on the full list), handing their memory back.
  void drop_geometry() {
    for (auto& c : xi) std::vector<double>().swap(c);
    std::vector<double>().swap(length);
  }
  // Keeps a float copy of the double weights beside them (explicit LPS in single precision,
  // whose frames and observers still read the doubles): made once, 4 bytes per bond.
  void add_float_weights() {
    if (weight_f.size() == weight.size()) return;
    weight_f.resize(weight.size());
    for (std::size_t b = 0; b < weight.size(); ++b) weight_f[b] = float(weight[b]);
  }
  // The fracture state per directed bond, one byte each (1 intact, 0 broken).
  std::span<std::uint8_t> states() { return {intact.data(), intact.size()}; }
  std::span<const std::uint8_t> states() const { return {intact.data(), intact.size()}; }
  static constexpr const char* name = "bond list";
  const char* storage() const {
    return lean() ? "lean list: partner, float weight, mask" : compact() ? "compact list: partner, weight, mask" : "list: partner, xi, |xi|, weight, mask";
  }
};

}  // namespace peridot
