export module peridot.solvers:boundary;
import peridot.std;
import peridot.geometry;
import peridot.models;
import :time_function;

export namespace peridot {

enum class BoundaryKind {
  body_force,    // adds value * g(t) [N/m^3] to the force density (tractions as a layer force)
  displacement,  // u_k = value_k * g(t) [m] on the selected components
  velocity,      // v_k = value_k * g(t) [m/s] on the selected components
};

struct Boundary {
  std::string name;
  BoundaryKind kind = BoundaryKind::body_force;
  std::vector<std::int32_t> points;
  Vec3 value{0, 0, 0};
  std::array<bool, 3> components{true, true, true};  // kinematic kinds: which are prescribed
  TimeFunction history;
};

// Indices of the points inside a region, in increasing order.
std::vector<std::int32_t> select_points(const PointCloud& points, const Shape& region);

}  // namespace peridot

namespace peridot {

std::vector<std::int32_t> select_points(const PointCloud& pc, const Shape& region) {
  auto inside = std::views::iota(std::size_t{0}, pc.size()) |
                std::views::filter([&](std::size_t i) { return region.contains(pc.position(i)); }) |
                std::views::transform([](std::size_t i) { return std::int32_t(i); });
  std::vector<std::int32_t> out;
  std::ranges::copy(inside, std::back_inserter(out));
  return out;
}

}  // namespace peridot
