#pragma once
// Test-side adapter for static LPS studies: a shipped deck with a few parameters changed, run
// through peridot::refine (the code behind `peridot converge`), with each study's CSV kept
// in <build>/studies/.
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>
import peridot.problem;

namespace study {

using Level = peridot::StudyLevel;

struct Variant {
  double horizon_factor = 3.5;
  double poisson = 0.3;
  double perturbation = 0.0;
  double inclusion_poisson = NAN;  // NaN: as in the deck
  int clouds = 1;                  // perturbed grids: independent random clouds per level
  bool exact_normal = false;       // static.neumann[].normal: exact
};

// A bare name is a deck of data/decks/lps/; a name with a folder ("lps_3d/x.yaml") is relative
// to data/decks/.
inline std::string deck_path(const std::string& name) {
  return std::string(PERIDOT_SOURCE_DIR) + "/data/decks/" + (name.find('/') == std::string::npos ? "lps/" + name : name);
}

inline peridot::Problem problem(const std::string& deck, const Variant& v) {
  peridot::Problem p = peridot::read_deck(deck_path(deck));
  p.horizon = v.horizon_factor * p.lattice.spacing;
  p.material.poisson_ratio = v.poisson;
  p.lattice.perturbation = v.perturbation;
  if (!std::isnan(v.inclusion_poisson))
    for (auto& in : p.inclusions) in.poisson_ratio = v.inclusion_poisson;
  for (auto& n : p.statics.neumann) n.exact_normal = v.exact_normal;
  return p;
}

// One solve at `cells` cells across the body's x extent, on the cloud of `seed`.
inline Level run(const std::string& deck, int cells, const Variant& v, std::uint64_t seed = 1) {
  auto p = problem(deck, v);
  p.lattice.seed = seed;
  return peridot::refine(p, {.cells = {cells}}).front();
}

inline double order(const std::vector<Level>& levels, bool theta) { return peridot::fitted_order(levels, theta); }

inline std::vector<Level> refine(const std::string& deck, const std::vector<int>& cells, const Variant& v, const std::string& name) {
  const auto levels = peridot::refine(problem(deck, v), {.cells = cells, .clouds = v.clouds});
  const auto dir = std::filesystem::path(PERIDOT_BINARY_DIR) / "studies";
  std::filesystem::create_directories(dir);
  peridot::write_study_csv(dir / (name + ".csv"), levels);
  return levels;
}

}  // namespace study
