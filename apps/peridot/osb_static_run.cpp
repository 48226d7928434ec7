// peridot run on a static OSB deck (seed 004): one linear solve, or a sequentially linear
// fracture run, then the VTU and PNG of the final state.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <span>
#include <string>
#include <vector>
#include <fmt/core.h>

#include "osb_static_run.hpp"
import peridot.problem;
import peridot.analysis;
import peridot.render;

using namespace peridot;

namespace {

const char* method_name(const OsbStaticProblem& prob) { return prob.corrected ? "fictitious Taylor nodes" : "uncorrected, conditions on the outermost nodes"; }

void write_outputs(const std::filesystem::path& dir, const Problem& p, const OsbStaticSetup& s, const OsbStaticResult& r, bool quiet) {
  const auto& pc = s.body.points;
  const std::size_t n = pc.size();
  std::vector<double> role(n), phi, ref_u(n), ref_v(n), real(n);
  for (std::size_t i = 0; i < n; ++i) {
    role[i] = double(static_cast<int>(pc.role[i]));
    const auto u0 = osb_reference(p, pc.position(i));
    ref_u[i] = u0[0], ref_v[i] = u0[1];
  }
  damage(s.body, phi);
  // Seed 004 Sec. 4.3: eq. (51) on the grid, from the bond forces of the solve (fictitious
  // points carry their extrapolated displacement and dilatation).
  const auto tau = lattice_stress(lattice_grid(pc), s.body, r.pair_force);
  std::vector<double> von(n);
  for (std::size_t i = 0; i < n; ++i)
    von[i] = std::sqrt(tau.xx[i] * tau.xx[i] - tau.xx[i] * tau.yy[i] + tau.yy[i] * tau.yy[i] + 3 * tau.xy[i] * tau.xy[i]);
  if (p.output.vtu_every) {
    std::vector<NamedField> fields{
        {"displacement", 3, {r.u[0], r.u[1], {}}},
        {"dilatation", 1, {r.theta, {}, {}}},
        {"damage", 1, {phi, {}, {}}},
        {"stress_xx", 1, {tau.xx, {}, {}}},
        {"stress_yy", 1, {tau.yy, {}, {}}},
        {"stress_xy", 1, {tau.xy, {}, {}}},
        {"role", 1, {role, {}, {}}},
    };
    if (p.statics.osb.affine_reference) fields.push_back({"reference_displacement", 3, {ref_u, ref_v, {}}});
    write_vtu(dir / (p.name + ".vtu"), pc, fields);
    if (!quiet) fmt::print("  output: {}\n", (dir / (p.name + ".vtu")).string());
  }
  if (p.output.png_every) {
    // Real points only: the fictitious layer is not part of the body.
    std::vector<double> x[2], u[2], values;
    const auto& f = p.output.png_field;
    for (std::size_t i = 0; i < n; ++i) {
      if (pc.role[i] != Role::interior) continue;
      for (int k = 0; k < 2; ++k) x[k].push_back(pc.x[k][i]), u[k].push_back(r.u[k][i]);
      values.push_back(f == "damage"      ? phi[i]
                       : f == "stress_xx" ? tau.xx[i]
                       : f == "stress_yy" ? tau.yy[i]
                       : f == "stress_xy" ? tau.xy[i]
                       : f == "von_mises" ? von[i]
                                          : std::hypot(r.u[0][i], r.u[1][i]));
    }
    RenderField rf;
    rf.dim = 2;
    rf.x = {x[0], x[1], {}};
    rf.u = {u[0], u[1], {}};
    rf.values = values;
    rf.field_name = f == "damage" ? "damage" : f == "displacement" ? "|displacement| [m]" : f + " [Pa]";
    rf.spacing = pc.spacing;
    RenderOptions ro;
    ro.width = p.output.png_width;
    ro.deformed = p.output.png_deformed;
    ro.magnification = p.output.png_magnification;
    ro.title = fmt::format("{}  {}  ({})", p.name, rf.field_name, method_name(s.problem));
    const auto file = dir / (p.name + ".png");
    render_png(file, rf, ro);
    if (!quiet) fmt::print("  output: {}\n", file.string());
  }
}

}  // namespace

int simulate_osb_static(const Problem& p, OsbStaticSetup& s, const RunArgs& args) {
  const auto& pc = s.body.points;
  std::size_t real = 0;
  for (auto role : pc.role) real += role == Role::interior;
  if (!args.quiet) {
    fmt::print("peridot: {} (static OSB, {}{}, {} real points, {} fictitious, h = {:.4g} m, delta = {:.4g} m = {:g} h)\n", p.name,
               method_name(s.problem), s.problem.corrected ? fmt::format(" of order {}", s.problem.taylor_order) : std::string(), real,
               pc.size() - real, p.lattice.spacing, p.horizon, p.horizon / p.lattice.spacing);
    if (s.options.critical_stretch > 0)
      fmt::print("  fracture: s_c = {:.4e}, {} most stretched bonds removed per re-solve\n", s.options.critical_stretch, s.options.bonds_per_solve);
  }
  auto opt = s.options;
  if (!args.quiet && opt.critical_stretch > 0)
    opt.progress = [](std::size_t solves, std::size_t broken) {
      if (solves % 25 == 0) fmt::print(stderr, "\r  re-solve {}  bonds removed {}", solves, broken);
    };
  const auto r = solve_osb_static(s.body, s.model, s.problem, opt);
  if (!args.quiet) {
    if (opt.critical_stretch > 0) fmt::print(stderr, "\n");
    fmt::print("  unknowns {} (u, v, theta) + {} condition rows  nonzeros {}  assembly {:.3f} s  factorisation and solve {:.3f} s  residual {:.2e}\n",
               3 * r.real_points, r.constraints, r.nonzeros, r.assembly_seconds, r.factor_seconds, r.residual);
    if (!r.multipliers.empty()) {
      double lam = 0;
      for (double l : r.multipliers) lam = std::max(lam, std::abs(l));
      fmt::print("  largest |Lagrange multiplier| {:.3e} N/m^3\n", lam);
    }
    if (opt.critical_stretch > 0)
      fmt::print("  fracture: {} solves, {} bonds removed{}\n", r.solves, r.broken,
                 r.stopped_singular ? ", stopped: equilibrium is no longer possible (singular system)" : "");
    if (p.statics.osb.affine_reference) {
      const auto e = osb_errors(p, s, r);
      fmt::print("  relative error (66) over the real points: u {:.4f} .. {:.4f} %, v {:.4f} .. {:.4f} %\n", e.rel_u_min, e.rel_u_max, e.rel_v_min, e.rel_v_max);
      fmt::print("  error (64), |u - u_ref| / max |u_ref|: u {:.4f} %, v {:.4f} %;  max |u| {:.6e} m, max |v| {:.6e} m\n", e.abs_u_max, e.abs_v_max,
                 e.max_u, e.max_v);
    }
  }
  if (p.output.vtu_every || p.output.png_every) {
    const auto dir = std::filesystem::path(args.out_dir ? *args.out_dir : p.output.directory.string());
    std::filesystem::create_directories(dir);
    write_outputs(dir, p, s, r, args.quiet);
  }
  return exit_ok;
}
