// Writes the generated seeds of tests/fuzz (small VTU, PVTU, PVD, checkpoint and .msh files)
// into the folder given as the only argument; tools/fuzz.sh does not need it, the committed
// copies under corpus/ and files/ came from it:
//   cmake --build build/asan --target fuzz_seeds && build/asan/tests/fuzz/fuzz_seeds /tmp/seeds
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>
#include <gmsh.h>
import peridot.io;

using namespace peridot;
namespace fs = std::filesystem;

namespace {

void vtu_seeds(const fs::path& out) {
  const auto pc = lattice(rectangle({0, 0, 0}, {0.003, 0.002, 0}), {.spacing = 1e-3});
  std::vector<double> damage(pc.size()), ux(pc.size()), uy(pc.size());
  for (std::size_t i = 0; i < pc.size(); ++i) damage[i] = 0.1 * double(i), ux[i] = 1e-6 * double(i), uy[i] = -ux[i];
  const NamedField fields[] = {{"damage", 1, {damage, {}, {}}}, {"displacement", 3, {ux, uy, {}}}};
  write_vtu(out / "cloud.vtu", pc, fields);
  const auto mesh = structured_triangles({0, 0, 0}, {2, 1, 0}, 2, 1, false);
  const auto mp = mesh_points(mesh);
  std::vector<double> ones(mp.size(), 1.0);
  const NamedField mesh_fields[] = {{"damage", 1, {ones, {}, {}}}};
  write_vtu(out / "mesh.vtu", mp, mesh_fields);
  // The fuzz target reads a .pvtu's pieces next to it, where its own input is input.vtu.
  const std::string pieces[] = {"input.vtu", "input.vtu"};
  write_pvtu(out / "pieces.pvtu", pieces, fields);
  PvdSeries series(out, "series");
  series.write(0.0, 0, pc, fields);
  series.write(2.5e-6, 10, pc, fields);
  fs::rename(series.pvd(), out / "series.pvd");
  fs::remove(out / "series_0000000.vtu");
  fs::remove(out / "series_0000010.vtu");
}

void checkpoint_seeds(const fs::path& out) {
  Checkpoint c;
  c.deck_name = "seed";
  c.deck_hash = 0x0123456789abcdefull;
  c.dim = 2;
  c.points = 4;
  c.bonds = 12;
  c.dt = 1e-7;
  c.scheme = "central_difference";
  c.step = 3;
  c.time = 3 * c.dt;
  for (int k = 0; k < 3; ++k)
    for (std::size_t i = 0; i < c.points; ++i) {
      c.u[k].push_back(1e-6 * double(i + k));
      c.v[k].push_back(-1e-3 * double(i));
      c.f[k].push_back(1e3 * double(k));
    }
  for (std::size_t b = 0; b < c.bonds; ++b) c.bond_state.push_back(std::uint8_t(b % 2));
  c.external_work = 0.5;
  c.broken = 6;
  write_checkpoint(out / "small.h5", c);
  c = Checkpoint{.deck_name = "empty", .dim = 3, .dt = 1e-8, .scheme = "velocity_verlet"};
  write_checkpoint(out / "empty.h5", c);
}

// The unit square with named sides, meshed coarsely by Gmsh and written as .msh v2 and v4.
void msh_seeds(const fs::path& out) {
  const fs::path geo = out / "square.geo";
  FILE* f = std::fopen(geo.c_str(), "w");
  std::fputs("Point(1) = {0, 0, 0, 0.5}; Point(2) = {1, 0, 0, 0.5}; Point(3) = {1, 1, 0, 0.5}; Point(4) = {0, 1, 0, 0.5};\n"
             "Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};\n"
             "Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};\n"
             "Physical Curve(\"bottom\") = {1}; Physical Curve(\"top\") = {3}; Physical Curve(\"left\") = {4};\n"
             "Physical Point(7) = {2}; Physical Surface(\"body\") = {1};\n",
             f);
  std::fclose(f);
  gmsh::initialize(0, nullptr, false);
  gmsh::option::setNumber("General.Terminal", 0);
  gmsh::open(geo.string());
  gmsh::model::mesh::generate(2);
  for (const auto& [name, version, binary] : {std::tuple{"square_v2.msh", 2.2, 0}, {"square_v4.msh", 4.1, 0}, {"square_v4_binary.msh", 4.1, 1}}) {
    gmsh::option::setNumber("Mesh.MshFileVersion", version);
    gmsh::option::setNumber("Mesh.Binary", binary);
    gmsh::write((out / name).string());
  }
  gmsh::finalize();
  fs::remove(geo);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: fuzz_seeds OUT_DIR\n");
    return 2;
  }
  const fs::path out = argv[1];
  fs::create_directories(out);
  vtu_seeds(out);
  checkpoint_seeds(out);
  msh_seeds(out);
  return 0;
}
