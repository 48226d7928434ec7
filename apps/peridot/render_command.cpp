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
      const SavedField saved = read_saved_field(file, args.field, time);
      RenderOptions ro;
      ro.width = args.width;
      ro.deformed = args.deformed;
      ro.magnification = args.magnification;
      auto out = file;
      out.replace_extension(".png");
      render_png(out, saved.field, ro);
      fmt::print("{}\n", out.string());
    }
  } catch (const std::exception& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return exit_runtime_error;
  }
  return exit_ok;
}
