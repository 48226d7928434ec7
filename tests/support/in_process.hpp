#pragma once
// Decks run in-process through the library, as `peridot run` would run them, for tests that
// need a run but do not test the CLI itself (those start the peridot executable: test_cli.cpp).
//   in_process::run_deck(deck, out, 2);                   // peridot run DECK --out OUT --threads 2
//   in_process::run_deck(deck, out, 1, checkpoint);       //   ... --threads 1 --restart CHECKPOINT
//   CHECK(in_process::refusal(deck, out).find("...") != std::string::npos);  // a DeckError, before any file
#include <catch2/catch.hpp>
#include <omp.h>
#include <unistd.h>

#include <exception>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <utility>
#include <vector>
#include "deck_text.hpp"
import peridot.run;

namespace in_process {

// Per-process temporary names: ctest runs the test cases of a file in parallel.
inline std::filesystem::path temp(const std::string& prefix, const std::string& name) {
  return std::filesystem::temp_directory_path() / (prefix + std::to_string(getpid()) + "_" + name);
}

// OpenMP threads for one run (`peridot run --threads N`; 0: the default), put back after it.
struct Threads {
  int before = omp_get_max_threads();
  explicit Threads(int n) {
    if (n > 0) omp_set_num_threads(n);
  }
  ~Threads() { omp_set_num_threads(before); }
  Threads(const Threads&) = delete;
  Threads& operator=(const Threads&) = delete;
};

// The deck file run to its end (or on from the checkpoint `restart`) into `out`, on `threads`
// threads; requires a run that was not interrupted. Its report goes nowhere.
inline peridot::RunOutcome run_deck(const std::filesystem::path& deck, const std::filesystem::path& out, int threads = 0,
                                    const std::optional<std::filesystem::path>& restart = std::nullopt) {
  const Threads t(threads);
  peridot::RunOptions options;
  options.out_dir = out;
  options.restart = restart;
  const peridot::RunOutcome outcome = peridot::Simulation(peridot::read_deck(deck), options).run();
  REQUIRE(outcome.exit_status() == 0);
  return outcome;
}

// The message of the DeckError the deck file is refused with (with `restart`, into `out`)
// while it is read and composed, before a run could start and write a file. A deck that is
// not refused, or refused with another exception, fails the test case's check and gives "".
inline std::string refusal(const std::filesystem::path& deck, const std::filesystem::path& out,
                           const std::optional<std::filesystem::path>& restart = std::nullopt) {
  peridot::RunOptions options;
  options.out_dir = out;
  options.restart = restart;
  try {
    const peridot::Simulation simulation(peridot::read_deck(deck), options);
  } catch (const peridot::DeckError& e) {
    return e.what();
  } catch (const std::exception& e) {
    FAIL_CHECK("refused, but not with a DeckError: " << e.what());
    return "";
  }
  FAIL_CHECK(deck.string() << " was not refused");
  return "";
}

// A shipped deck (`deck`, under data/decks) with pieces of its text replaced (`edits`: pairs of
// old, new; each old one must be there), written into the fresh per-process folder
// temp(prefix, name) and run there on `threads` threads. Returns the folder, for the caller
// to read and remove.
inline std::filesystem::path run_edited(const std::string& deck, const std::vector<std::pair<std::string, std::string>>& edits,
                                        const std::string& prefix, const std::string& name, int threads) {
  std::string text = deck_text::file_text(std::filesystem::path(PERIDOT_SOURCE_DIR) / "data/decks" / deck);
  for (const auto& [from, to] : edits) text = deck_text::replaced(text, from, to);
  const auto dir = temp(prefix, name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "deck.yaml") << text;
  run_deck(dir / "deck.yaml", dir, threads);
  return dir;
}

}  // namespace in_process
