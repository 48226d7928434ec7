// peridot.discretization: point clouds, nodal volumes, neighbour search, CSR bond lists and
// lattice stencils.
export module peridot.discretization;
import peridot.std;
export import peridot.geometry;
export import :point_cloud;
export import :large_array;
export import :bond_list;
export import :neighbor_search;
export import :exterior;
export import :triangle_mesh;
export import :tetrahedral_mesh;
export import :node_order;
export import :lattice_grid;
export import :stencil;
export import :slab;
