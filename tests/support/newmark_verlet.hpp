#pragma once
// Newmark against velocity Verlet on the same LPS deck: under a step load, which excites every
// frequency, the two schemes' phase errors differ by O(dt^2).
#include <algorithm>
#include <cmath>
#include <variant>
#include <catch2/catch.hpp>
import peridot.problem;

namespace newmark_verlet {

// Largest |u_verlet - u_newmark| over the points at end_time, relative to the largest |u_verlet|.
inline double relative_difference(const peridot::Problem& explicit_deck, const peridot::Problem& newmark_deck, double end_time) {
  using namespace peridot;
  auto e = compose(explicit_deck);
  auto& es = std::get<Setup>(e);
  ExplicitSolver<Lps> verlet(es.body, std::get<Lps>(es.model), es.boundaries, es.time_step);
  State a(es.body.size());
  verlet.initialize(a);
  for (std::size_t k = 0; k < es.time_step.steps; ++k) verlet.step(a);
  auto n = compose(newmark_deck);
  auto& ns = std::get<NewmarkSetup>(n);
  NewmarkSolver<Lps> newmark(ns.body, ns.model, ns.boundaries, ns.options);
  State b(ns.body.size());
  newmark.initialize(b);
  for (std::size_t k = 0; k < newmark.steps(); ++k) newmark.step(b);
  REQUIRE(a.time == Approx(end_time));
  REQUIRE(b.time == Approx(end_time));
  double diff = 0, size = 0;
  for (std::size_t i = 0; i < es.body.size(); ++i) {
    double d2 = 0, u2 = 0;
    for (std::size_t k = 0; k < 3; ++k) {
      d2 += (a.u[k][i] - b.u[k][i]) * (a.u[k][i] - b.u[k][i]);
      u2 += a.u[k][i] * a.u[k][i];
    }
    diff = std::max(diff, std::sqrt(d2));
    size = std::max(size, std::sqrt(u2));
  }
  REQUIRE(size > 1e-9);
  return diff / size;
}

}  // namespace newmark_verlet
