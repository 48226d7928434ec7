module;
#include <yaml-cpp/yaml.h>
export module peridot.deck:parse;
import peridot.std;
import peridot.io;
import peridot.quadrature;
import peridot.implicit;
import :spec;
import :combinations;
import :resources;
import :mesh_once;

export namespace peridot {

// Reads and validates a deck. Every error is a DeckError naming the field, the value and
// the allowed range. SI units throughout; see data/decks/README.md for the schema.
// Relative mesh paths are resolved against base_dir (read_deck: the deck's folder).
Problem parse_deck(const std::string& yaml_text, const std::string& source = "deck", const std::filesystem::path& base_dir = {});
Problem read_deck(const std::filesystem::path& file);

// Decks are small; anything larger is refused before it is parsed.
inline constexpr std::size_t max_deck_bytes = 1 << 20;

}  // namespace peridot

namespace peridot {

namespace {

Vec3 point(DeckMap& m, const std::string& key, int dim) {
  const auto v = m.numbers(key, std::size_t(dim), std::size_t(dim));
  Vec3 p{0, 0, 0};
  for (int k = 0; k < dim; ++k) p[k] = v[k];
  return p;
}

Vec3 point_node(const YAML::Node& n, const std::string& path, int dim) {
  if (!n.IsSequence() || n.size() != std::size_t(dim)) throw DeckError(fmt::format("{}: expected a list of {} numbers", path, dim));
  Vec3 p{0, 0, 0};
  for (int k = 0; k < dim; ++k) p[k] = parse_number(n[k], fmt::format("{}[{}]", path, k), {});
  return p;
}

struct ShapeContext {
  int dim;
  double spacing;
  Aabb body;  // bounds of the body shape, for layers
  bool allow_layers;
  const std::map<std::string, std::vector<std::int32_t>>* groups = nullptr;  // mesh physical groups
};

Shape parse_shape(const YAML::Node& node, const std::string& path, const ShapeContext& ctx);

Shape check_dim(Shape s, const std::string& path, int dim) {
  if (s.dimension() != dim) throw DeckError(fmt::format("{}: a {}D shape in a {}D problem", path, s.dimension(), dim));
  return s;
}

Shape parse_list(const YAML::Node& n, const std::string& path, const ShapeContext& ctx, bool is_union) {
  if (!n.IsSequence() || n.size() < 2) throw DeckError(fmt::format("{}: expected a list of at least 2 shapes", path));
  Shape s = parse_shape(n[0], path + "[0]", ctx);
  for (std::size_t k = 1; k < n.size(); ++k) {
    Shape t = parse_shape(n[k], fmt::format("{}[{}]", path, k), ctx);
    s = is_union ? unite(std::move(s), std::move(t)) : subtract(std::move(s), std::move(t));
  }
  return s;
}

// A slab of the body's bounding box: the outermost `count` lattice layers, or `thickness` metres.
Shape parse_layer(DeckMap m, const ShapeContext& ctx, double* thickness_out) {
  std::vector<std::string> sides{"-x", "+x"};
  if (ctx.dim >= 2) sides.insert(sides.end(), {"-y", "+y"});
  if (ctx.dim == 3) sides.insert(sides.end(), {"-z", "+z"});
  const auto side = m.choice("side", sides);
  double t = 0;
  if (m.has("thickness") && m.has("count")) m.fail("thickness", "give either count or thickness, not both");
  if (m.has("thickness")) t = m.number("thickness", Range::positive());
  else t = double(m.integer("count", Range::between(1, 1e6), 1)) * ctx.spacing;
  m.finish();
  const int axis = side[1] - 'x';
  const double big = 1e300;
  Vec3 lo{-big, -big, -big}, hi{big, big, big};
  if (side[0] == '+') lo[axis] = ctx.body.hi[axis] - t;
  else hi[axis] = ctx.body.lo[axis] + t;
  if (thickness_out) *thickness_out = t;
  return ctx.dim == 1 ? interval(lo[0], hi[0]) : ctx.dim == 2 ? rectangle(lo, hi) : box(lo, hi);
}

Shape parse_shape(const YAML::Node& node, const std::string& path, const ShapeContext& ctx) {
  if (!node.IsMap() || node.size() != 1)
    throw DeckError(fmt::format("{}: a shape is a mapping with exactly one key: interval, rectangle, box, disk, sphere, annulus, "
                                "cylinder_shell, polygon, union, difference{}",
                                path, ctx.allow_layers ? ", layer" : ""));
  const auto kind = node.begin()->first.as<std::string>();
  const YAML::Node body = node.begin()->second;
  const std::string p = path + "." + kind;
  const bool three_d = kind == "box" || kind == "sphere" || kind == "cylinder_shell";
  const bool two_d = kind == "rectangle" || kind == "disk" || kind == "annulus" || kind == "polygon";
  const bool one_d = kind == "interval";
  if ((three_d && ctx.dim != 3) || (two_d && ctx.dim != 2) || (one_d && ctx.dim != 1))
    throw DeckError(fmt::format("{}: a {}D shape in a {}D problem", p, three_d ? 3 : two_d ? 2 : 1, ctx.dim));
  try {
    if (kind == "union" || kind == "difference") return parse_list(body, p, ctx, kind == "union");
    if (kind == "polygon") {
      DeckMap m(body, p);
      std::vector<Vec3> v;
      const auto list = m.list("vertices");
      for (std::size_t k = 0; k < list.size(); ++k) v.push_back(point_node(list[k], fmt::format("{}.vertices[{}]", p, k), 2));
      m.finish();
      return check_dim(polygon(std::move(v)), p, ctx.dim);
    }
    DeckMap m(body, p);
    Shape s;
    if (kind == "interval") {
      const Vec3 lo = point(m, "min", 1), hi = point(m, "max", 1);
      s = interval(lo[0], hi[0]);
    } else if (kind == "rectangle" || kind == "box") {
      const int d = kind == "rectangle" ? 2 : 3;
      const Vec3 lo = point(m, "min", d), hi = point(m, "max", d);
      s = d == 2 ? rectangle(lo, hi) : box(lo, hi);
    } else if (kind == "disk" || kind == "sphere") {
      const int d = kind == "disk" ? 2 : 3;
      const Vec3 c = point(m, "center", d);
      const double r = m.number("radius", Range::positive());
      s = d == 2 ? disk(c, r) : sphere(c, r);
    } else if (kind == "annulus" || kind == "cylinder_shell") {
      const Vec3 c = point(m, "center", 2);
      const double ri = m.number("inner_radius", Range::non_negative());
      const double ro = m.number("outer_radius", Range{ri, 1e300, true, false});
      if (kind == "annulus") s = annulus(c, ri, ro);
      else {
        const double z0 = m.number("z_min", {}), z1 = m.number("z_max", Range{z0, 1e300, true, false});
        s = cylinder_shell(c, ri, ro, z0, z1);
      }
    } else if (kind == "layer" && ctx.allow_layers) {
      return parse_layer(std::move(m), ctx, nullptr);
    } else {
      throw DeckError(fmt::format("{}: unknown shape '{}'", path, kind));
    }
    m.finish();
    return check_dim(std::move(s), p, ctx.dim);
  } catch (const std::invalid_argument& e) {
    throw DeckError(fmt::format("{}: {}", p, e.what()));
  }
}

// A required shape under `key` of m.
Shape required_shape(DeckMap& m, const std::string& key, const ShapeContext& ctx) {
  if (!m.has(key)) m.fail(key, "required shape is missing");
  return parse_shape(m.raw(key), m.child_path(key), ctx);
}

TimeFunction parse_history(DeckMap m) {
  const auto type = m.choice("type", {"constant", "ramp", "exp_decay", "table", "sine"}, "constant");
  TimeFunction f;
  if (type == "ramp") {
    const double a = m.number("start", Range::non_negative(), 0.0);
    f = TimeFunction::ramp(a, m.number("end", Range{a, 1e300, true, false}));
  } else if (type == "exp_decay") {
    f = TimeFunction::exp_decay(m.number("tau", Range::positive()));
  } else if (type == "sine") {
    const double hz = m.number("frequency", Range::positive());
    f = TimeFunction::sine(hz, m.number("phase", {}, 0.0));
  } else if (type == "table") {
    auto t = m.numbers("times", 1, 100000, Range::non_negative());
    auto v = m.numbers("values", t.size(), t.size());
    for (std::size_t k = 1; k < t.size(); ++k)
      if (!(t[k] > t[k - 1])) m.fail("times", "must be strictly increasing");
    f = TimeFunction::table(std::move(t), std::move(v));
  }
  m.finish();
  return f;
}

BoundarySpec parse_boundary(DeckMap m, const ShapeContext& ctx, std::size_t index, bool quasi_static, bool nonlocal_traction) {
  BoundarySpec bc;
  bc.name = m.text("name", fmt::format("boundary{}", index));
  const auto type = m.choice("type", {"traction", "body_force", "displacement", "velocity"});
  // Quasi-static loads are value x the load factor: no velocities, no time histories.
  if (quasi_static && type == "velocity") m.fail("type", "= 'velocity': not used by solver.type = 'quasi_static' (use displacement)");
  if (quasi_static && m.has("history"))
    m.fail("history", "not used by solver.type = 'quasi_static' (loads are value x the load factor, 0 to 1 over solver.steps)");
  double thickness = 0;
  if (!m.has("region")) m.fail("region", "required shape is missing");
  if (type == "traction" && nonlocal_traction) {
    // LPS dynamics: the traction acts through (4.6) on the exterior points inside the region.
    bc.nonlocal_traction = true;
    bc.kind = BoundaryKind::body_force;
    bc.region = parse_shape(m.raw("region"), m.child_path("region"), ctx);
    if (m.has("normal") == m.has("value")) m.fail("value", "a nonlocal traction takes either value: [T_x, T_y] (Pa) or normal: T_n (Pa, > 0 pulls), not both or neither");
    if (m.has("normal")) {
      bc.normal = true;
      bc.value = {m.number("normal", {}), 0, 0};
    } else {
      bc.value = point(m, "value", ctx.dim);
    }
    if (m.has("components")) m.fail("components", "only kinematic boundaries (displacement, velocity) select components");
    if (auto h = m.optional_map("history")) bc.history = parse_history(std::move(*h));
    m.finish();
    return bc;
  }
  if (type == "traction") {
    const auto r = m.raw("region");
    if (!r.IsMap() || r.size() != 1 || !r["layer"])
      m.fail("region", "a traction acts on a boundary layer: use region: {layer: {side: +y, count: 1}}");
    bc.region = parse_layer(DeckMap(r["layer"], m.child_path("region.layer")), ctx, &thickness);
  } else if (const auto r = m.raw("region"); r.IsMap() && r.size() == 1 && r["group"]) {
    // A named node set of the mesh (a Gmsh physical group, or left/right/bottom/top of a structured mesh).
    DeckMap region(r, m.child_path("region"));
    const auto path = region.child_path("group");
    bc.group = region.text("group");
    region.finish();
    if (!ctx.groups) throw DeckError(path + ": physical groups exist only with discretization.type = 'mesh'");
    if (!ctx.groups->contains(bc.group)) {
      std::string names;
      for (const auto& [name, nodes] : *ctx.groups) names += (names.empty() ? "" : ", ") + name;
      throw DeckError(fmt::format("{} = '{}': the mesh has no such physical group (it has: {})", path, shown(bc.group), names.empty() ? "none" : names));
    }
  } else {
    bc.region = parse_shape(m.raw("region"), m.child_path("region"), ctx);
  }
  bc.value = point(m, "value", ctx.dim);
  if (type == "traction") {
    // Traction [Pa] spread over the layer as a body force density [N/m^3].
    bc.kind = BoundaryKind::body_force;
    bc.value = (1.0 / thickness) * bc.value;
  } else {
    bc.kind = type == "body_force" ? BoundaryKind::body_force
              : type == "displacement" ? BoundaryKind::displacement : BoundaryKind::velocity;
  }
  if (m.has("components")) {
    if (bc.kind == BoundaryKind::body_force) m.fail("components", "only kinematic boundaries (displacement, velocity) select components");
    bc.components = {false, false, false};
    const auto list = m.list("components");
    if (list.empty()) m.fail("components", "must name at least one of x, y, z");
    for (const auto& c : list) {
      const auto s = c.as<std::string>();
      if (s.size() != 1 || s[0] < 'x' || s[0] >= 'x' + ctx.dim) m.fail("components", fmt::format("= '{}': allowed x, y{}", s, ctx.dim == 3 ? ", z" : ""));
      bc.components[s[0] - 'x'] = true;
    }
  }
  if (auto h = m.optional_map("history")) bc.history = parse_history(std::move(*h));
  m.finish();
  return bc;
}

// A file name without directories: 1 to 100 letters, digits, '.', '_' and '-', not '.' or '..'.
void require_file_name(const DeckMap& m, const std::string& key, const std::string& value) {
  if (value.empty() || value.size() > 100 || value == "." || value == "..")
    m.fail(key, fmt::format("= '{}': must be 1 to 100 characters of letters, digits, '.', '_' and '-'", shown(value)));
  for (char c : value)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == '-'))
      m.fail(key, fmt::format("= '{}': character '{}' is not allowed; use letters, digits, '.', '_' and '-'", shown(value), c));
}

std::size_t cadence(DeckMap& out, const std::string& key) {
  auto m = out.optional_map(key);
  if (!m) return 0;
  const auto every = std::size_t(m->integer("every", Range::between(0, 1e12), 0));
  m->finish();
  return every;
}

void parse_png(DeckMap& m, OutputSpec& o, int dim) {
  auto png = m.optional_map("png");
  if (!png) return;
  if (dim == 1) m.fail("png", "PNG snapshots draw 2D and 3D bodies (dimension = 1 here): use output.vtu or output.csv");
  o.png_every = std::size_t(png->integer("every", Range::between(0, 1e12), 0));
  o.png_width = int(png->integer("width", Range::between(16, 16384), 1200));
  o.png_field = png->choice("field", {"damage", "displacement", "velocity", "stress_xx", "stress_yy", "stress_xy", "von_mises"}, "damage");
  o.png_deformed = png->flag("deformed", false);
  o.png_magnification = png->number("magnification", Range::non_negative(), 1.0);
  for (const char* key : {"view", "axis", "slice_at"})
    if (dim != 3 && png->has(key))
      png->fail(key, fmt::format("chooses how a 3D body is drawn (dimension = {} here; a 2D body is drawn whole)", dim));
  o.png_projection = png->choice("view", {"slice", "projection"}, "slice") == "projection";
  const auto axis = png->choice("axis", {"x", "y", "z"}, "z");
  o.png_axis = axis == "x" ? 0 : axis == "y" ? 1 : 2;
  if (png->has("slice_at")) {
    if (o.png_projection) png->fail("slice_at", "places a slice; view = 'projection' draws the whole depth");
    o.png_slice_at = png->number("slice_at", Range{}, 0.0);
  }
  png->finish();
}

void parse_dds(DeckMap& m, OutputSpec& o) {
  if (auto dds = m.optional_map("dds")) {
    o.dds_every = std::size_t(dds->integer("every", Range::between(0, 1e12), 0));
    o.dds_snapshot_every = std::size_t(dds->integer("snapshot_every", Range::between(0, 1e12), 0));
    dds->finish();
  }
}

void parse_fragments(DeckMap& m, OutputSpec& o) {
  if (auto fr = m.optional_map("fragments")) {
    o.fragments_every = std::size_t(fr->integer("every", Range::between(0, 1e12), 0));
    o.large_fragment_fraction = fr->number("large_mass_fraction", Range::between(0, 1), 0.01);
    fr->finish();
  }
}

OutputSpec parse_output(DeckMap m, int dim, SolverKind solver, bool osb_static = false, bool pair_forces = true) {
  OutputSpec o;
  o.directory = m.text("directory", "out");
  // A static solve has one state: its history is one row, its live state one summary.
  const auto static_observers = [&] {
    o.csv_every = cadence(m, "csv");
    parse_dds(m, o);
  };
  if (solver == SolverKind::static_linear && osb_static) {
    // One state, written once: the VTU carries the stress (51) always; a PNG draws one field.
    o.vtu_every = cadence(m, "vtu");
    parse_png(m, o, dim);
    if (o.png_field == "velocity") m.fail("png", "field = 'velocity': a static solve has no velocity");
    static_observers();
    // A fracture run (static.fracture) re-solves: its history has a row per solve, which the
    // plot draws, and the plate may come apart into fragments.
    o.plot_every = cadence(m, "plot");
    parse_fragments(m, o);
    for (const char* key : {"crack_tip", "checkpoint"})
      if (m.has(key))
        m.fail(key, "not used by a static OSB solve (it writes one VTU and one PNG at the end, and a CSV row, DDS summary, plot point and "
                    "fragment count per linear solve)");
    m.finish();
    return o;
  }
  if (solver == SolverKind::static_linear) {
    // A static solve has one state: it is written once, as a VTU, when `vtu` is on.
    if (auto vtu = m.optional_map("vtu"); vtu && vtu->has("stress"))
      vtu->fail("stress", "not used by solver.type = 'static' (only explicit and quasi-static runs write the stress)");
    o.vtu_every = cadence(m, "vtu");
    static_observers();
    parse_png(m, o, dim);
    if (o.png_field == "velocity") m.fail("png", "field = 'velocity': a static solve has no velocity");
    if (o.png_field != "damage" && o.png_field != "displacement")
      m.fail("png", fmt::format("field = '{}': material.model = 'lps' reports no pair forces, so it has no stress tensor", o.png_field));
    for (const char* key : {"fragments", "crack_tip", "crack_front", "checkpoint"})
      if (m.has(key)) m.fail(key, "not used by solver.type = 'static' (a static solve writes one VTU, PNGs of its start and solution, a CSV row and DDS summaries)");
    m.finish();
    return o;
  }
  if (auto vtu = m.optional_map("vtu")) {
    o.vtu_every = std::size_t(vtu->integer("every", Range::between(0, 1e12), 0));
    o.vtu_stress = vtu->flag("stress", false);
    if (o.vtu_stress && !pair_forces) vtu->fail("stress", "material.model = 'lps' reports no pair forces, so it has no stress tensor");
    vtu->finish();
  }
  o.csv_every = cadence(m, "csv");
  o.plot_every = cadence(m, "plot");
  if (m.has("condition_number") && solver != SolverKind::quasi_static)
    m.fail("condition_number", "only solver.type = 'quasi_static' has a tangent to take the condition number of");
  o.condition_number = m.flag("condition_number", false);
  parse_png(m, o, dim);
  if (!pair_forces && (o.png_field.starts_with("stress_") || o.png_field == "von_mises"))
    m.fail("png", fmt::format("field = '{}': material.model = 'lps' reports no pair forces, so it has no stress tensor", o.png_field));
  parse_dds(m, o);
  parse_fragments(m, o);
  if (auto tip = m.optional_map("crack_tip")) {
    if (dim != 2) m.fail("crack_tip", fmt::format("crack-tip tracking is implemented for 2D runs only (dimension = {} here)", dim));
    o.crack_tip_every = std::size_t(tip->integer("every", Range::between(0, 1e12), 0));
    o.crack_tip_threshold = tip->number("threshold", Range::between(0, 1e6), 0.35);
    if (tip->has("origin")) o.crack_tip_origin = point(*tip, "origin", dim);
    if (tip->has("direction")) o.crack_tip_direction = point(*tip, "direction", dim);
    o.crack_tip_speed_along_direction = tip->choice("speed", {"path", "along_direction"}, "path") == "along_direction";
    if (o.crack_tip_speed_along_direction && !o.crack_tip_direction) tip->fail("speed", "= 'along_direction' needs output.crack_tip.direction");
    tip->finish();
  }
  if (auto front = m.optional_map("crack_front")) {
    if (dim != 3) m.fail("crack_front", fmt::format("tracks the front of a 3D crack (dimension = {} here; 2D runs use output.crack_tip)", dim));
    o.crack_front_every = std::size_t(front->integer("every", Range::between(0, 1e12), 0));
    const auto axis = front->choice("axis", {"x", "y", "z"}, "z");
    o.crack_front_axis = axis == "x" ? 0 : axis == "y" ? 1 : 2;
    o.crack_front_threshold = front->number("threshold", Range::between(0, 1e6), 0.35);
    if (front->has("origin")) o.crack_front_origin = point(*front, "origin", dim);
    o.crack_front_direction = point(*front, "direction", dim);
    auto across = o.crack_front_direction;
    across[std::size_t(o.crack_front_axis)] = 0;
    if (!(std::abs(across[0]) + std::abs(across[1]) + std::abs(across[2]) > 0))
      front->fail("direction", fmt::format("must point across the slices: it has no component off axis {}", axis));
    front->finish();
  }
  if (auto ck = m.optional_map("checkpoint")) {
    if (solver != SolverKind::explicit_dynamics)
      m.fail("checkpoint", fmt::format("not used by solver.type = '{}' (only explicit runs write restart checkpoints)",
                                       seam_names(Seam::solver)[std::size_t(solver)]));
    o.checkpoint_every = std::size_t(ck->integer("every", Range::between(0, 1e12), 0));
    if (ck->has("file")) {
      o.checkpoint_file = ck->text("file");
      require_file_name(*ck, "file", o.checkpoint_file);
      if (!o.checkpoint_file.ends_with(".h5") || o.checkpoint_file.size() < 4)
        ck->fail("file", fmt::format("= '{}': a checkpoint is an HDF5 file; the name must end in '.h5'", shown(o.checkpoint_file)));
    }
    ck->finish();
  }
  m.finish();
  return o;
}

// The memory a mesh body of about `nodes` nodes with elements of size h [m] and bonds out to
// `horizon` needs, checked before the mesh exists (the estimate of the mesh set-up itself).
void require_mesh_fits(double nodes, int dim, double h, double horizon) {
  const double capped = std::min(nodes, 1e15);  // beyond any machine; keeps the conversion defined
  require_bonds_fit(std::size_t(capped), dim, horizon + 2 * h, h, bytes_per_bond_explicit);
}

// A structured mesh or a Gmsh file, in `dim` = 2 (triangles) or 3 (tetrahedra).
MeshSpec parse_mesh(DeckMap& disc, const std::filesystem::path& base_dir, double horizon, int dim) {
  MeshSpec ms;
  auto m = disc.map("mesh");
  if (m.has("structured") == m.has("file")) m.fail("structured", "give either structured: {min, max, cells} or file: <.msh or .geo>");
  try {
    if (auto st = m.optional_map("structured")) {
      ms.lo = point(*st, "min", dim);
      ms.hi = point(*st, "max", dim);
      for (int k = 0; k < dim; ++k)
        if (!(ms.hi[k] > ms.lo[k])) st->fail("max", fmt::format("must exceed min in every component (component {})", k));
      const auto cells = st->numbers("cells", std::size_t(dim), std::size_t(dim), Range::between(1, 1e5));
      ms.nx = int(cells[0]);
      ms.ny = int(cells[1]);
      ms.nz = dim == 3 ? int(cells[2]) : 0;
      const double nodes = double(ms.nx + 1) * double(ms.ny + 1) * double(ms.nz + 1);
      if (nodes > 1e9) st->fail("cells", "more than 1e9 nodes");
      if (dim == 2) ms.lower_left_diagonal = st->choice("diagonal", {"lower_left", "lower_right"}, "lower_left") == "lower_left";
      else if (st->has("diagonal")) st->fail("diagonal", "2D only: a 3D cell is cut into six tetrahedra around its main diagonal");
      st->finish();
      double h = std::min((ms.hi[0] - ms.lo[0]) / ms.nx, (ms.hi[1] - ms.lo[1]) / ms.ny);
      if (dim == 3) h = std::min(h, (ms.hi[2] - ms.lo[2]) / ms.nz);
      try {
        require_mesh_fits(nodes, dim, h, horizon);
      } catch (const DeckError& e) {
        st->fail("cells", fmt::format("= [{}, {}{}]: {}", ms.nx, ms.ny, dim == 3 ? fmt::format(", {}", ms.nz) : "", e.what()));
      }
      // On N ranks every rank makes only its part.
      if (!make_structured_in_parts(ms, dim, horizon)) make_mesh_once(ms, [&] {
        if (dim == 3) ms.tets = std::make_shared<const TetMesh>(structured_tetrahedra(ms.lo, ms.hi, ms.nx, ms.ny, ms.nz));
        else ms.mesh = std::make_shared<const TriangleMesh>(structured_triangles(ms.lo, ms.hi, ms.nx, ms.ny, ms.lower_left_diagonal));
      });
    } else {
      const auto name = m.text("file");
      ms.file = std::filesystem::path(name).is_absolute() || base_dir.empty() ? std::filesystem::path(name) : base_dir / name;
      const bool geo = ms.file.extension() == ".geo";
      if (!geo && m.has("size")) m.fail("size", "only a .geo file is meshed here; a .msh file has its own elements");
      ms.size = m.number("size", Range::positive(), 0.0);
      if (ms.file.extension() != ".geo" && ms.file.extension() != ".msh")
        m.fail("file", fmt::format("= '{}': expected a Gmsh .msh or .geo file", shown(name)));
      const auto estimate = [&](double nodes, double h) {
        try {
          require_mesh_fits(nodes, dim, h, horizon);
        } catch (const DeckError& e) {
          // invalid_argument: read_gmsh_mesh passes it on as the reason, and the caller names the key.
          throw std::invalid_argument(fmt::format("meshing it{} would make about {:.3g} nodes: {}",
                                      ms.size > 0 ? fmt::format(" at size = {:g} m", ms.size) : "", nodes, e.what()));
        }
      };
      ms.spatial_order = m.choice("node_order", {"spatial", "file"}, "spatial") == "spatial";
      // On N ranks a .msh in spatial order is read by every rank, each keeping its part.
      if (geo || !ms.spatial_order || !read_mesh_in_parts(ms, dim, horizon)) make_mesh_once(ms, [&] {
        const auto ordered = [&](auto mesh) {
          if (ms.spatial_order) order_nodes_spatially(mesh);
          return mesh;
        };
        if (dim == 3) ms.tets = std::make_shared<const TetMesh>(ordered(read_gmsh_tet_mesh(ms.file, ms.size, estimate)));
        else ms.mesh = std::make_shared<const TriangleMesh>(ordered(read_gmsh_mesh(ms.file, ms.size, estimate)));
      });
    }
    if (ms.tets) validate(*ms.tets);
    else if (ms.mesh) validate(*ms.mesh);
  } catch (const std::invalid_argument& e) {
    throw DeckError(fmt::format("{}: {}", m.child_path(m.has("file") ? "file" : "structured"), e.what()));
  }
  m.finish();
  return ms;
}

// Output files are <name>_<step>.vtu and so on inside the output directory: the name must be
// a plain file stem, or outputs would land elsewhere (a '/') or be hidden (an empty name).
std::string parse_name(DeckMap& top) {
  const auto name = top.text("name", "run");
  require_file_name(top, "name", name);
  return name;
}

// Problem::content_hash: FNV-1a over a canonical serialisation of the YAML tree (map keys
// sorted, every item tagged with its kind and length), skipping name, output and solver.end_time.
class ContentHash {
 public:
  std::uint64_t of_deck(const YAML::Node& root) {
    add(root, "");
    return h_;
  }
  // And what a deck means without saying it, where that changed: a checkpoint written before
  // then holds another numbering of the same points.
  std::uint64_t and_implicit(const std::string& what) {
    token('I', what);
    return h_;
  }

 private:
  void bytes(const std::string& s) {
    for (unsigned char c : s) h_ = (h_ ^ c) * 0x100000001b3ull;
  }
  void token(char kind, const std::string& text) { bytes(fmt::format("{}{}:{}", kind, text.size(), text)); }
  void add(const YAML::Node& n, const std::string& path) {
    if (n.IsScalar()) return token('S', n.Scalar());
    if (n.IsSequence()) {
      token('L', std::to_string(n.size()));
      for (const auto& item : n) add(item, path + "[]");
      return;
    }
    if (!n.IsMap()) return token('N', "");
    std::map<std::string, YAML::Node> sorted;  // child path -> value
    for (const auto& kv : n) {
      const auto key = kv.first.as<std::string>();
      const auto child = path.empty() ? key : path + "." + key;
      if (child != "name" && child != "output" && child != "solver.end_time") sorted.emplace(child, kv.second);
    }
    token('M', std::to_string(sorted.size()));
    for (const auto& [child, value] : sorted) {
      token('K', child);
      add(value, child);
    }
  }
  std::uint64_t h_ = 0xcbf29ce484222325ull;
};

// Keys that only some solvers read are errors under the others, naming the solver.
// static.* for the OSB solve on a rectangle (seed 004).
void parse_osb_static(DeckMap& st, Problem& p) {
  auto& o = p.statics.osb;
  const bool corrected = p.boundary_method == BoundaryMethodKind::fictitious_taylor;
  o.taylor_order = int(st.integer("taylor_order", Range::between(1, 3), 1));
  if (!corrected && st.has("taylor_order")) st.fail("taylor_order", "only boundary_method = 'fictitious_taylor' extrapolates");
  if (auto edges = st.optional_map("edges")) {
    const char* names[] = {"left", "right", "bottom", "top"};
    for (int e = 0; e < 4; ++e) {
      auto em = edges->optional_map(names[e]);
      if (!em) continue;
      const char* comps[] = {"x", "y"};
      for (int c = 0; c < 2; ++c) {
        auto cm = em->optional_map(comps[c]);
        if (!cm) continue;
        auto& cond = o.conditions.edge[std::size_t(e)][std::size_t(c)];
        if (cm->has("displacement") == cm->has("traction"))
          throw DeckError(fmt::format("{}: give exactly one of displacement [m] or traction [Pa]", cm->path()));
        cond.displacement = cm->has("displacement");
        cond.value = cm->number(cond.displacement ? "displacement" : "traction", {});
        cm->finish();
      }
      em->finish();
    }
    edges->finish();
  }
  if (auto bf = st.optional_map("body_force")) {
    for (const char* kind : {"uniform", "cosine"})
      if (bf->has(kind)) {
        if (o.body_force != "none") bf->fail(kind, "give one of uniform or cosine");
        o.body_force = kind;
        const auto v = bf->numbers(kind, 2, 2);
        o.body_force_value = {v[0], v[1], 0};
      }
    if (o.body_force == "none") throw DeckError(fmt::format("{}: give uniform: [bx, by] or cosine: [bx, by] [N/m^3]", bf->path()));
    bf->finish();
  }
  if (auto ref = st.optional_map("reference")) {
    o.affine_reference = true;
    const auto d = ref->numbers("displacement", 2, 2);
    o.reference_displacement = {d[0], d[1]};
    if (!ref->has("gradient")) ref->fail("gradient", "is required: [[du/dx, du/dy], [dv/dx, dv/dy]]");
    const auto g = ref->raw("gradient");
    if (!g.IsSequence() || g.size() != 2 || !g[0].IsSequence() || !g[1].IsSequence() || g[0].size() != 2 || g[1].size() != 2)
      ref->fail("gradient", "must be [[du/dx, du/dy], [dv/dx, dv/dy]]");
    for (int a = 0; a < 2; ++a)
      for (int b = 0; b < 2; ++b)
        o.reference_gradient[std::size_t(2 * a + b)] = parse_number(g[a][b], fmt::format("{}[{}][{}]", ref->child_path("gradient"), a, b), {});
    ref->finish();
  }
  if (auto fr = st.optional_map("fracture")) {
    if (!(p.material.fracture_energy > 0)) fr->fail("bonds_per_solve", "fracture needs material.fracture_energy > 0 [J/m^2]");
    o.bonds_per_solve = int(fr->integer("bonds_per_solve", Range::between(1, 1e6), 4));
    o.max_solves = std::size_t(fr->integer("max_solves", Range::between(1, 1e9), 100000));
    fr->finish();
  } else if (p.material.fracture_energy > 0) {
    st.fail("fracture", "is needed when material.fracture_energy > 0 (the sequentially linear settings); give fracture: {}");
  }
}

void reject_for(DeckMap& m, const char* key, const char* solver, const char* why) {
  if (m.has(key)) m.fail(key, fmt::format("not used by solver.type = '{}' ({})", solver, why));
}
void reject_for_static(DeckMap& m, const char* key, const char* why) { reject_for(m, key, "static", why); }

}  // namespace

Problem parse_deck(const std::string& text, const std::string& source, const std::filesystem::path& base_dir) {
  if (text.size() > max_deck_bytes)
    throw DeckError(fmt::format("{}: the deck is {} bytes; decks are at most {} bytes", source, text.size(), max_deck_bytes));
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw DeckError(fmt::format("{}: malformed YAML at line {}, column {}: {}", source, e.mark.line + 1, e.mark.column + 1, e.msg));
  }
  if (!root || root.IsNull()) throw DeckError(fmt::format("{}: the deck is empty", source));
  try {
    DeckMap top(root, "");
    Problem p;
    p.name = parse_name(top);
    p.dim = int(top.integer("dimension", Range::between(1, 3), 2));

    // The solver and the model decide which keys the rest of the deck may use.
    auto sol = top.map("solver");
    const auto& solvers = seam_names(Seam::solver);
    const auto stype = sol.choice("type", solvers, "explicit");
    p.solver_kind = SolverKind(index_of(solvers, stype));
    const bool is_static = p.solver_kind == SolverKind::static_linear;
    const bool is_quasi_static = p.solver_kind == SolverKind::quasi_static;
    auto mat = top.map("material");
    const auto& models = seam_names(Seam::model);
    p.material.model = ModelKind(index_of(models, mat.choice("model", models, "pmb")));
    require_supported_pair(Seam::solver, std::size_t(p.solver_kind), Seam::model, std::size_t(p.material.model));
    if (p.dim == 1 && p.material.model != ModelKind::rnp)
      top.fail("dimension", fmt::format("= 1: only material.model: rnp has a 1D bar (material.model = '{}')", models[std::size_t(p.material.model)]));

    auto disc = top.map("discretization");
    const auto& kinds = seam_names(Seam::discretization);
    p.discretization_kind = DiscretizationKind(index_of(kinds, disc.choice("type", kinds, "lattice")));
    const bool on_mesh = p.discretization_kind == DiscretizationKind::mesh;
    if (on_mesh) {
      require_supported_pair(Seam::discretization, std::size_t(p.discretization_kind), Seam::solver, std::size_t(p.solver_kind));
      require_supported_pair(Seam::discretization, std::size_t(p.discretization_kind), Seam::model, std::size_t(p.material.model));
      for (const char* key : {"spacing", "horizon_factor", "perturbation", "seed"})
        if (disc.has(key)) disc.fail(key, "not used by discretization.type = 'mesh' (the mesh sets the nodes; give horizon in metres)");
      // The horizon first: the mesh's memory estimate, made before it is meshed, needs it.
      p.horizon = disc.number("horizon", Range::positive());
      if (p.dim == 1) top.fail("dimension", "= 1: a mesh is 2D (triangles) or 3D (tetrahedra)");
      p.mesh = parse_mesh(disc, base_dir, p.horizon, p.dim);
      p.lattice.spacing = p.mesh.mean_edge();
    } else {
      if (disc.has("mesh")) disc.fail("mesh", "only discretization.type = 'mesh' reads a mesh");
      if (disc.has("quadrature_order")) disc.fail("quadrature_order", "only discretization.quadrature = 'element' (a mesh) uses a triangle rule");
      p.lattice.spacing = disc.number("spacing", Range::positive());
      if (disc.has("horizon") && disc.has("horizon_factor")) disc.fail("horizon", "give either horizon or horizon_factor, not both");
      if (disc.has("horizon")) p.horizon = disc.number("horizon", Range::positive());
      else p.horizon = disc.number("horizon_factor", Range::positive(), 4.0) * p.lattice.spacing;
      if (p.horizon < p.lattice.spacing)
        disc.fail(disc.has("horizon") ? "horizon" : "horizon_factor",
                  fmt::format("horizon {:g} m is smaller than the spacing {:g} m: must be >= spacing", p.horizon, p.lattice.spacing));
      p.lattice.perturbation = disc.number("perturbation", Range{0, 0.5, false, true}, 0.0);
      p.lattice.seed = std::uint64_t(disc.integer("seed", Range::between(0, 9e15), 1));
    }
    const auto& quadratures = seam_names(Seam::quadrature);
    const auto default_quad = on_mesh ? default_choice(Seam::discretization, std::size_t(p.discretization_kind), Seam::quadrature)
                                      : default_choice(Seam::model, std::size_t(p.material.model), Seam::quadrature);
    const auto quad = disc.choice("quadrature", quadratures, quadratures[default_quad]);
    p.quadrature_kind = QuadratureKind(index_of(quadratures, quad));
    require_supported_pair(Seam::model, std::size_t(p.material.model), Seam::quadrature, std::size_t(p.quadrature_kind));
    require_supported_pair(Seam::discretization, std::size_t(p.discretization_kind), Seam::quadrature, std::size_t(p.quadrature_kind));
    p.partial_volume = p.quadrature_kind == QuadratureKind::partial_volume;
    p.material.quadrature = p.quadrature_kind == QuadratureKind::gmls ? QuadratureRule::gmls : QuadratureRule::volume;
    const auto layout = disc.choice("bonds", {"auto", "list", "compact", "stencil"}, "auto");
    p.bond_layout = layout == "list"      ? BondLayout::list
                    : layout == "compact" ? BondLayout::compact
                    : layout == "stencil" ? BondLayout::stencil
                                          : BondLayout::automatic;
    if (p.bond_layout == BondLayout::compact &&
        ((p.material.model != ModelKind::rnp && p.material.model != ModelKind::lps) || p.solver_kind != SolverKind::explicit_dynamics))
      disc.fail("bonds", fmt::format("= 'compact' (a list that recomputes xi and |xi|) runs material.model = 'rnp' or 'lps' with solver.type = "
                                     "'explicit' only (got '{}' with '{}'); allowed here: auto, list",
                                     models[std::size_t(p.material.model)], stype));
    if (p.bond_layout == BondLayout::stencil) {
      if (on_mesh) disc.fail("bonds", "= 'stencil': a mesh's nodes are not a lattice; allowed here: auto, list");
      if (p.material.model != ModelKind::pmb || p.solver_kind != SolverKind::explicit_dynamics)
        disc.fail("bonds", fmt::format("= 'stencil' runs material.model = 'pmb' with solver.type = 'explicit' only (got '{}' with '{}')",
                                       models[std::size_t(p.material.model)], stype));
      if (p.lattice.perturbation > 0)
        disc.fail("bonds", fmt::format("= 'stencil' needs an unperturbed lattice (discretization.perturbation = {:g}; allowed 0)", p.lattice.perturbation));
      if (p.quadrature_kind != QuadratureKind::volume && p.quadrature_kind != QuadratureKind::partial_volume)
        disc.fail("bonds", fmt::format("= 'stencil' needs quadrature volume or partial_volume (got '{}')", quad));
    }
    // PMB's lean list runs in single precision unless asked; RNP's and LPS's only when asked (explicit).
    const bool rnp = p.material.model == ModelKind::rnp, lps = p.material.model == ModelKind::lps;
    const bool pmb = p.material.model == ModelKind::pmb;
    p.list_precision = disc.choice("list_precision", {"single", "double"}, pmb ? "single" : "double") == "double" ? ListPrecision::double_precision
                                                                                                                : ListPrecision::single;
    if (!pmb && p.list_precision == ListPrecision::single) {
      if (!rnp && !lps)
        disc.fail("list_precision", fmt::format("= 'single' runs material.model = 'pmb', 'rnp' or 'lps' (got '{}'); allowed here: double",
                                                models[std::size_t(p.material.model)]));
      if (p.solver_kind != SolverKind::explicit_dynamics)
        disc.fail("list_precision", fmt::format("= 'single' runs material.model = '{}' with solver.type = 'explicit' only (got '{}': "
                                                "{}); allowed here: double",
                                                models[std::size_t(p.material.model)], stype,
                                                rnp ? "Newton needs the double residual" : "implicit solvers need the double operator"));
      if (rnp && p.bond_layout == BondLayout::compact)
        disc.fail("list_precision", "= 'single' with bonds = 'compact': RNP in single precision keeps a lean list (9 bytes per bond), "
                                    "smaller than compact's 13; set bonds: list (or auto), or list_precision: double");
    }
    if (on_mesh) p.mesh.quadrature_order = int(disc.integer("quadrature_order", Range::between(1, 5), 2));
    if (on_mesh && p.dim == 2 && p.mesh.quadrature_order == 3)
      disc.fail("quadrature_order", "= 3: allowed 1, 2, 4, 5 (degrees of the symmetric triangle rules)");
    if (on_mesh && p.dim == 3 && (p.mesh.quadrature_order == 3 || p.mesh.quadrature_order == 4))
      disc.fail("quadrature_order", fmt::format("= {}: allowed 1, 2, 5 (degrees of the tetrahedron rules)", p.mesh.quadrature_order));
    disc.finish();

    const auto& methods = seam_names(Seam::boundary_method);
    std::size_t default_method = default_choice(Seam::solver, std::size_t(p.solver_kind), Seam::boundary_method);
    for (const auto& c : supported_combinations)
      if (c.solver == p.solver_kind && c.model == p.material.model) {
        default_method = std::size_t(c.boundary_method);
        break;
      }
    const auto method = top.choice("boundary_method", methods, methods[default_method]);
    p.boundary_method = BoundaryMethodKind(index_of(methods, method));
    require_supported_pair(Seam::solver, std::size_t(p.solver_kind), Seam::boundary_method, std::size_t(p.boundary_method));
    require_supported_pair(Seam::model, std::size_t(p.material.model), Seam::boundary_method, std::size_t(p.boundary_method));

    auto geo = on_mesh && !top.has("geometry") ? DeckMap(YAML::Node(YAML::NodeType::Map), "geometry") : top.map("geometry");
    ShapeContext ctx{p.dim, p.lattice.spacing, {}, false};
    if (on_mesh) {
      if (geo.has("body")) geo.fail("body", "not used by discretization.type = 'mesh' (the mesh is the body)");
      const Aabb b = p.mesh.bounds();
      p.body = p.dim == 3 ? box(b.lo, b.hi) : rectangle(b.lo, b.hi);  // the mesh's bounding box: what layers and bounds refer to
    } else {
      p.body = required_shape(geo, "body", ctx);
    }
    const auto cracks = geo.list("cracks");
    for (std::size_t k = 0; k < cracks.size(); ++k) {
      const std::string cp = fmt::format("geometry.cracks[{}]", k);
      const auto& c = cracks[k];
      if (!c.IsMap() || c.size() != 1) throw DeckError(cp + ": a crack is {segment: {from, to}} (2D) or {rectangle: {origin, edge1, edge2}} (3D)");
      const auto kind = c.begin()->first.as<std::string>();
      DeckMap m(c.begin()->second, cp + "." + kind);
      if (kind == "segment" && p.dim == 2) p.cracks.push_back(CrackSegment{point(m, "from", 2), point(m, "to", 2)});
      else if (kind == "rectangle" && p.dim == 3)
        p.cracks.push_back(CrackRectangle{point(m, "origin", 3), point(m, "edge1", 3), point(m, "edge2", 3)});
      else throw DeckError(fmt::format("{}: '{}' cracks are not allowed in {}D (2D: segment, 3D: rectangle)", cp, kind, p.dim));
      m.finish();
    }
    if (is_static) reject_for_static(geo, "precrack_damage", "it reports no damage");
    p.precrack_damage = geo.flag("precrack_damage", true);
    geo.finish();
    ctx.body = p.body.bounds();
    ctx.allow_layers = true;
    ctx.groups = on_mesh ? &p.mesh.groups() : nullptr;

    const auto kin = mat.choice("kinematics",
                                p.dim == 2   ? std::vector<std::string>{"plane_stress", "plane_strain"}
                                : p.dim == 1 ? std::vector<std::string>{"bar"}
                                             : std::vector<std::string>{"solid"},
                                p.dim == 2 ? "plane_stress" : p.dim == 1 ? "bar" : "solid");
    p.material.kinematics = kin == "plane_stress"   ? Kinematics::plane_stress
                            : kin == "plane_strain" ? Kinematics::plane_strain
                            : kin == "bar"          ? Kinematics::bar
                                                    : Kinematics::solid;
    if (p.material.model == ModelKind::rnp) {
      // Either the paper's constants or the engineering ones, not both.
      const bool given = mat.has("C") || mat.has("beta");
      if (given && (mat.has("youngs_modulus") || mat.has("fracture_energy")))
        mat.fail("C", "give either C and beta, or youngs_modulus and fracture_energy, not both");
      if (given) {
        p.material.rnp_C = mat.number("C", Range::positive());
        p.material.rnp_beta = mat.number("beta", Range::positive());
      } else {
        p.material.youngs_modulus = mat.number("youngs_modulus", Range::positive());
        p.material.fracture_energy = mat.number("fracture_energy", Range::positive());
        p.material.lipton_calibration = mat.choice("calibration", {"matched", "lipton"}, "matched") == "lipton";
        if (p.material.lipton_calibration && p.dim != 2)
          mat.fail("calibration", fmt::format("= 'lipton': eq. (83) of seed 003 is the 2D form (dimension = {} here)", p.dim));
      }
      p.material.break_factor = mat.number("break_factor", Range::non_negative(), 0.0);
      p.material.influence = mat.choice("influence", {"constant", "linear"}, "constant") == "linear" ? RnpInfluence::linear : RnpInfluence::constant;
      if (is_quasi_static) reject_for(mat, "density", "quasi_static", "it has no inertia");
      p.material.density = is_quasi_static ? 1.0 : mat.number("density", Range::positive());
    } else if (p.material.model == ModelKind::pmb) {
      p.material.youngs_modulus = mat.number("youngs_modulus", Range::positive());
      p.material.density = mat.number("density", Range::positive());
      p.material.fracture_energy = mat.number("fracture_energy", Range::positive());
    } else if (p.material.model == ModelKind::osb) {
      if (p.dim != 2) mat.fail("model", "= 'osb': only the 2D OSB model is implemented (dimension must be 2)");
      p.material.youngs_modulus = mat.number("youngs_modulus", Range::positive());
      p.material.poisson_ratio = mat.number("poisson_ratio", Range{-1, 0.5, true, true});
      if (is_static) reject_for_static(mat, "density", "a static solve has no inertia");
      p.material.density = is_static ? 1.0 : mat.number("density", Range::positive());
      // G0 > 0 turns fracture on: s_c = sqrt(4 G0 / (9 E delta)), seed 004 eq. (71).
      p.material.fracture_energy = mat.number("fracture_energy", Range::non_negative(), 0.0);
    } else {
      if (p.dim != 2 && p.dim != 3) mat.fail("model", fmt::format("= 'lps': the model is 2D or 3D (dimension = {} here)", p.dim));
      p.material.youngs_modulus = mat.number("youngs_modulus", Range::positive());
      if (is_static) reject_for_static(mat, "density", "a static solve has no inertia");
      if (is_static) reject_for_static(mat, "fracture_energy", "nothing breaks in a static solve");
      p.material.density = is_static ? 1.0 : mat.number("density", Range::positive());
      // G0 > 0 turns bond breaking on, s0 of seed 000 eq. (6.3) (3D: its ball form, Lps::critical_stretch).
      p.material.fracture_energy = is_static ? 0.0 : mat.number("fracture_energy", Range::non_negative(), 0.0);
      p.material.poisson_ratio = mat.number("poisson_ratio", Range{-1, 0.5, true, true});
      const auto inc = mat.list("inclusions");
      for (std::size_t k = 0; k < inc.size(); ++k) {
        DeckMap m(inc[k], fmt::format("material.inclusions[{}]", k));
        InclusionSpec in;
        in.region = required_shape(m, "region", ctx);
        in.youngs_modulus = m.number("youngs_modulus", Range::positive());
        in.poisson_ratio = m.number("poisson_ratio", Range{-1, 0.5, true, true});
        m.finish();
        p.inclusions.push_back(std::move(in));
      }
    }
    mat.finish();

    if (is_static) {
      reject_for_static(top, "no_fail", "nothing breaks in a static solve");
      reject_for_static(top, "boundaries", "its loads are static.reference and static.neumann");
    }
    const auto nf = top.list("no_fail");
    for (std::size_t k = 0; k < nf.size(); ++k) p.no_fail.push_back(parse_shape(nf[k], fmt::format("no_fail[{}]", k), ctx));
    const auto bcs = top.list("boundaries");
    for (std::size_t k = 0; k < bcs.size(); ++k)
      p.boundaries.push_back(parse_boundary(DeckMap(bcs[k], fmt::format("boundaries[{}]", k)), ctx, k, is_quasi_static,
                                           p.boundary_method == BoundaryMethodKind::collar_traction));

    if (is_quasi_static) {
      auto& q = p.quasi_static.options;
      q.steps = std::size_t(sol.integer("steps", Range::between(1, 1e7), 10));
      q.tolerance = sol.number("tolerance", Range{0, 1, true, false}, 1e-10);
      q.max_iterations = int(sol.integer("max_iterations", Range::between(1, 10000), 15));
      q.line_search = sol.flag("line_search", true);
      q.min_increment = sol.number("min_increment", Range{0, 1, true, true}, 1e-4);
      const auto ls = sol.choice("linear_solver", {"auto", "cholmod", "umfpack", "cg", "petsc"}, "auto");
      q.linear_solver = ls == "cholmod" ? QsLinearSolver::cholmod : ls == "umfpack" ? QsLinearSolver::umfpack
                        : ls == "cg"    ? QsLinearSolver::cg : ls == "petsc" ? QsLinearSolver::petsc : QsLinearSolver::automatic;
      if (sol.has("petsc_options")) {
        if (q.linear_solver != QsLinearSolver::petsc) sol.fail("petsc_options", fmt::format("needs linear_solver: petsc (it is '{}')", ls));
        q.petsc.options = sol.text("petsc_options");
      }
      q.nonlinear = sol.choice("nonlinear", {"newton", "ceres"}, "newton") == "ceres" ? QsNonlinear::ceres : QsNonlinear::newton;
      q.tangent = sol.choice("tangent", {"analytic", "finite_difference"}, "analytic") == "finite_difference" ? QsTangent::finite_difference
                                                                                                          : QsTangent::analytic;
      q.control = sol.choice("control", {"load", "arc_length"}, "load") == "arc_length" ? QsControl::arc_length : QsControl::load;
      if (q.control == QsControl::arc_length && q.nonlinear == QsNonlinear::ceres)
        sol.fail("control", "= 'arc_length' corrects the load factor with Newton's iterations; it needs nonlinear: newton (it is 'ceres')");
      for (const char* key : {"end_time", "dt", "safety", "scheme"})
        if (sol.has(key)) sol.fail(key, "not used by solver.type = 'quasi_static' (its steps are load steps: solver.steps)");
    } else if (is_static) {
      // OSB's saddle-point system defaults to one process's LU (on N ranks: MUMPS through PETSc);
      // LPS solves on PETSc.
      const bool osb = p.material.model == ModelKind::osb;
      p.statics.linear_solver_named = sol.has("linear_solver");
      const auto ls = osb ? sol.choice("linear_solver", {"umfpack", "sparse_lu", "petsc"}, "umfpack")
                          : sol.choice("linear_solver", {"petsc", "umfpack", "sparse_lu", "bicgstab"}, "petsc");
      p.statics.linear_solver = ls == "petsc"       ? LinearSolver::petsc
                                : ls == "umfpack"   ? LinearSolver::umfpack
                                : ls == "sparse_lu" ? LinearSolver::sparse_lu
                                                    : LinearSolver::bicgstab_ilut;
      if (sol.has("petsc_options")) {
        if (p.statics.linear_solver != LinearSolver::petsc) sol.fail("petsc_options", fmt::format("needs linear_solver: petsc (it is '{}')", ls));
        p.statics.petsc_options = sol.text("petsc_options");
      }
      for (const char* key : {"end_time", "dt", "safety", "scheme"})
        if (sol.has(key)) sol.fail(key, "not used by solver.type = 'static' (it has no time steps)");
    } else if (p.solver_kind == SolverKind::newmark) {
      for (const char* key : {"linear_solver", "steps", "line_search", "min_increment", "nonlinear", "tangent", "control", "safety", "scheme"})
        if (sol.has(key)) sol.fail(key, "not used by solver.type = 'newmark'");
      auto& nm = p.newmark;
      nm.end_time = p.solver.end_time = sol.number("end_time", Range::positive());
      nm.dt = p.solver.dt = sol.number("dt", Range::positive());
      if (!(nm.end_time / nm.dt <= 1e9)) sol.fail("dt", fmt::format("= {:g} s gives {:.3g} steps to end_time; at most 1e9", nm.dt, nm.end_time / nm.dt));
      nm.tolerance = sol.number("tolerance", Range{0, 1, true, false}, 1e-8);
      nm.max_iterations = int(sol.integer("max_iterations", Range::between(1, 100000), 500));
      nm.max_sub_iterations = int(sol.integer("max_sub_iterations", Range::between(1, 100000), 200));
    } else {
      for (const char* key : {"linear_solver", "steps", "tolerance", "max_iterations", "line_search", "min_increment", "nonlinear", "tangent", "control", "max_sub_iterations"})
        if (sol.has(key)) sol.fail(key, "not used by solver.type = 'explicit'");
      p.solver.end_time = sol.number("end_time", Range::positive());
      p.solver.dt = sol.number("dt", Range::non_negative(), 0.0);
      p.solver.safety = sol.number("safety", Range{0, 1, true, false}, 0.8);
      p.solver.scheme = sol.choice("scheme", {"velocity_verlet", "central_difference"}, "velocity_verlet") == "central_difference"
                            ? ExplicitScheme::central_difference
                            : ExplicitScheme::velocity_verlet;
    }
    sol.finish();

    if (!is_static && top.has("static")) top.fail("static", fmt::format("not used by solver.type = '{}' (only by 'static')", stype));
    if (is_static && p.material.model == ModelKind::osb) {
      auto st = top.has("static") ? top.map("static") : DeckMap(YAML::Node(YAML::NodeType::Map), "static");
      parse_osb_static(st, p);
      st.finish();
    } else if (is_static) {
      auto st = top.map("static");
      auto ref = st.map("reference");
      auto& r = p.statics.reference;
      r.type = ref.choice("type", {"linear_patch", "manufactured_sine", "kirsch_hole", "hollow_disk", "circular_inclusion", "spherical_inclusion"});
      if (p.dim == 3 && r.type != "linear_patch" && r.type != "manufactured_sine" && r.type != "spherical_inclusion")
        ref.fail("type", fmt::format("= '{}' is a 2D solution; 3D decks have linear_patch, manufactured_sine and spherical_inclusion", r.type));
      if (p.dim != 3 && r.type == "spherical_inclusion")
        ref.fail("type", "= 'spherical_inclusion' is a 3D solution; 2D decks have circular_inclusion");
      const bool inclusion = r.type == "circular_inclusion" || r.type == "spherical_inclusion";
      if (r.type == "manufactured_sine") r.A = ref.number("A", Range::positive(), 0.4);
      if (r.type == "kirsch_hole" || inclusion) r.radius = ref.number("radius", Range::positive());
      if (r.type == "kirsch_hole") r.sigma0 = ref.number("sigma0", {}, 1.0);
      if (r.type == "hollow_disk") {
        r.inner_radius = ref.number("inner_radius", Range::positive());
        r.outer_radius = ref.number("outer_radius", Range{r.inner_radius, 1e300, true, false});
        r.pressure = ref.number("pressure", {}, 0.1);
      }
      if (inclusion) {
        r.inclusion_stress = ref.number("inclusion_stress", {}, 1.0);
        if (p.inclusions.size() != 1) ref.fail("type", fmt::format("= '{}' needs exactly one material.inclusions entry", r.type));
      }
      ref.finish();
      const auto neu = st.list("neumann");
      for (std::size_t k = 0; k < neu.size(); ++k) {
        DeckMap m(neu[k], fmt::format("static.neumann[{}]", k));
        NeumannSpec nspec;
        nspec.region = required_shape(m, "region", ctx);
        if (m.has("traction")) {
          const auto t = m.raw("traction");
          if (t.IsScalar() && t.Scalar() == "reference") nspec.from_reference = true;
          else {
            nspec.from_reference = false;
            nspec.traction = point(m, "traction", p.dim);
          }
        }
        nspec.at_projection = m.choice("traction_at", {"projection", "point"}, "projection") == "projection";
        nspec.exact_normal = m.choice("normal", {"numerical", "exact"}, "numerical") == "exact";
        // (4.6) needs x-bar and its normal: only shapes that know their surface can give them.
        const bool needs_projection = (nspec.from_reference && nspec.at_projection) || nspec.exact_normal;
        if (needs_projection && !nspec.region.projects())
          m.fail("region", fmt::format("has no surface projection (known for rectangle, box, disk, sphere and their unions), but {} needs one; "
                                       "use traction_at: point with normal: numerical",
                                       nspec.exact_normal ? "normal: exact" : "traction_at: projection"));
        m.finish();
        p.statics.neumann.push_back(std::move(nspec));
      }
      p.statics.band_factor = st.number("band_factor", Range::between(1, 10), 2.0);
      st.finish();
    }

    if (top.has("output")) p.output = parse_output(top.map("output"), p.dim, p.solver_kind, p.material.model == ModelKind::osb, p.material.model != ModelKind::lps);
    if (p.output.checkpoint_file.empty()) p.output.checkpoint_file = p.name + ".h5";
    if (const auto at = p.output.png_slice_at) {
      const auto box = p.body.bounds();
      const auto k = std::size_t(p.output.png_axis);
      if (!(*at >= box.lo[k] && *at <= box.hi[k]))
        throw DeckError(fmt::format("output.png.slice_at = {:g} m: outside the body, which spans [{:g}, {:g}] m along {}", *at, box.lo[k], box.hi[k],
                                    "xyz"[k]));
    }
    if (p.bond_layout == BondLayout::stencil && p.output.wants_stress())
      throw DeckError("discretization.bonds = 'stencil' stores no per-bond pair forces, so output.vtu.stress and stress PNG fields need "
                      "discretization.bonds: list (or auto)");
    top.finish();
    ContentHash hash;
    p.content_hash = hash.of_deck(root);
    // Since wave 3 a mesh file's nodes are renumbered by default (MeshSpec::spatial_order).
    if (p.discretization_kind == DiscretizationKind::mesh && !p.mesh.file.empty() && p.mesh.spatial_order)
      p.content_hash = hash.and_implicit("discretization.mesh.node_order: spatial");
    return p;
  } catch (const DeckError& e) {
    throw DeckError(fmt::format("{}: {}", source, e.what()));
  } catch (const YAML::Exception& e) {
    throw DeckError(fmt::format("{}: invalid value at line {}: {}", source, e.mark.line + 1, e.msg));
  }
}

Problem read_deck(const std::filesystem::path& file) {
  std::error_code ec;
  if (std::filesystem::is_directory(file, ec))
    throw DeckError(fmt::format("{}: is a directory, not a deck file", file.string()));
  std::ifstream in(file, std::ios::binary);
  if (!in) throw DeckError(fmt::format("{}: cannot open deck file (missing or unreadable)", file.string()));
  // Read at most one byte past the limit, so a huge file is refused without loading it.
  std::string text(max_deck_bytes + 1, '\0');
  in.read(text.data(), std::streamsize(text.size()));
  text.resize(std::size_t(in.gcount()));
  if (text.size() > max_deck_bytes)
    throw DeckError(fmt::format("{}: the deck is larger than {} bytes; decks are at most that", file.string(), max_deck_bytes));
  return parse_deck(text, file.string(), file.parent_path());
}

}  // namespace peridot
