#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>
#include <fmt/core.h>

#include "commands.hpp"
import peridot.problem;
import peridot.render;

using namespace peridot;

// Re-renders saved VTU output (a .pvd series or one .vtu) to PNG files next to it.
int render_command(const RenderArgs& args) {
  std::vector<std::pair<double, std::filesystem::path>> files;
  try {
    const std::filesystem::path in(args.input);
    if (in.extension() == ".pvd") files = read_pvd(in);
    else if (in.extension() == ".vtu") files = {{NAN, in}};
    else throw std::runtime_error(fmt::format("{}: expected a .pvd series or a .vtu file", args.input));
    if (args.last_only) files = {files.back()};
  } catch (const std::exception& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return exit_input_error;
  }
  try {
    for (const auto& [time, file] : files) {
      const VtuData d = read_vtu(file);
      const auto* values = d.find(args.field);
      if (!values) throw std::runtime_error(fmt::format("{}: no point array named '{}'", file.string(), args.field));
      const std::size_t n = d.x[0].size();
      std::vector<double> v(n), u[3];
      for (std::size_t i = 0; i < n; ++i) {
        double m = 0;
        for (int k = 0; k < values->components; ++k) m += values->values[i * values->components + k] * values->values[i * values->components + k];
        v[i] = values->components == 1 ? values->values[i] : std::sqrt(m);
      }
      // read_vtu guarantees components x points values; a displacement must have 3 of them.
      if (const auto* disp = d.find("displacement"); disp && disp->components == 3)
        for (int k = 0; k < 3; ++k) {
          u[k].resize(n);
          for (std::size_t i = 0; i < n; ++i) u[k][i] = disp->values[3 * i + k];
        }
      bool flat = true;
      for (double z : d.x[2]) flat = flat && z == 0.0;
      RenderField rf;
      rf.dim = flat ? 2 : 3;
      rf.x = {d.x[0], d.x[1], d.x[2]};
      rf.u = {u[0], u[1], u[2]};
      rf.values = v;
      rf.field_name = args.field;
      rf.time = std::isnan(time) ? 0.0 : time;
      const auto stem = file.stem().string();
      const auto us = stem.rfind('_');
      rf.step = us == std::string::npos ? 0 : std::size_t(std::strtoull(stem.c_str() + us + 1, nullptr, 10));
      RenderOptions ro;
      ro.width = args.width;
      ro.deformed = args.deformed;
      ro.magnification = args.magnification;
      auto out = file;
      out.replace_extension(".png");
      render_png(out, rf, ro);
      fmt::print("{}\n", out.string());
    }
  } catch (const std::exception& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return exit_runtime_error;
  }
  return exit_ok;
}
