#pragma once
// Deck variants for input tests: a valid deck with one piece of text replaced.
#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace deck_text {

inline std::string replaced(std::string deck, const std::string& from, const std::string& to) {
  const auto p = deck.find(from);
  REQUIRE(p != std::string::npos);
  return deck.replace(p, from.size(), to);
}

// A whole text file (a deck, a .pvd) as a string.
inline std::string file_text(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace deck_text
