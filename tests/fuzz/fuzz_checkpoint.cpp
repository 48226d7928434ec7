// read_checkpoint (`peridot run --restart`) on a fuzzed HDF5 file in this process's scratch
// folder. std::runtime_error is a clean refusal; anything else is a finding.
#include <cstddef>
#include <cstdint>
#include <stdexcept>

#include "fuzz_support.hpp"
import peridot.io;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto file = fuzz::scratch("checkpoint") / "input.h5";
  fuzz::write(file, data, size);
  try {
    peridot::read_checkpoint(file);
  } catch (const std::runtime_error& e) {
    fuzz::refused(e);
  }
  return 0;
}
