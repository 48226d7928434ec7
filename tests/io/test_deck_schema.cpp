#include <catch2/catch.hpp>
#include <unistd.h>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>
import peridot.problem;

using namespace peridot;
namespace fs = std::filesystem;

namespace {

const std::set<std::string> shape_kinds{"interval", "rectangle", "box", "disk", "sphere", "annulus", "cylinder_shell", "polygon", "layer"};

// geometry.body.difference... -> shape.<kind>.<key>: shapes read the same keys wherever they
// appear, and the schema documents them once. Crack kinds are not shapes.
std::string normalised(const std::string& path) {
  if (path.rfind("geometry.cracks", 0) == 0) return path;
  std::vector<std::string> parts;
  std::stringstream ss(path);
  for (std::string p; std::getline(ss, p, '.');) parts.push_back(p);
  for (std::size_t k = 0; k < parts.size(); ++k)
    if (shape_kinds.count(parts[k]) && k + 1 < parts.size()) return "shape." + parts[k] + "." + parts[k + 1];
  return path;
}

// Every key path the parser asks about while reading the shipped decks and the test decks
// that exercise the remaining keys.
std::set<std::string> parser_keys() {
  DeckKeyLog log;
  set_deck_key_log(&log);
  std::vector<fs::path> decks;
  for (const auto* dir : {"/data/decks", "/data/decks/lps", "/data/decks/rnp", "/data/decks/fe", "/data/decks/osb", "/data/decks/lps_dynamic", "/tests/io/decks"})
    for (const auto& e : fs::directory_iterator(std::string(PERIDOT_SOURCE_DIR) + dir))
      if (e.path().extension() == ".yaml") decks.push_back(e.path());
  // Reading a deck meshes its .geo file: at the paper decks' sizes that is a minute of Gmsh for
  // nothing the key log needs. Those decks are read from a copy with a coarse mesh size (the
  // same keys, another value), beside copies of their .geo files.
  const fs::path coarse = fs::temp_directory_path() / ("peridot_schema_" + std::to_string(::getpid()));
  fs::create_directories(coarse);
  const std::regex mesh_size("(mesh: \\{file: [^,]+, size: )[0-9.eE+-]+\\}");
  for (const auto& d : decks) {
    INFO(d.string());
    std::ifstream in(d);
    std::stringstream text;
    text << in.rdbuf();
    const std::string original = text.str();
    if (!std::regex_search(original, mesh_size)) {
      CHECK_NOTHROW(read_deck(d));
      continue;
    }
    for (const auto& e : fs::directory_iterator(d.parent_path()))
      if (e.path().extension() == ".geo") fs::copy_file(e.path(), coarse / e.path().filename(), fs::copy_options::overwrite_existing);
    const fs::path copy = coarse / d.filename();
    std::ofstream(copy) << std::regex_replace(original, mesh_size, "$012.0e-3}");
    CHECK_NOTHROW(read_deck(copy));
  }
  fs::remove_all(coarse);
  set_deck_key_log(nullptr);
  std::set<std::string> keys;
  for (const auto& k : log.keys) keys.insert(normalised(k));
  return keys;
}

// The first column of every "| key |" table in data/decks/README.md: `a.b`, `.c` (a sibling of
// the previous key) and shape keys (`rectangle.min`, listed under Shapes).
std::set<std::string> documented_keys() {
  std::ifstream in(std::string(PERIDOT_SOURCE_DIR) + "/data/decks/README.md");
  REQUIRE(in);
  std::set<std::string> keys;
  bool in_key_table = false;
  const std::regex tick("`([^`]+)`");
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("| key |", 0) == 0) {
      in_key_table = true;
      continue;
    }
    if (line.rfind("|", 0) != 0) {
      in_key_table = false;
      continue;
    }
    if (!in_key_table || line.rfind("|---", 0) == 0) continue;
    const auto cell = line.substr(1, line.find('|', 1) - 1);
    std::string previous;
    for (auto it = std::sregex_iterator(cell.begin(), cell.end(), tick); it != std::sregex_iterator(); ++it) {
      std::string k = (*it)[1];
      if (k.front() == '.') k = previous.substr(0, previous.rfind('.')) + k;
      previous = k;
      keys.insert(shape_kinds.count(k.substr(0, k.find('.'))) ? "shape." + k : k);
    }
  }
  return keys;
}

}  // namespace

TEST_CASE("data/decks/README.md documents exactly the keys the deck parser reads") {
  const auto parsed = parser_keys();
  const auto documented = documented_keys();
  REQUIRE(parsed.size() > 50);
  // Leaves: keys that are not a section holding other keys.
  for (const auto& k : parsed) {
    bool section = false;
    for (const auto& other : parsed)
      if (other.size() > k.size() && other.compare(0, k.size(), k) == 0 && (other[k.size()] == '.' || other[k.size()] == '['))
        section = true;
    INFO("the parser reads '" << k << "', which data/decks/README.md does not document");
    CHECK((section || documented.count(k)));
  }
  for (const auto& k : documented) {
    INFO("data/decks/README.md documents '" << k << "', which the parser never reads");
    CHECK(parsed.count(k));
  }
}

// The dense SVD behind output.condition_number is O(n^3): its limit is an input error, found
// when the run is composed, before any output exists (not after the first load step).
TEST_CASE("a quasi-static deck whose condition number would need a dense SVD past the limit is refused when composed") {
  std::ifstream in(fs::path(PERIDOT_SOURCE_DIR) / "data/decks/rnp/plate_2d_crack_condition.yaml");
  std::stringstream ss;
  ss << in.rdbuf();
  std::string deck = ss.str();
  const std::string coarse = "spacing: 0.1";
  REQUIRE(deck.find(coarse) != std::string::npos);
  // The shipped deck: 16 x 16 points (cell centres), far below the limit.
  CHECK_NOTHROW(compose(parse_deck(deck)));
  // 80 x 80 cell centres, the 5 columns at x > 1.5 clamped: (80 - 5) x 80 x 2 = 12000 unknowns.
  deck.replace(deck.find(coarse), coarse.size(), "spacing: 0.02");
  CHECK_THROWS_WITH(compose(parse_deck(deck)), Catch::Contains("output.condition_number") && Catch::Contains("12000 unknowns") &&
                                                   Catch::Contains("4000"));
}
