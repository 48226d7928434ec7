// read_gmsh_mesh on a fuzzed .msh file in this process's scratch folder (Gmsh parses it; the
// checks after it are Peridot's). std::invalid_argument is the reader's only clean refusal;
// anything else is a finding.
#include <cstddef>
#include <cstdint>
#include <stdexcept>

#include "fuzz_support.hpp"
import peridot.io;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto file = fuzz::scratch("gmsh") / "input.msh";
  fuzz::write(file, data, size);
  try {
    peridot::read_gmsh_mesh(file);
  } catch (const std::invalid_argument& e) {
    fuzz::refused(e);
  }
  return 0;
}
