#pragma once
// Deck variants for input tests: a valid deck with one piece of text replaced.
#include <catch2/catch.hpp>
#include <string>

namespace deck_text {

inline std::string replaced(std::string deck, const std::string& from, const std::string& to) {
  const auto p = deck.find(from);
  REQUIRE(p != std::string::npos);
  return deck.replace(p, from.size(), to);
}

}  // namespace deck_text
