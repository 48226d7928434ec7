module;
#include <sys/mman.h>
#include <unistd.h>

export module peridot.discretization:large_array;
import peridot.std;

export namespace peridot {

// The allocator of the per-bond arrays, which hold most of a run's memory (10^8 bonds at the
// 512k-point 3D deck).
//  - resize() default-initialises, which for these trivial types writes nothing: the parallel
//    fill that follows is the first touch, so pages fault in on every thread instead of in
//    one serial memset;
//  - blocks of 4 MiB and up are 2 MiB-aligned and advised as transparent huge pages: 512 times
//    fewer page faults (1.5 s of the 5.8 s set-up of that deck on this machine).
template <class T>
struct LargeArrayAllocator {
  using value_type = T;
  static constexpr std::size_t huge_page = std::size_t(2) << 20;
  static constexpr std::size_t huge_threshold = std::size_t(4) << 20;

  LargeArrayAllocator() = default;
  template <class U>
  LargeArrayAllocator(const LargeArrayAllocator<U>&) noexcept {}

  T* allocate(std::size_t n) {
    const std::size_t bytes = n * sizeof(T);
    if (bytes < huge_threshold) return static_cast<T*>(::operator new(bytes));
    const std::size_t rounded = (bytes + huge_page - 1) / huge_page * huge_page;
    void* p = std::aligned_alloc(huge_page, rounded);
    if (!p) throw std::bad_alloc();
    madvise(p, rounded, MADV_HUGEPAGE);  // advice only: without THP this is a no-op
    return static_cast<T*>(p);
  }
  void deallocate(T* p, std::size_t n) noexcept {
    if (n * sizeof(T) < huge_threshold) ::operator delete(p);
    else std::free(p);
  }
  template <class U>
  void construct(U* p) noexcept {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
  friend bool operator==(const LargeArrayAllocator&, const LargeArrayAllocator&) { return true; }
};

// A std::vector whose resize() leaves new elements unwritten: every user fills what it sizes.
template <class T>
using LargeArray = std::vector<T, LargeArrayAllocator<T>>;

// Hands the whole pages of a vector's storage past its size back to the system: resize() never
// shrinks storage, and an array cut down in place would keep its written tail resident. Unlike
// shrink_to_fit it copies nothing, so it adds no second array to the peak. The pages read as
// zero if the vector grows into them again.
template <class V>
void release_spare_pages(V& v) {
  const auto page = std::size_t(sysconf(_SC_PAGESIZE));
  auto first = reinterpret_cast<std::size_t>(v.data() + v.size()), last = reinterpret_cast<std::size_t>(v.data() + v.capacity());
  first = (first + page - 1) / page * page;
  last = last / page * page;
  if (last > first) madvise(reinterpret_cast<void*>(first), last - first, MADV_DONTNEED);
}

}  // namespace peridot
