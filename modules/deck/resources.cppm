module;
#include <stdio.h>  // stderr
#include <unistd.h>

export module peridot.deck:resources;
import peridot.std;
import peridot.io;

export namespace peridot {

// Resident bytes a run needs per point (positions, volume, role, u, v, f, flags) and per
// directed bond (partner, xi, length, weight, mask: 45; a lean PMB list keeps partner, float
// weight and mask: 9; a lattice stencil about 1.3). A static solve also holds about 8 matrix entries per bond as triplets
// and in compressed form.
inline constexpr double bytes_per_point = 160;
inline constexpr double bytes_per_bond_explicit = 48;
inline constexpr double bytes_per_bond_lean = 10;
inline constexpr double bytes_per_bond_stencil = 2;  // a state byte per (point, offset), padding and maps
inline constexpr double bytes_per_bond_static = 48 + 8 * (24 + 16);
// Dynamic LPS set-up: the list, the exterior band's bonds until they are dropped, and the GMLS
// solves. Measured per bond of the estimate below (peak RSS of `peridot check`, ci build):
// 2D glass plate at h = 0.2 mm 0.75 GB and h = 0.125 mm 1.66 GB, about 93 B; 3D
// Kalthoff-Winkler at dx = 1 mm 3.42 GB, 57 B. The 2D figure with a margin.
inline constexpr double bytes_per_bond_lps_dynamic = 112;
// Gmsh's working memory while it meshes a .geo, per node made: the slope of `peridot mesh`'s
// peak RSS between two sizes (ci build). 2D, fe/hole_precrack.geo, 5.8e4 to 2.3e5 nodes: 0.18
// to 0.49 GB, 1.8 kB per node; 3D, fe/circular_hole_3d.geo, 3.6e4 to 1.5e5 nodes: 0.23 to
// 0.55 GB, 2.8 kB per node.
inline constexpr double bytes_per_node_meshing_2d = 2000, bytes_per_node_meshing_3d = 3000;
// A run estimated above this fraction of the available memory gets a warning.
inline constexpr double memory_warning_fraction = 0.5;

// Memory this process may use: MemAvailable from /proc/meminfo, else the physical memory,
// capped by limit_memory_bytes.
double available_memory_bytes();

// Caps what available_memory_bytes reports (bytes > 0; 0 removes the cap): for fuzzing and
// tests, which must refuse large bodies long before the machine's memory would.
void limit_memory_bytes(double bytes);

// Before the lattice is allocated: refuses (DeckError) a bounding box, grown by `margin` [m] on
// every side, with more lattice sites than fit in memory (or than 2^31 points can index).
void require_lattice_fits(const Aabb& box, double spacing, int dim, double margin);

// Before Gmsh meshes: refuses (std::invalid_argument, naming the estimate) about `nodes` nodes
// of element size h [m] in `dim` = 2 or 3 that Gmsh could not mesh in the available memory or
// 2^31 nodes could not index.
void require_meshing_fits(double nodes, int dim, double h);

// Before the bonds are allocated: refuses a run whose points x neighbours x bytes per bond
// exceed the available memory, with the estimate and the machine's memory in the message;
// warns on stderr above memory_warning_fraction of it.
void require_bonds_fit(std::size_t points, int dim, double horizon, double spacing, double bytes_per_bond);

}  // namespace peridot

namespace peridot {

namespace {

std::string gib(double bytes) { return fmt::format("{:.3g} GiB", bytes / (1024.0 * 1024.0 * 1024.0)); }

}  // namespace

namespace {

double memory_cap = 0;  // 0: none

double machine_memory_bytes() {
  std::ifstream in("/proc/meminfo");
  std::string key;
  double kib = 0;
  std::string unit;
  while (in >> key >> kib >> unit)
    if (key == "MemAvailable:") return kib * 1024.0;
  const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
  return pages > 0 && page > 0 ? double(pages) * double(page) : 8.0 * 1024 * 1024 * 1024;
}

}  // namespace

double available_memory_bytes() {
  const double have = machine_memory_bytes();
  return memory_cap > 0 ? std::min(have, memory_cap) : have;
}

void limit_memory_bytes(double bytes) { memory_cap = bytes > 0 ? bytes : 0; }

void require_lattice_fits(const Aabb& box, double spacing, int dim, double margin) {
  double sites = 1;
  for (int k = 0; k < dim; ++k) sites *= std::ceil((box.hi[k] - box.lo[k] + 2 * margin) / spacing) + 1;
  const double limit = 2147483647.0;
  const double need = sites * bytes_per_point, have = available_memory_bytes();
  if (!std::isfinite(sites) || sites > limit || need > have)
    throw DeckError(fmt::format("discretization.spacing = {:g} m: the body's bounding box holds about {:.3g} lattice sites, needing "
                                "about {} for points alone; this machine has {} available (and at most 2^31 points are indexed). "
                                "Use a larger spacing or a smaller body",
                                spacing, sites, gib(need), gib(have)));
}

void require_meshing_fits(double nodes, int dim, double h) {
  const double need = nodes * (dim == 3 ? bytes_per_node_meshing_3d : bytes_per_node_meshing_2d), have = available_memory_bytes();
  if (nodes > double(std::numeric_limits<std::int32_t>::max()) || need > have)
    throw std::invalid_argument(fmt::format("meshing it at element size {:g} m would make about {:.3g} nodes, which Gmsh needs about {} "
                                            "to make, but this machine has {} available{}",
                                            h, nodes, gib(need), gib(have), nodes > double(std::numeric_limits<std::int32_t>::max()) ? " (and 2^31 nodes at most)" : ""));
}

void require_bonds_fit(std::size_t points, int dim, double horizon, double spacing, double bytes_per_bond) {
  // Lattice neighbours within delta: the ball's volume in cells, plus a shell of half a cell
  // for partners counted at the horizon edge.
  const double r = horizon / spacing + 0.5;
  const double neighbours = dim == 2 ? std::numbers::pi * r * r : 4.0 / 3.0 * std::numbers::pi * r * r * r;
  const double bonds = double(points) * neighbours;
  const double need = bonds * bytes_per_bond + double(points) * bytes_per_point, have = available_memory_bytes();
  const std::string estimate = fmt::format("{} points x about {:.3g} neighbours = {:.3g} directed bonds, about {}", points, neighbours,
                                           bonds, gib(need));
  if (need > have || bonds > 9.0e18)
    throw DeckError(fmt::format("discretization: horizon {:g} m = {:.3g} h: {} needed, but this machine has {} available. "
                                "Reduce horizon or horizon_factor, or the number of points",
                                horizon, horizon / spacing, estimate, gib(have)));
  if (need > memory_warning_fraction * have)
    fmt::print(stderr, "warning: this run needs {} of the {} available ({})\n", gib(need), gib(have), estimate);
}

}  // namespace peridot
