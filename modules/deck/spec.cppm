export module peridot.deck:spec;
import peridot.std;
import peridot.quadrature;
import peridot.implicit;

export namespace peridot {

// One implementation per seam, as the deck names it. Which combinations run is decided in one
// place, the table in :combinations; nothing else branches on these.
enum class DiscretizationKind { lattice, mesh };
enum class QuadratureKind { volume, partial_volume, gmls, element, cell_area };
enum class ModelKind { pmb, lps, rnp, osb };
// How bonds are stored: a CSR list, or a stencil of lattice offsets (PMB on an unperturbed
// lattice; `automatic` picks it whenever it applies).
// compact: a list without stored xi and |xi| (BondList::compact; explicit RNP).
enum class BondLayout { automatic, list, compact, stencil };
// PMB on a lean bond list: single-precision forces (the default) or the double path.
enum class ListPrecision { single, double_precision };
enum class BoundaryMethodKind { layers, collar_traction, fictitious_taylor, outermost_nodes };
enum class SolverKind { explicit_dynamics, static_linear, quasi_static, newmark };

struct MaterialSpec {
  ModelKind model = ModelKind::pmb;
  Kinematics kinematics = Kinematics::plane_stress;
  double youngs_modulus = 0;   // E [Pa]
  double density = 0;          // rho [kg/m^3]
  double fracture_energy = 0;  // G0 [J/m^2] (pmb)
  double poisson_ratio = 0.25; // nu (lps)
  QuadratureRule quadrature = QuadratureRule::gmls;  // lps bond weights
  // rnp: either C and beta as given, or both from youngs_modulus and fracture_energy.
  double rnp_C = 0, rnp_beta = 0;
  double break_factor = 0;     // rnp: > 0 breaks a bond for good past this multiple of r_c
  RnpInfluence influence = RnpInfluence::constant;  // rnp: J(|xi| / eps)
  // rnp from youngs_modulus and fracture_energy: matched to E and G_c (Rnp::from_elastic), or
  // Lipton's constants of seed 003 eq. (83), whose effective Young's modulus is 2E (spec 003 Sec. 1.5).
  bool lipton_calibration = false;
};

// A triangle mesh (seed 003) in 2D or a tetrahedral one in 3D: structured, or read from a Gmsh
// .msh / meshed from a .geo. The mesh is read when the deck is, so group names are checked
// before anything runs. Exactly one of `mesh` and `tets` is set, except on MPI ranks other than
// 0, which hold its `summary` only.
struct MeshSpec {
  std::filesystem::path file;          // empty: structured
  double size = 0;                     // .geo element size [m]; 0: the file's own sizes
  Vec3 lo{0, 0, 0}, hi{0, 0, 0};       // structured box [m]
  int nx = 0, ny = 0, nz = 0;          // structured cells (nz: 3D)
  bool lower_left_diagonal = true;     // 2D structured
  int quadrature_order = 2;            // element rule degree for V_ij
  bool spatial_order = true;           // a file's nodes renumbered along a Morton curve (order_nodes_spatially)
  std::shared_ptr<const TriangleMesh> mesh;
  std::shared_ptr<const TetMesh> tets;
  // On N MPI ranks rank 0 alone holds the mesh and sends each rank its share at set-up; the
  // other ranks hold what the deck's checks read (make_mesh_once).
  struct Summary {
    Aabb bounds{};
    double mean_edge = 0;
    std::map<std::string, std::vector<std::int32_t>> groups;  // the names, with no nodes
  };
  std::shared_ptr<const Summary> summary;
  // On N MPI ranks a .msh in spatial node order is read by every rank, each keeping its part
  // only (read_mesh_part): no rank holds the whole mesh, and the set-up takes each rank's
  // share from its part. Then `summary` is set on every rank and `mesh`, `tets` on none.
  struct Part {
    std::vector<std::int64_t> ids;            // the held nodes' global ids (the one-process numbering), ascending
    std::vector<int> owner;                   // the rank that owns each held node
    PointCloud points;                        // held nodes: positions, lumped volumes, the elements among them (mesh order)
    std::vector<std::uint8_t> complete;       // 1 where every element of the node is held: its volume is the whole mesh's
    std::vector<std::uint64_t> owned_counts;  // every rank's owned node count (runs of the numbering, unless `bricks`)
    double longest_edge = 0;                  // the whole mesh's [m]
    int depth = 0;                            // held: the nodes within depth + 1 cubes of an owned node's cube
    Vec3 cube_origin{};                       // cubes of side >= 1.01 (horizon + longest edge): a bond reach
    double cube_side = 0;
    std::map<std::string, std::vector<std::int64_t>> groups;  // per group, the global ids of its held nodes, ascending
    std::shared_ptr<const BrickCut> bricks;  // a structured mesh's: the ranks own bricks of its node grid; else runs of the numbering
  };
  std::shared_ptr<const Part> part;  // released once the set-up has taken its share

  // On N ranks once every rank has its share: no rank keeps the whole mesh (rank 0 read or made
  // it) or its part; what the run still asks of the mesh (bounds, mean edge, group names) stays
  // in `summary`.
  void release_whole() {
    if (held()) {
      Summary s;
      s.bounds = bounds();
      s.mean_edge = mean_edge();
      for (const auto& [name, nodes] : groups()) s.groups[name];
      summary = std::make_shared<const Summary>(std::move(s));
      mesh.reset();
      tets.reset();
    }
    part.reset();
  }

  bool held() const { return mesh || tets; }
  const std::map<std::string, std::vector<std::int32_t>>& groups() const {
    return tets ? tets->groups : mesh ? mesh->groups : summary->groups;
  }
  Aabb bounds() const { return tets ? tets->bounds() : mesh ? mesh->bounds() : summary->bounds; }
  double mean_edge() const { return tets ? tets->mean_edge() : mesh ? mesh->mean_edge() : summary->mean_edge; }
  PointCloud points() const {
    if (!held()) throw std::logic_error("the mesh is held by MPI rank 0 only");
    return tets ? mesh_points(*tets) : mesh_points(*mesh);
  }
};

// Quasi-static load control (seed 002): Newton on the tangent, or Ceres on the same residual.
struct QuasiStaticSpec {
  QuasiStaticOptions options;
};

// A region of different elastic moduli (composites, seed 000 Sec. 5.4).
struct InclusionSpec {
  Shape region;
  double youngs_modulus = 0;   // [Pa]
  double poisson_ratio = 0;
};

// Closed-form reference solution of a static problem: Dirichlet data, body force, tractions
// and the errors reported after the solve.
struct ReferenceSpec {
  std::string type;            // linear_patch | manufactured_sine | kirsch_hole | hollow_disk | circular_inclusion | spherical_inclusion
  double A = 0.4;              // manufactured_sine wave number [1/m]
  double radius = 0.2;         // kirsch_hole / circular_inclusion / spherical_inclusion radius [m]
  double sigma0 = 1;           // kirsch_hole far-field stress [Pa]
  double inner_radius = 1, outer_radius = 1.5, pressure = 0.1;  // hollow_disk [m, m, Pa]
  double inclusion_stress = 1;  // circular_inclusion, spherical_inclusion: hydrostatic stress P inside the inclusion [Pa]
};

// Exterior points inside `region` are traction (Neumann) ghosts; the traction is sigma(u_ref) n
// from the reference solution, or a constant vector. With at_projection, the reference traction
// is taken at the point's projection x-bar onto the region's surface with the exact normal there
// (seed 000 (4.6)); otherwise at the point itself with the numerical normal (4.9).
// With exact_normal, (4.6) uses the exact surface normal at x-bar for n_i and p_i instead of the
// numerical normal (4.9), the paper's choice and the default.
struct NeumannSpec {
  Shape region;
  bool from_reference = true;
  bool at_projection = true;
  bool exact_normal = false;
  Vec3 traction{0, 0, 0};      // [Pa]
};

// Static OSB on a rectangle (seed 004): what each edge imposes, the Taylor order, a body
// force, an optional closed-form reference and sequentially linear fracture.
struct OsbStaticSpec {
  EdgeConditions conditions;
  int taylor_order = 1;
  std::string body_force = "none";     // none | uniform | cosine
  Vec3 body_force_value{0, 0, 0};      // uniform: b; cosine: b cos(pi x / Lx) cos(pi y / Ly), origin at the centre [N/m^3]
  bool affine_reference = false;       // u_ref = displacement + gradient (x - centre)
  std::array<double, 2> reference_displacement{0, 0};
  std::array<double, 4> reference_gradient{0, 0, 0, 0};  // du/dx, du/dy, dv/dx, dv/dy
  int bonds_per_solve = 4;             // fracture: bonds removed per re-solve
  std::size_t max_solves = 100000;
};

struct StaticSpec {
  OsbStaticSpec osb;
  ReferenceSpec reference;
  std::vector<NeumannSpec> neumann;
  LinearSolver linear_solver = LinearSolver::petsc;  // OSB decks: umfpack
  bool linear_solver_named = false;  // the deck chose it (else N MPI ranks solve OSB on PETSc)
  std::string petsc_options;   // solver.petsc_options, e.g. "-ksp_type gmres -pc_type hypre"
  double band_factor = 2;      // exterior band width / delta (2: theta on the collar needs u_D a further delta out)
};

struct BoundarySpec {
  std::string name;
  BoundaryKind kind = BoundaryKind::body_force;
  Shape region;
  std::string group;                      // a mesh physical group instead of a region
  Vec3 value{0, 0, 0};                    // body force [N/m^3], displacement [m] or velocity [m/s]
  std::array<bool, 3> components{true, true, true};
  TimeFunction history;
  // With boundary_method: collar_traction (LPS dynamics), a traction acts through the nonlocal
  // traction operator on the exterior points inside `region`: value is T [Pa], or with
  // `normal` value[0] is the normal traction T_n along the outward normal (pressure = -T_n).
  bool nonlocal_traction = false;
  bool normal = false;
};

// Observer cadences in steps; 0 turns an observer off.
struct OutputSpec {
  std::filesystem::path directory = "out";
  std::size_t vtu_every = 0;
  bool vtu_stress = false;  // point fields stress_xx, ... [Pa] in every VTU (needs a pair-force model)
  std::size_t csv_every = 0;
  std::size_t plot_every = 0;  // history rows kept for <name>_history.png, drawn at the end of the run
  std::size_t png_every = 0;
  int png_width = 1200;
  std::string png_field = "damage";
  bool png_deformed = false;
  double png_magnification = 1.0;
  // 3D: a slice through the plane normal to png_axis (0, 1, 2: x, y, z) at png_slice_at [m]
  // (default: the body's mid-plane), or a projection along it, the largest value in front.
  bool png_projection = false;
  int png_axis = 2;
  std::optional<double> png_slice_at;
  std::size_t dds_every = 0;
  std::size_t dds_snapshot_every = 0;
  std::size_t fragments_every = 0;
  double large_fragment_fraction = 0.01;
  std::size_t crack_tip_every = 0;
  bool condition_number = false;  // quasi-static: cond_2 of the reduced tangent per load step (dense SVD)
  double crack_tip_threshold = 0.35;
  Vec3 crack_tip_origin{0, 0, 0};
  std::optional<Vec3> crack_tip_direction;
  bool crack_tip_speed_along_direction = false;
  // 3D: the crack front, slice by slice across crack_front_axis (0, 1, 2), to <name>_crack_front.csv.
  std::size_t crack_front_every = 0;
  int crack_front_axis = 2;
  Vec3 crack_front_direction{1, 0, 0};
  Vec3 crack_front_origin{0, 0, 0};
  double crack_front_threshold = 0.35;
  std::size_t checkpoint_every = 0;  // explicit runs: steps between HDF5 restart checkpoints (and the last step)
  std::string checkpoint_file;       // a file name in the output directory; default <name>.h5

  // Whether an observer needs the stress tensor, and so per-bond pair forces.
  bool wants_stress() const {
    return (vtu_every && vtu_stress) || (png_every && (png_field.starts_with("stress_") || png_field == "von_mises"));
  }
};

// A whole problem as read from a deck: geometry, discretization, material, loads,
// solver and output. Building it into a Body is peridot::setup().
struct Problem {
  std::string name = "run";    // a file stem: letters, digits, '.', '_' and '-'
  int dim = 2;
  Shape body;
  std::vector<Crack> cracks;
  LatticeOptions lattice;      // with a mesh, spacing holds its mean edge length
  MeshSpec mesh;
  double horizon = 0;          // delta [m]
  bool partial_volume = false;
  bool precrack_damage = true; // damage counts bonds cut by pre-cracks as broken (as CabanaPD, Peridigm)
  MaterialSpec material;
  std::vector<Shape> no_fail;
  std::vector<BoundarySpec> boundaries;
  std::vector<InclusionSpec> inclusions;
  DiscretizationKind discretization_kind = DiscretizationKind::lattice;
  QuadratureKind quadrature_kind = QuadratureKind::volume;
  BondLayout bond_layout = BondLayout::automatic;
  ListPrecision list_precision = ListPrecision::single;
  BoundaryMethodKind boundary_method = BoundaryMethodKind::layers;
  SolverKind solver_kind = SolverKind::explicit_dynamics;
  ExplicitOptions solver;
  NewmarkOptions newmark;      // solver.type = newmark (end_time and dt shared with `solver`)
  StaticSpec statics;
  QuasiStaticSpec quasi_static;
  OutputSpec output;
  // Identifies the physics of the deck for restarts: a 64-bit FNV-1a hash of the parsed YAML
  // with map keys sorted, leaving out `name`, `output` and `solver.end_time` (which a restart
  // may change). Comments, layout and key order do not change it; any other value does.
  std::uint64_t content_hash = 0;
};

}  // namespace peridot
