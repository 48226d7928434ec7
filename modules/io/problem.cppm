module;
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>
export module peridot.io:problem;
import peridot.solvers;

export namespace peridot {

enum class ModelKind { pmb };

struct MaterialSpec {
  ModelKind model = ModelKind::pmb;
  Kinematics kinematics = Kinematics::plane_stress;
  double youngs_modulus = 0;   // E [Pa]
  double density = 0;          // rho [kg/m^3]
  double fracture_energy = 0;  // G0 [J/m^2]
};

struct BoundarySpec {
  std::string name;
  BoundaryKind kind = BoundaryKind::body_force;
  Shape region;
  Vec3 value{0, 0, 0};                    // body force [N/m^3], displacement [m] or velocity [m/s]
  std::array<bool, 3> components{true, true, true};
  TimeFunction history;
};

// Observer cadences in steps; 0 turns an observer off.
struct OutputSpec {
  std::filesystem::path directory = "out";
  std::size_t vtu_every = 0;
  std::size_t csv_every = 0;
  std::size_t png_every = 0;
  int png_width = 1200;
  std::string png_field = "damage";
  bool png_deformed = false;
  double png_magnification = 1.0;
  std::size_t dds_every = 0;
  std::size_t dds_snapshot_every = 0;
  std::size_t fragments_every = 0;
  double large_fragment_fraction = 0.01;
  std::size_t crack_tip_every = 0;
  double crack_tip_threshold = 0.35;
  Vec3 crack_tip_origin{0, 0, 0};
  std::optional<Vec3> crack_tip_direction;
};

// A whole problem as read from a deck: geometry, discretization, material, loads,
// solver and output. Building it into a Body is peridot::setup().
struct Problem {
  std::string name = "run";
  int dim = 2;
  Shape body;
  std::vector<Crack> cracks;
  LatticeOptions lattice;
  double horizon = 0;          // delta [m]
  bool partial_volume = false;
  MaterialSpec material;
  std::vector<Shape> no_fail;
  std::vector<BoundarySpec> boundaries;
  ExplicitOptions solver;
  OutputSpec output;
};

}  // namespace peridot
