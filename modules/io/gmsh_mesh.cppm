module;
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <exception>
#include <filesystem>
#include <map>
#include <mutex>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <vector>
#include <fmt/core.h>
#include <gmsh.h>
export module peridot.io:gmsh_mesh;
import peridot.discretization;

export namespace peridot {

// Reads a 2D mesh of 3-node triangles: a .msh file (format v2 or v4) or a .geo file meshed
// on the fly with characteristic length `mesh_size` [m] (0: the sizes in the .geo file;
// ignored for a .msh).
//
// Nodes are those used by triangles, in increasing Gmsh node tag, numbered 0..n-1; z must be 0.
// Triangles come out counter-clockwise: a surface whose triangles all run clockwise (meshed
// with normal -z) is flipped; a surface with both orientations is an error. Physical groups of
// dimension 0-2 become `groups` (the nodes of the group's elements); an unnamed group is called
// "group<tag>" in 2D and "<dim>d_group<tag>" in 0D/1D, and groups sharing a name are merged.
// Every error is a std::invalid_argument naming the file. Gmsh is a process-wide singleton:
// this initialises and finalises it per call under a lock, so do not use the Gmsh API
// elsewhere in the process at the same time.
TriangleMesh read_gmsh_mesh(const std::filesystem::path& file, double mesh_size = 0);

}  // namespace peridot

namespace peridot {
namespace {

constexpr int kLinearTriangle = 2;  // Gmsh element type

[[noreturn]] void fail(const std::filesystem::path& file, const std::string& why) {
  throw std::invalid_argument(fmt::format("{}: {}", file.string(), why));
}

// How Gmsh 4.8 fails: initialize() sets General.AbortOnError = 2, so the first error throws a
// std::string (not a std::exception). Thrown out of the .geo parser (which also reads any file
// that does not start with $MeshFormat), it leaves the unread rest of that file in the lexer
// buffer, which even finalize() keeps, so every later file fails with "syntax error". So we
// set AbortOnError = 0, let the parser run to the end of the file, and collect the errors from
// the logger instead; a missing file is not an error at all. A fresh session per call also
// restores every option to its default.
struct GmshSession {
  GmshSession() {
    gmsh::initialize(0, nullptr, false);
    gmsh::option::setNumber("General.Terminal", 0);
    gmsh::option::setNumber("General.Verbosity", 1);  // errors only, and they reach the logger
    gmsh::option::setNumber("General.AbortOnError", 0);
    gmsh::logger::start();
  }
  ~GmshSession() {
    try {
      gmsh::logger::stop();
      gmsh::finalize();
    } catch (...) {
    }
  }
  GmshSession(const GmshSession&) = delete;
  GmshSession& operator=(const GmshSession&) = delete;
};

void throw_logged_error() {
  std::vector<std::string> log;
  gmsh::logger::get(log);
  const std::string error = "Error: ";
  for (const auto& line : log)
    if (line.starts_with(error)) throw line.substr(error.size());
}

TriangleMesh extract(const std::filesystem::path& file) {
  std::vector<int> types;
  gmsh::model::mesh::getElementTypes(types);
  std::string kinds;
  bool triangles = false, others = false;
  for (int type : types) {
    std::string name;
    int dim, order, nodes, primary;
    std::vector<double> local;
    gmsh::model::mesh::getElementProperties(type, name, dim, order, nodes, local, primary);
    if (dim < 2) continue;  // points and lines only carry boundary groups
    kinds += (kinds.empty() ? "" : ", ") + name;
    (type == kLinearTriangle ? triangles : others) = true;
  }
  if (others) fail(file, fmt::format("mixed element types: {}; only linear 3-node triangles are supported", kinds));
  if (!triangles) fail(file, "the mesh contains no triangles");

  std::vector<std::size_t> tags;
  std::vector<double> coord, param;
  gmsh::model::mesh::getNodes(tags, coord, param);
  std::unordered_map<std::size_t, std::size_t> where;  // node tag -> position in coord
  for (std::size_t i = 0; i < tags.size(); ++i) where.emplace(tags[i], i);

  // Triangles per surface, since orientation is a property of the surface's normal.
  gmsh::vectorpair surfaces;
  gmsh::model::getEntities(surfaces, 2);
  std::vector<std::vector<std::size_t>> elements(surfaces.size()), connectivity(surfaces.size());
  std::vector<std::size_t> used;
  for (std::size_t s = 0; s < surfaces.size(); ++s) {
    gmsh::model::mesh::getElementsByType(kLinearTriangle, elements[s], connectivity[s], surfaces[s].second);
    used.insert(used.end(), connectivity[s].begin(), connectivity[s].end());
  }
  std::ranges::sort(used);
  used.erase(std::unique(used.begin(), used.end()), used.end());
  if (used.size() > std::size_t(INT32_MAX)) fail(file, "more than 2^31 nodes");

  TriangleMesh mesh;
  std::unordered_map<std::size_t, std::int32_t> index;  // node tag -> mesh node
  double lo[2] = {HUGE_VAL, HUGE_VAL}, hi[2] = {-HUGE_VAL, -HUGE_VAL};
  for (std::size_t tag : used) {
    const auto it = where.find(tag);
    if (it == where.end()) fail(file, fmt::format("a triangle refers to node {}, which does not exist", tag));
    const double* x = &coord[3 * it->second];
    index.emplace(tag, std::int32_t(mesh.nodes.size()));
    mesh.nodes.push_back({x[0], x[1], x[2]});
    for (int k = 0; k < 2; ++k) lo[k] = std::min(lo[k], x[k]), hi[k] = std::max(hi[k], x[k]);
  }
  // Relative to the mesh size, so that round-off in a written file does not count.
  const double flat = 1e-10 * std::max({hi[0] - lo[0], hi[1] - lo[1], 1e-300});
  for (std::size_t i = 0; i < mesh.nodes.size(); ++i) {
    if (std::abs(mesh.nodes[i][2]) > flat)
      fail(file, fmt::format("the mesh is not planar in z = 0: node {} has z = {:g} m", used[i], mesh.nodes[i][2]));
    mesh.nodes[i][2] = 0;
  }

  for (std::size_t s = 0; s < surfaces.size(); ++s) {
    const std::size_t first = mesh.triangles.size(), count = elements[s].size();
    std::size_t ccw = 0, cw = 0;
    for (std::size_t e = 0; e < count; ++e) {
      const std::size_t* n = &connectivity[s][3 * e];
      mesh.triangles.push_back({index.at(n[0]), index.at(n[1]), index.at(n[2])});
      const double a = mesh.area(mesh.triangles.size() - 1);
      ccw += a > 0, cw += a < 0;
    }
    if (ccw > 0 && cw > 0) {
      // The minority orientation is the inverted one.
      for (std::size_t e = 0; e < count; ++e)
        if (ccw >= cw ? mesh.area(first + e) < 0 : mesh.area(first + e) > 0)
          fail(file, fmt::format("inverted element {}: its nodes run opposite to the other triangles of surface {}", elements[s][e],
                                 surfaces[s].second));
    }
    if (cw > 0 && ccw == 0)
      for (std::size_t t = first; t < mesh.triangles.size(); ++t) std::swap(mesh.triangles[t][1], mesh.triangles[t][2]);
  }
  try {
    validate(mesh);
  } catch (const std::invalid_argument& e) {
    fail(file, e.what());
  }

  gmsh::vectorpair groups;
  gmsh::model::getPhysicalGroups(groups);
  for (const auto& [dim, tag] : groups) {
    if (dim > 2) continue;
    std::string name;
    gmsh::model::getPhysicalName(dim, tag, name);
    if (name.empty()) name = dim == 2 ? fmt::format("group{}", tag) : fmt::format("{}d_group{}", dim, tag);
    // Not getNodes(dim, entity, includeBoundary): after reading a v2 file the nodes on
    // curves outside any physical group belong to no entity, and a surface would miss them.
    gmsh::model::mesh::getNodesForPhysicalGroup(dim, tag, tags, coord);
    auto& nodes = mesh.groups[name];
    for (std::size_t t : tags)
      if (const auto it = index.find(t); it != index.end()) nodes.push_back(it->second);
    std::ranges::sort(nodes);
    nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
  }
  return mesh;
}

}  // namespace

TriangleMesh read_gmsh_mesh(const std::filesystem::path& file, double mesh_size) {
  const bool geo = file.extension() == ".geo";
  if (!(mesh_size >= 0) || !std::isfinite(mesh_size))
    fail(file, fmt::format("mesh size must be a finite number >= 0 (0: the sizes in the file), not {:g}", mesh_size));
  std::error_code ec;
  // Gmsh opens a missing file without a word and returns an empty model.
  if (!std::filesystem::is_regular_file(file, ec)) fail(file, "no such file");

  static std::mutex gmsh_lock;
  const std::lock_guard lock(gmsh_lock);
  try {
    GmshSession session;
    gmsh::open(file.string());
    throw_logged_error();
    if (geo) {
      if (mesh_size > 0) {
        // Min = max clamps every size Gmsh computes (from points, curvature or fields of the
        // .geo) to mesh_size, so no other size option matters. Set after open(), since the
        // .geo may set these options itself.
        gmsh::option::setNumber("Mesh.MeshSizeMin", mesh_size);
        gmsh::option::setNumber("Mesh.MeshSizeMax", mesh_size);
        gmsh::model::mesh::clear();  // a "Mesh 2;" in the .geo would otherwise stand
      }
      gmsh::model::mesh::generate(2);
      throw_logged_error();
    }
    return extract(file);
  } catch (const std::invalid_argument&) {
    throw;
  } catch (const std::string& e) {
    fail(file, "Gmsh cannot read it: " + e);
  } catch (const std::exception& e) {
    fail(file, std::string("Gmsh cannot read it: ") + e.what());
  } catch (...) {
    fail(file, "Gmsh cannot read it");
  }
}

}  // namespace peridot
