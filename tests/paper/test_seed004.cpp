// Seed 004 Ex. 5 and 6 at the paper's grid (dx = 2.5 mm, m = 3) on our guessed specimen
// (data/decks/osb/crack_*.yaml): sequentially linear crack growth with and without the
// fictitious Taylor layer. Writes the crack paths as PNGs to <build>/seed004/ and reports
// whether each run branches (two cracked runs of points along the top edge).
// A crack reaches the top edge where the top row holds a run of points with damage >= 0.3, where
// the plate's intact bonds leave its top row in two pieces, or where the run stopped because the
// plate came apart (under traction: no equilibrium, the pulled part held by at most a hinge, a
// mechanism) with the crack's damage >= 0.3 within one horizon of the top edge. The last is
// crack_neumann_uncorrected's end: the ligament left at the edge is a hinge, and the edge points'
// damage stays below 0.3. Before a run stopped there, re-solves past it removed bonds by the
// noise of the singular solves (9 of them here, residuals 0.9 to 5) and cut the hinge.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <variant>
#include <vector>
import peridot.problem;
import peridot.analysis;
import peridot.render;

using namespace peridot;

namespace {

std::string fmt_title(const std::string& name, std::size_t solves, std::size_t broken) {
  return name + ": damage after " + std::to_string(solves) + " solves, " + std::to_string(broken) + " bonds removed";
}

}  // namespace

TEST_CASE("Ex. 5 and 6 crack paths with and without the correction", "[paper][osb]") {
  const std::filesystem::path out = std::filesystem::path(PERIDOT_BINARY_DIR) / "seed004";
  std::filesystem::create_directories(out);
  for (const std::string name : {"crack_dirichlet", "crack_neumann", "crack_dirichlet_uncorrected", "crack_neumann_uncorrected"}) {
    const Problem p = read_deck(std::string(PERIDOT_SOURCE_DIR) + "/data/decks/osb/" + name + ".yaml");
    auto s = std::get<OsbStaticSetup>(compose(p));
    const auto r = solve_osb_static(s.body, s.model, s.problem, s.options);
    std::vector<double> phi;
    damage(s.body, phi);
    const auto& pc = s.body.points;
    const auto g = lattice_grid(pc);
    int top = -1 << 30;
    for (std::size_t i = 0; i < pc.size(); ++i)
      if (pc.role[i] == Role::interior) top = std::max(top, g.gy[i]);
    int runs = 0;
    bool in_run = false;
    const auto pieces = count_fragments(s.body);
    std::vector<std::int32_t> top_pieces;
    double crack_top = -1e300, top_y = -1e300;  // the highest point with damage >= 0.3, and the top row's y [m]
    for (std::size_t i = 0; i < pc.size(); ++i)
      if (pc.role[i] == Role::interior) {
        top_y = std::max(top_y, pc.x[1][i]);
        if (phi[i] >= 0.3) crack_top = std::max(crack_top, pc.x[1][i]);
      }
    std::vector<double> x, y, d;
    for (std::size_t i = 0; i < pc.size(); ++i) {
      if (pc.role[i] != Role::interior) continue;
      x.push_back(pc.x[0][i]), y.push_back(pc.x[1][i]), d.push_back(phi[i]);
    }
    for (int ix = g.lo[0]; ix < g.lo[0] + g.n[0]; ++ix) {
      const auto i = g.at(ix, top);
      if (i < 0 || pc.role[std::size_t(i)] != Role::interior) continue;
      if (const auto l = pieces.label[std::size_t(i)]; l >= 0) top_pieces.push_back(l);
      const bool cracked = phi[std::size_t(i)] >= 0.3;
      runs += cracked && !in_run;
      in_run = cracked;
    }
    RenderField rf;
    rf.x = {x, y, {}};
    rf.values = d;
    rf.spacing = pc.spacing;
    RenderOptions ro;
    ro.title = fmt_title(name, r.solves, r.broken);
    render_png(out / (name + ".png"), rf, ro);
    std::ranges::sort(top_pieces);
    const auto cut = std::unique(top_pieces.begin(), top_pieces.end()) - top_pieces.begin();
    const bool apart = r.stopped_singular && crack_top >= top_y - p.horizon;
    WARN(name << ": " << r.solves << " solves, " << r.broken << " bonds removed, " << runs << " crack(s) at the top edge, its top row in " << cut
              << " piece(s), the crack's top " << (top_y - crack_top) * 1e3 << " mm below the edge, singular at the end " << r.stopped_singular
              << ", " << r.assembly_seconds << " s assembly + " << r.factor_seconds << " s factorisation");
    CHECK((runs >= 1 || cut >= 2 || apart));
  }
}
