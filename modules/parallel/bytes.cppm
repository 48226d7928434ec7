export module peridot.parallel:bytes;
import peridot.std;

export namespace peridot::parallel {

// Arrays of plain values packed one after another, each behind its length, for a broadcast or
// a scatter (broadcast_from_root, scatter_from_root), and read back in the same order.
struct Bytes {
  std::vector<std::uint8_t> data;
  std::size_t at = 0;  // where the next read starts

  template <class T>
  void put(std::span<const T> v) {
    static_assert(std::is_trivially_copyable_v<T>);
    put_count(v.size());
    const auto* p = reinterpret_cast<const std::uint8_t*>(v.data());
    data.insert(data.end(), p, p + v.size_bytes());
  }
  template <class T>
  void put(const std::vector<T>& v) {
    put(std::span<const T>(v));
  }
  void put_count(std::uint64_t n) {
    const auto* p = reinterpret_cast<const std::uint8_t*>(&n);
    data.insert(data.end(), p, p + sizeof n);
  }
  std::uint64_t count() {
    std::uint64_t n = 0;
    take(&n, sizeof n);
    return n;
  }
  template <class T>
  void get(std::vector<T>& v) {
    const std::uint64_t n = count();
    if (n > (data.size() - at) / std::max<std::size_t>(sizeof(T), 1)) throw std::logic_error("packed bytes end early");
    v.resize(n);
    take(v.data(), n * sizeof(T));
  }
  template <class T>
  std::vector<T> get() {
    std::vector<T> v;
    get(v);
    return v;
  }
  void take(void* to, std::size_t n) {
    if (n > data.size() - at) throw std::logic_error("packed bytes end early");
    if (n > 0) std::memcpy(to, data.data() + at, n);
    at += n;
  }
};

}  // namespace peridot::parallel
