module;
#include <malloc.h>
export module peridot.deck:mesh_once;
import peridot.std;
import peridot.parallel;
import :spec;
import :mesh_part;
import :structured_part;

export namespace peridot {

// Makes the deck's mesh once per run: `make` reads ms.file (a Gmsh .msh, or a .geo meshed at
// ms.size) or builds the structured one, into ms.mesh (2D) or ms.tets (3D). On N MPI ranks rank
// 0 alone runs it and keeps the mesh until every rank has its share (MeshSpec::release_whole):
// Gmsh's working memory while it meshes (1.8 kB per node in 2D, 2.8 kB in 3D) and its time are
// paid once, not on every rank, and the set-up sends each rank only its share
// (setup_rcb_local). The other ranks get ms.summary: the mesh's bounds,
// mean edge and group names, bit for bit rank 0's. A failure on rank 0 (a bad file, a mesh that
// would not fit) fails every rank as an input error (std::invalid_argument), its message
// printed by rank 0.
void make_mesh_once(MeshSpec& ms, const std::function<void()>& make);

// On N MPI ranks, reads the .msh ms.file in parts (read_mesh_part): every rank keeps its part in
// ms.part, holding the nodes within `depth` bond reaches of its own (3: the deepest ghosts any
// deck needs), and ms.summary. False (on every rank) on one rank, or where the file cannot be
// read in parts; the caller then reads it with make_mesh_once.
bool read_mesh_in_parts(MeshSpec& ms, int dim, double horizon);

// On N MPI ranks, makes the structured mesh of ms in parts (structured_mesh_part), as
// read_mesh_in_parts reads a file. False (on every rank) on one rank or where no grid of ranks
// fits the nodes; the caller then makes it with make_mesh_once.
bool make_structured_in_parts(MeshSpec& ms, int dim, double horizon);

}  // namespace peridot

namespace peridot {

namespace {

constexpr int kPartDepth = 3;  // bonds deep: the deepest ghosts any deck's set-up needs

bool keep_part(MeshSpec& ms, std::optional<MeshSpec::Part> part, MeshSpec::Summary s) {
  if (!part) return false;
  ms.summary = std::make_shared<const MeshSpec::Summary>(std::move(s));
  ms.part = std::make_shared<const MeshSpec::Part>(std::move(*part));
  malloc_trim(0);  // the readings' arrays, handed back before the set-up allocates
  return true;
}

}  // namespace

bool read_mesh_in_parts(MeshSpec& ms, int dim, double horizon) {
  if (parallel::ranks() <= 1) return false;
  MeshSpec::Summary s;
  auto part = read_mesh_part(ms.file, dim, horizon, kPartDepth, s);
  return keep_part(ms, std::move(part), std::move(s));
}

bool make_structured_in_parts(MeshSpec& ms, int dim, double horizon) {
  if (parallel::ranks() <= 1) return false;
  MeshSpec::Summary s;
  auto part = structured_mesh_part(ms, dim, horizon, kPartDepth, s);
  return keep_part(ms, std::move(part), std::move(s));
}

void make_mesh_once(MeshSpec& ms, const std::function<void()>& make) {
  if (parallel::ranks() <= 1) return make();
  // make holds no collective, so every rank learns together whether it failed on rank 0.
  parallel::together("reading the mesh", [&] {
    if (parallel::rank() == 0) make();
  });
  parallel::Bytes b;
  if (parallel::rank() == 0) {
    const Aabb box = ms.bounds();
    b.put(std::vector<double>{box.lo[0], box.lo[1], box.lo[2], box.hi[0], box.hi[1], box.hi[2], ms.mean_edge()});
    b.put_count(ms.groups().size());
    for (const auto& [name, nodes] : ms.groups()) b.put(std::span(name.data(), name.size()));
  }
  parallel::broadcast_from_root(b.data);
  if (parallel::rank() == 0) return;
  MeshSpec::Summary s;
  const auto v = b.get<double>();
  s.bounds = {{v[0], v[1], v[2]}, {v[3], v[4], v[5]}};
  s.mean_edge = v[6];
  for (std::uint64_t g = b.count(); g > 0; --g) {
    const auto name = b.get<char>();
    s.groups[std::string(name.begin(), name.end())];
  }
  ms.summary = std::make_shared<const MeshSpec::Summary>(std::move(s));
}

}  // namespace peridot
