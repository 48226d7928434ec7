#pragma once
// What the fuzz targets share: a scratch folder of their own per process (libFuzzer's -jobs and
// -fork run several at once) into which the readers that take a path get the input as a file.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <string>

namespace fuzz {

// $TMPDIR/peridot_fuzz_<target>_<pid>, created on first use and removed at exit.
inline const std::filesystem::path& scratch(const char* target) {
  static const std::filesystem::path dir = [&] {
    auto d = std::filesystem::temp_directory_path() / (std::string("peridot_fuzz_") + target + "_" + std::to_string(::getpid()));
    std::filesystem::create_directories(d);
    static const struct Remove {
      std::filesystem::path d;
      ~Remove() {
        std::error_code ec;
        std::filesystem::remove_all(d, ec);
      }
    } remove{d};
    return d;
  }();
  return dir;
}

// The input as the whole content of `file`.
inline void write(const std::filesystem::path& file, const std::uint8_t* data, std::size_t size) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), std::streamsize(size));
}

// A clean refusal: silent, or printed with PERIDOT_FUZZ_VERBOSE set (to see why a corpus file
// is refused: PERIDOT_FUZZ_VERBOSE=1 build/asan/tests/fuzz/fuzz_deck FILE).
inline void refused(const std::exception& e) {
  static const bool verbose = std::getenv("PERIDOT_FUZZ_VERBOSE") != nullptr;
  if (verbose) std::fprintf(stderr, "refused: %s\n", e.what());
}

}  // namespace fuzz
