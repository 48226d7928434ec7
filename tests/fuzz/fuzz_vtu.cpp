// The readers behind `peridot render`: the input is written as a .vtu, a .pvtu and a .pvd in
// this process's scratch folder and read as each (a .pvtu's pieces resolve next to it, so a
// piece named input.vtu is the same input read as a VTU). std::runtime_error and
// std::invalid_argument are clean refusals; anything else is a finding, and so is a VtuData
// that breaks read_vtu's promise (the renderer indexes arrays by it without checking).
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>

#include "fuzz_support.hpp"
import peridot.io;

namespace {

void require(bool ok, const char* what) {
  if (ok) return;
  std::fprintf(stderr, "fuzz_vtu: read_vtu returned data that breaks its promise: %s\n", what);
  std::abort();
}

void check(const peridot::VtuData& d) {
  const std::size_t n = d.x[0].size();
  require(d.x[1].size() == n && d.x[2].size() == n, "coordinate arrays of different lengths");
  for (const auto& a : d.arrays) {
    require(a.components >= 1 && a.components <= 9, "components outside 1..9");
    require(a.values.size() == n * std::size_t(a.components), "an array's length is not components x points");
  }
  for (auto c : d.connectivity) require(c >= 0 && std::size_t(c) < n, "a connectivity entry is not a point index");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto& dir = fuzz::scratch("vtu");
  for (const char* name : {"input.vtu", "input.pvtu", "input.pvd"}) fuzz::write(dir / name, data, size);
  for (const char* name : {"input.vtu", "input.pvtu"}) {
    try {
      check(peridot::read_vtu(dir / name));
    } catch (const std::invalid_argument& e) {
      fuzz::refused(e);
    } catch (const std::runtime_error& e) {
      fuzz::refused(e);
    }
  }
  try {
    for (const auto& [time, file] : peridot::read_pvd(dir / "input.pvd")) require(!file.empty(), "an empty file name");
  } catch (const std::invalid_argument& e) {
    fuzz::refused(e);
  } catch (const std::runtime_error& e) {
    fuzz::refused(e);
  }
  return 0;
}
