// `peridot check` on a fuzzed deck: parse_deck, then compose (points, bonds, weights), with
// the memory cap low so that a large body is refused in milliseconds instead of allocated:
// 8 MiB (PERIDOT_FUZZ_MEMORY_MIB overrides). In the Debug + ASan + coverage build a static
// or dynamic LPS body composes at a few MiB a second (a 16 MiB one took 7.6 s on 2 busy
// cores), so at 8 MiB the largest body a mutation can ask for still composes well inside
// tools/fuzz.sh's -timeout=10, and a timeout is a hang, not a big body.
// Relative mesh paths resolve against $PERIDOT_FUZZ_FILES (tools/fuzz.sh: a scratch copy of
// tests/fuzz/files), else the working directory. A DeckError, std::invalid_argument or
// std::runtime_error is a clean refusal; anything else escaping, a crash, a sanitizer report,
// a hang or an allocation past -rss_limit_mb is a finding.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <variant>

#include "fuzz_support.hpp"
import peridot.problem;

namespace {

std::filesystem::path files_dir() {
  const char* env = std::getenv("PERIDOT_FUZZ_FILES");
  return env && *env ? std::filesystem::path(env) : std::filesystem::current_path();
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  const char* mib = std::getenv("PERIDOT_FUZZ_MEMORY_MIB");
  peridot::limit_memory_bytes((mib && *mib ? std::atof(mib) : 8.0) * 1024 * 1024);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::filesystem::path base = files_dir();
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const peridot::Problem p = peridot::parse_deck(text, "fuzz.yaml", base);
    const auto composed = peridot::compose(p);
    if (const auto* st = std::get_if<peridot::StaticSetup>(&composed)) peridot::check_petsc_options(*st);
  } catch (const std::invalid_argument& e) {
    fuzz::refused(e);
  } catch (const std::runtime_error& e) {  // DeckError among them
    fuzz::refused(e);
  }
  return 0;
}
