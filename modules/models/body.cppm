export module peridot.models:body;
import peridot.std;
export import peridot.discretization;

export namespace peridot {

// Lambdas overloaded on their argument type, for Body::visit_bonds.
template <class... F>
struct overloaded : F... {
  using F::operator()...;
};
template <class... F>
overloaded(F...) -> overloaded<F...>;

// A vector field over points, one array per component (z stays zero in 2D).
using VectorField = std::array<std::vector<double>, 3>;

inline VectorField zero_field(std::size_t n) { return {std::vector<double>(n), std::vector<double>(n), std::vector<double>(n)}; }

// The discretised solid: points, bonds, density and the points whose bonds never break.
// Its bonds are either a CSR list or, for lattice bodies on the stencil path, a Stencil (then
// `bonds` is empty).
struct Body {
  PointCloud points;
  BondList bonds;
  Stencil stencil;
  double density = 0;                   // rho [kg/m^3]
  std::vector<std::uint8_t> no_fail;    // 1: bonds touching this point never break

  std::size_t size() const { return points.size(); }
  bool on_stencil() const { return !stencil.empty(); }
  // The one branch on the bond layout. The layout is data of the body, chosen per deck when the
  // problem is composed, not a type parameter: templating bodies and models on it would double
  // every set-up alternative and solver instantiation. Code that differs by layout hands a
  // generic callable (or `overloaded` lambdas) here and overloads on Stencil / BondList.
  template <class F>
  decltype(auto) visit_bonds(F&& f) {
    if (on_stencil()) return f(stencil);
    return f(bonds);
  }
  template <class F>
  decltype(auto) visit_bonds(F&& f) const {
    if (on_stencil()) return f(stencil);
    return f(bonds);
  }
  std::size_t directed_bonds() const { return visit_bonds([](const auto& b) { return b.size(); }); }
  std::size_t bond_bytes() const { return visit_bonds([](const auto& b) { return b.bytes(); }); }
  // The fracture state of every bond, one byte each, whatever the layout: a stencil's state per
  // (point, offset), a list's intact flag per directed bond. Checkpoints and rank transfers
  // move these bytes without asking which layout holds them.
  std::span<std::uint8_t> bond_states() { return visit_bonds([](auto& b) { return b.states(); }); }
  std::span<const std::uint8_t> bond_states() const { return visit_bonds([](const auto& b) { return b.states(); }); }
  std::size_t broken_bonds() const { return visit_bonds([](const auto& b) { return b.broken(); }); }  // directed
  const char* layout_name() const { return visit_bonds([](const auto& b) { return b.name; }); }
  const char* layout_storage() const { return visit_bonds([](const auto& b) { return b.storage(); }); }
  int dim() const { return points.dim; }
};

// The strain energy of a body from its points' energies, as an exact sum: the same bits for any
// thread count, and on N ranks for the owned points' energies summed per rank and reduced.
inline double point_sum(const std::vector<double>& per_point) {
  ExactSum total;
  for (double e : per_point) total += e;
  return total.value();
}

// Evolving solution. Forces are densities [N/m^3] (2D: N/m^3 per unit thickness).
struct State {
  VectorField u, v, f;
  double time = 0;
  std::size_t step = 0;
  explicit State(std::size_t n = 0) : u(zero_field(n)), v(zero_field(n)), f(zero_field(n)) {}
};

// How one MPI rank's part of a body joins the others' sums. The part holds its owned points
// and the ghosts its forces read (two bonds deep for state-based models, with the rows of the
// nearer ones). Sums over points run over the owned points only, exactly, and `reduce` adds the
// ranks' exact sums, so every rank gets one rank's number. `exchange` refreshes the ghosts of a
// field from their owners before each operator application. Empty on one rank: every point is
// owned, and nothing travels.
struct BodyParts {
  std::span<const std::int64_t> owned;
  std::span<const std::int64_t> ids;  // each local point's global id, where a start vector needs it (empty: the local index)
  std::function<void(VectorField&)> exchange;
  std::function<void(ExactSum&)> reduce;

  bool parted() const { return !owned.empty() || reduce != nullptr; }
  void refresh(VectorField& x) const {
    if (exchange) exchange(x);
  }
};

// The sum over the part's owned points (of `points` points in all) of a_i . b_i, each point's
// product summed exactly: the same bits for any thread count and any cut of the points among
// ranks.
double owned_dot(const BodyParts& parts, const VectorField& a, const VectorField& b, std::size_t points, int dim);

// What a force evaluation reports.
struct ForceReport {
  // Directed bonds that broke in this evaluation: a pair counts twice. Counts are halved once,
  // by whoever reports bonds (broken directed bonds since t = 0, over 2), so a bond list whose
  // bond i -> j has no j -> i (mesh V_ij) reports the same on any number of ranks.
  std::size_t newly_broken_directed = 0;
};

// A force model: computes internal force densities from displacements, updates the bond
// mask for fracture, reports energy and its own stable time step. Models are templates
// the solver is instantiated on, so the per-bond work is inlined, never a virtual call.
template <class M>
concept ForceModel = requires(const M& m, Body& body, const Body& cbody, const VectorField& u, VectorField& f) {
  { m.forces(body, u, f) } -> std::same_as<ForceReport>;
  { m.strain_energy(cbody, u) } -> std::convertible_to<double>;
  { m.stable_time_step(cbody) } -> std::convertible_to<double>;
};

}  // namespace peridot

namespace peridot {

double owned_dot(const BodyParts& parts, const VectorField& a, const VectorField& b, std::size_t points, int dim) {
  const bool parted = parts.parted();
  const auto n = static_cast<std::int64_t>(parted ? parts.owned.size() : points);
  ExactSum total;
#pragma omp parallel
  {
    ExactSum mine;
#pragma omp for schedule(static) nowait
    for (std::int64_t j = 0; j < n; ++j) {
      const auto i = std::size_t(parted ? parts.owned[std::size_t(j)] : j);
      double ab = 0;
      for (int k = 0; k < dim; ++k) ab += a[std::size_t(k)][i] * b[std::size_t(k)][i];
      mine += ab;
    }
#pragma omp critical(peridot_owned_dot)
    total.add(mine);
  }
  if (parts.reduce) parts.reduce(total);
  return total.value();
}

}  // namespace peridot
