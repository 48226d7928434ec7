#pragma once
// Seed 003 Sec. 4.1 from the shipped deck data/decks/fe/convergence.yaml, run in-process at
// another mesh size and end time, with displacement snapshots at every output time. Shared by
// the default suite (m = 2, 4, 8) and the paper suite (m = 4, 8, 12, 16).
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <variant>
#include <utility>
#include <vector>
#include "deck_text.hpp"
import peridot.problem;

namespace fe_study {

using namespace peridot;

inline std::string deck_path() { return std::string(PERIDOT_SOURCE_DIR) + "/data/decks/fe/convergence.yaml"; }

// The deck with h = eps / m (eps = 0.05 on the unit square: 20 m cells a side).
inline Problem convergence_problem(int m, double end_time, ExplicitScheme scheme = ExplicitScheme::central_difference) {
  std::ifstream in(deck_path());
  std::stringstream text;
  text << in.rdbuf();
  std::string deck = text.str();
  const std::string cells = "cells: [80, 80]";
  deck.replace(deck.find(cells), cells.size(), "cells: [" + std::to_string(20 * m) + ", " + std::to_string(20 * m) + "]");
  Problem p = parse_deck(deck, deck_path());
  p.solver.end_time = end_time;
  p.solver.scheme = scheme;
  return p;
}

struct Snapshots {
  std::shared_ptr<const TriangleMesh> mesh;
  std::vector<double> times;
  std::vector<std::vector<double>> ux, uy;
};

// Runs a deck's problem with its own scheme and calls sample(body, model, state) every `every`
// steps and after the last one.
template <class Sample>
void run_deck(const Problem& p, std::size_t every, Sample&& sample) {
  Setup s = setup(p);
  const auto& model = std::get<Rnp>(s.model);
  ExplicitSolver solver(s.body, model, s.boundaries, s.time_step, p.solver.scheme);
  State state(s.body.size());
  solver.initialize(state);
  for (std::size_t k = 0; k < s.time_step.steps; ++k) {
    solver.step(state);
    if (state.step % every == 0 || k + 1 == s.time_step.steps) sample(s.body, model, state);
  }
}

// A shipped deck of data/decks/fe/ with another end time.
inline Problem fe_deck(const std::string& name, double end_time) {
  Problem p = read_deck(std::string(PERIDOT_SOURCE_DIR) + "/data/decks/fe/" + name);
  p.solver.end_time = end_time;
  return p;
}

// The same with pieces of its text replaced first (`edits`: pairs of old, new), for reduced
// runs: a coarser mesh size, another dt. Each old piece must be in the deck.
inline Problem fe_deck(const std::string& name, double end_time, const std::vector<std::pair<std::string, std::string>>& edits) {
  const std::filesystem::path file = std::string(PERIDOT_SOURCE_DIR) + "/data/decks/fe/" + name;
  std::string text = deck_text::file_text(file);
  for (const auto& [from, to] : edits) text = deck_text::replaced(text, from, to);
  Problem p = parse_deck(text, file.string(), file.parent_path());
  p.solver.end_time = end_time;
  return p;
}

// Runs the problem, keeping u every `every` steps (the deck's dt = 1.25e-4 s: 80 steps = 0.01 s,
// the paper's output interval).
inline Snapshots run(const Problem& p, std::size_t every = 80) {
  Snapshots out{p.mesh.mesh, {}, {}, {}};
  run_deck(p, every, [&](const Body&, const Rnp&, const State& state) {
    if (state.step % every) return;
    out.times.push_back(state.time);
    out.ux.push_back(state.u[0]);
    out.uy.push_back(state.u[1]);
  });
  return out;
}

// How ||u_a - u_ref|| is taken over a's mesh, u_ref interpolated (P1) on its own mesh:
// nodal: at a's nodes with lumped areas; p1: the P1 fields integrated by a 7-point rule.
enum class Norm { nodal, p1 };

inline double difference(const Snapshots& a, const Snapshots& ref, const MeshLocator& loc, std::size_t k, Norm norm) {
  const P1Field fa{a.mesh.get(), {&a.ux[k], &a.uy[k]}}, fr{ref.mesh.get(), {&ref.ux[k], &ref.uy[k]}};
  return norm == Norm::nodal ? nodal_l2_difference(fa, fr, loc) : l2_difference(fa, fr, loc);
}

// Rate (87) between meshes of sizes h_a > h_b at every output time, against the reference.
inline std::vector<double> rates(const Snapshots& a, double ha, const Snapshots& b, double hb, const Snapshots& ref, Norm norm) {
  const MeshLocator loc(*ref.mesh);
  std::vector<double> out;
  for (std::size_t k = 0; k < ref.times.size(); ++k)
    out.push_back(std::log(difference(a, ref, loc, k, norm) / difference(b, ref, loc, k, norm)) / std::log(ha / hb));
  return out;
}

}  // namespace fe_study
