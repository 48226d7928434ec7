#pragma once
// Shared helpers for the static LPS studies (default suite and the `paper` label).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>
import peridot.io;

namespace study {

struct Level {
  int cells;
  double h;
  peridot::StaticErrors errors;
};

struct Variant {
  double horizon_factor = 3.5;
  double poisson = 0.3;
  double perturbation = 0.0;
  double inclusion_poisson = NAN;  // NaN: as in the deck
  int clouds = 1;                  // perturbed grids: independent random clouds per level
};

inline std::string deck_path(const std::string& name) { return std::string(PERIDOT_SOURCE_DIR) + "/data/decks/lps/" + name; }

// Runs a static deck at `cells` cells across the body's x extent, on the cloud of `seed`.
inline Level run(const std::string& deck, int cells, const Variant& v, std::uint64_t seed = 1) {
  peridot::Problem p = peridot::read_deck(deck_path(deck));
  const auto box = p.body.bounds();
  p.lattice.spacing = (box.hi[0] - box.lo[0]) / cells;
  p.horizon = v.horizon_factor * p.lattice.spacing;
  p.material.poisson_ratio = v.poisson;
  p.lattice.perturbation = v.perturbation;
  p.lattice.seed = seed;
  if (!std::isnan(v.inclusion_poisson))
    for (auto& in : p.inclusions) in.poisson_ratio = v.inclusion_poisson;
  const auto s = peridot::setup_static(p);
  const auto r = peridot::solve_static_lps(s.body, s.model, s.problem, s.options);
  if (!(r.residual < 1e-8)) throw std::runtime_error("linear solve residual too large");
  return {cells, p.lattice.spacing, peridot::static_errors(s, r)};
}

// Slope of the least-squares line through (log h, log e).
inline double order(const std::vector<Level>& levels, bool theta) {
  double mh = 0, me = 0;
  const double n = double(levels.size());
  for (const auto& l : levels) mh += std::log(l.h) / n, me += std::log(theta ? l.errors.theta : l.errors.u) / n;
  double num = 0, den = 0;
  for (const auto& l : levels) {
    const double dh = std::log(l.h) - mh;
    num += dh * (std::log(theta ? l.errors.theta : l.errors.u) - me);
    den += dh * dh;
  }
  return num / den;
}

// Runs a refinement study and writes (h, error u, error theta, order) to <build>/studies/<name>.csv.
// On perturbed grids with v.clouds > 1 each level's errors are the root mean square over that
// many random clouds: one cloud per level makes boundary errors, and so the slope, erratic.
inline std::vector<Level> refine(const std::string& deck, const std::vector<int>& cells, const Variant& v, const std::string& name) {
  std::vector<Level> levels;
  const int clouds = v.perturbation > 0 ? std::max(1, v.clouds) : 1;
  for (int c : cells) {
    Level mean = run(deck, c, v, 1);
    double su = mean.errors.u * mean.errors.u, st = mean.errors.theta * mean.errors.theta;
    for (int k = 2; k <= clouds; ++k) {
      const Level l = run(deck, c, v, std::uint64_t(k));
      su += l.errors.u * l.errors.u, st += l.errors.theta * l.errors.theta;
    }
    mean.errors.u = std::sqrt(su / clouds);
    mean.errors.theta = std::sqrt(st / clouds);
    levels.push_back(mean);
  }
  const auto dir = std::filesystem::path(PERIDOT_BINARY_DIR) / "studies";
  std::filesystem::create_directories(dir);
  std::ofstream csv(dir / (name + ".csv"));
  csv << "cells,h,error_u,error_theta,order_u,order_theta\n";
  for (std::size_t k = 0; k < levels.size(); ++k) {
    const auto& l = levels[k];
    double ou = NAN, ot = NAN;
    if (k > 0) {
      const double r = std::log(levels[k - 1].h / l.h);
      ou = std::log(levels[k - 1].errors.u / l.errors.u) / r;
      ot = std::log(levels[k - 1].errors.theta / l.errors.theta) / r;
    }
    csv << l.cells << ',' << l.h << ',' << l.errors.u << ',' << l.errors.theta << ',' << ou << ',' << ot << '\n';
  }
  return levels;
}

}  // namespace study
