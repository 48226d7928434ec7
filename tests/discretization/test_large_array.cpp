#include <catch2/catch.hpp>
#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <vector>
import peridot.discretization;

using namespace peridot;

namespace {

// Resident pages of [first, last) as the kernel reports them (mincore), the range widened to
// whole pages.
std::size_t resident_pages(const void* first, const void* last) {
  const auto page = std::uintptr_t(sysconf(_SC_PAGESIZE));
  const auto a = reinterpret_cast<std::uintptr_t>(first) / page * page;
  const auto b = (reinterpret_cast<std::uintptr_t>(last) + page - 1) / page * page;
  std::vector<unsigned char> in((b - a) / page);
  REQUIRE(mincore(reinterpret_cast<void*>(a), b - a, in.data()) == 0);
  std::size_t n = 0;
  for (unsigned char c : in) n += c & 1;
  return n;
}

}  // namespace

TEST_CASE("an array cut down in place hands the pages past its size back to the system and keeps its values") {
  for (bool large : {false, true}) {  // std::vector's storage, and LargeArray's (huge-page advised)
    INFO((large ? "LargeArray" : "std::vector"));
    constexpr std::size_t n = std::size_t(8) << 20, kept = std::size_t(3) << 20;  // 64 MiB of doubles, 24 MiB kept
    std::vector<double> plain;
    LargeArray<double> big;
    const auto run = [&](auto& v) {
      v.resize(n);
      for (std::size_t i = 0; i < n; ++i) v[i] = double(i) + 0.5;
      v.resize(kept);
      const double* data = v.data();
      // Written and still held: every page of the whole block is resident.
      CHECK(resident_pages(data, data + n) * std::size_t(sysconf(_SC_PAGESIZE)) >= n * sizeof(double) * 9 / 10);
      release_spare_pages(v);
      CHECK(v.data() == data);  // nothing copied
      const auto page = std::size_t(sysconf(_SC_PAGESIZE));
      // The tail's whole pages (past the page of the last kept value, short of the page the block
      // ends in, which may hold the allocator's next block): none resident.
      CHECK(resident_pages(data + kept + page / sizeof(double), data + n - page / sizeof(double)) == 0);
      // The kept values, untouched.
      std::size_t wrong = 0;
      for (std::size_t i = 0; i < kept; ++i) wrong += v[i] != double(i) + 0.5;
      CHECK(wrong == 0);
      // Growing into the handed-back pages again works (they read as zero before being written).
      v.resize(n);
      v[n - 1] = 1.0;
      CHECK(v[n - 1] == 1.0);
    };
    if (large) run(big);
    else run(plain);
  }
}
