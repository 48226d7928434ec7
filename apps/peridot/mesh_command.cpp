// peridot mesh: a .geo meshed once into a .msh that decks then read, instead of meshing it on
// every run (and, under mpirun, Gmsh's working memory on rank 0).
#include <filesystem>
#include <stdexcept>
#include <string>
#include <fmt/core.h>

#include "commands.hpp"
#include "guarded.hpp"
import peridot.run;

int mesh_command(const MeshArgs& args) {
  using namespace peridot;
  namespace fs = std::filesystem;
  return guarded([&] {
    const fs::path geo = args.geo;
    const fs::path out = args.out ? fs::path(*args.out) : fs::path(geo.stem().string() + ".msh");
    if (geo.extension() != ".geo") throw std::invalid_argument(fmt::format("{}: expected a Gmsh .geo file to mesh", geo.string()));
    if (out.extension() != ".msh") throw std::invalid_argument(fmt::format("--out {}: the mesh is written as a .msh file", out.string()));
    const fs::path dir = out.parent_path().empty() ? fs::path(".") : out.parent_path();
    std::error_code ec;
    if (!fs::is_directory(dir, ec)) throw std::invalid_argument(fmt::format("--out {}: no directory {}", out.string(), dir.string()));
    if (fs::equivalent(geo, out, ec)) throw std::invalid_argument(fmt::format("--out {}: that is the input file", out.string()));
    // Input errors are std::invalid_argument (exit 2); a failed write is a runtime error (exit 1).
    const auto nodes = write_gmsh_mesh(geo, args.size, args.dimension, out, [&](double n, double h) { require_meshing_fits(n, args.dimension, h); });
    fmt::print("{}: {} nodes ({}D{}); a deck reads it as discretization.mesh: {{file: {}}}\n", out.string(), nodes, args.dimension,
               args.size > 0 ? fmt::format(", element size {:g} m", args.size) : "", out.filename().string());
    return int(exit_ok);
  });
}
