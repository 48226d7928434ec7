// peridot.io: file formats only. YAML deck reading primitives (validated maps with field
// paths in every error), VTU/PVD output and reading, the CSV history, Gmsh triangle meshes
// and HDF5 restart checkpoints. It knows nothing of models or solvers; turning a deck into a
// run is peridot.problem.
export module peridot.io;
import peridot.std;
export import peridot.discretization;
export import :files;
export import :deck_reader;
export import :vtu;
export import :history_csv;
export import :gmsh_mesh;
export import :checkpoint;
