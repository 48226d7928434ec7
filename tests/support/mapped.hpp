// Whether this process has mapped a shared library whose path contains `library`: the
// process's own memory map is an independent witness of what was loaded.
#pragma once
#include <fstream>
#include <iterator>
#include <string>

inline bool mapped(const std::string& library) {
  std::ifstream maps("/proc/self/maps");
  const std::string text{std::istreambuf_iterator<char>(maps), {}};
  return text.find(library) != std::string::npos;
}
