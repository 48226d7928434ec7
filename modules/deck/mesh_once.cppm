export module peridot.deck:mesh_once;
import peridot.std;
import peridot.io;
import peridot.parallel;

export namespace peridot {

// A Gmsh mesh read, or a .geo meshed, once per run. On N MPI ranks rank 0 alone runs Gmsh and
// sends the mesh (nodes, elements and groups: about 33 bytes per node in 2D) to the others:
// Gmsh's working memory while it meshes (about 2 kB per node for a 2D .geo) and its time are
// then paid once per run, not once per rank. The mesh is the one rank 0 read, bit for bit. A
// failure on rank 0 (a bad file, a mesh that would not fit) fails every rank as an input error
// (std::invalid_argument), its message printed by rank 0. On one rank: read_gmsh_mesh.
TriangleMesh read_gmsh_mesh_once(const std::filesystem::path& file, double mesh_size, const MeshEstimateCheck& before_meshing);
TetMesh read_gmsh_tet_mesh_once(const std::filesystem::path& file, double mesh_size, const MeshEstimateCheck& before_meshing);

}  // namespace peridot

namespace peridot {

namespace {

struct Bytes {
  std::vector<std::uint8_t> data;
  std::size_t at = 0;

  template <class T>
  void put(std::span<const T> v) {
    put_count(v.size());
    const auto* p = reinterpret_cast<const std::uint8_t*>(v.data());
    data.insert(data.end(), p, p + v.size_bytes());
  }
  void put_count(std::uint64_t n) {
    const auto* p = reinterpret_cast<const std::uint8_t*>(&n);
    data.insert(data.end(), p, p + sizeof n);
  }
  std::uint64_t count() {
    std::uint64_t n = 0;
    take(&n, sizeof n);
    return n;
  }
  template <class T>
  void get(std::vector<T>& v) {
    v.resize(count());
    take(v.data(), v.size() * sizeof(T));
  }
  void take(void* to, std::size_t n) {
    if (n > data.size() - at) throw std::logic_error("a shared mesh ended early");
    std::memcpy(to, data.data() + at, n);
    at += n;
  }
};

template <class Mesh, class Elements, class Read>
Mesh read_once(Elements elements, Read read) {
  if (parallel::ranks() <= 1) return read();
  Mesh mesh;
  // Gmsh has no collectives, so every rank learns together whether rank 0's read failed.
  parallel::together("reading the mesh", [&] {
    if (parallel::rank() == 0) mesh = read();
  });
  Bytes b;
  if (parallel::rank() == 0) {
    b.put(std::span<const Vec3>(mesh.nodes));
    const auto& els = mesh.*elements;
    b.put(std::span(els));
    b.put_count(mesh.groups.size());
    for (const auto& [name, nodes] : mesh.groups) {
      b.put(std::span(name.data(), name.size()));
      b.put(std::span(nodes));
    }
  }
  parallel::broadcast_from_root(b.data);
  if (parallel::rank() != 0) {
    b.get(mesh.nodes);
    b.get(mesh.*elements);
    for (std::uint64_t g = b.count(); g > 0; --g) {
      std::vector<char> name;
      b.get(name);
      b.get(mesh.groups[std::string(name.begin(), name.end())]);
    }
  }
  return mesh;
}

}  // namespace

TriangleMesh read_gmsh_mesh_once(const std::filesystem::path& file, double mesh_size, const MeshEstimateCheck& before_meshing) {
  return read_once<TriangleMesh>(&TriangleMesh::triangles, [&] { return read_gmsh_mesh(file, mesh_size, before_meshing); });
}

TetMesh read_gmsh_tet_mesh_once(const std::filesystem::path& file, double mesh_size, const MeshEstimateCheck& before_meshing) {
  return read_once<TetMesh>(&TetMesh::tetrahedra, [&] { return read_gmsh_tet_mesh(file, mesh_size, before_meshing); });
}

}  // namespace peridot
