#pragma once
// Whether a directory (and its subdirectories) holds no leftover `.tmp` file: every atomic
// writer renames its .tmp on success and removes it on failure.
#include <filesystem>

namespace no_tmp {

inline bool left_in(const std::filesystem::path& dir) {
  for (const auto& e : std::filesystem::recursive_directory_iterator(dir))
    if (e.path().extension() == ".tmp") return false;
  return true;
}

}  // namespace no_tmp
