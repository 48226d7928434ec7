export module peridot.geometry:shapes;
import peridot.std;
import :vec;

namespace peridot {

// Nearest point on a shape's surface seen from outside it, and the unit normal there pointing
// into the shape (for an exterior Neumann region: the outward normal of the body).
export struct SurfacePoint {
  Vec3 point;
  Vec3 normal;
};

struct ShapeNode {
  virtual ~ShapeNode() = default;
  virtual bool contains(const Vec3& p) const = 0;
  virtual Aabb bounds() const = 0;
  virtual std::optional<SurfacePoint> project(const Vec3&) const { return std::nullopt; }
  virtual bool projects() const { return false; }  // project() is implemented for every outside point
  virtual bool is_box() const { return false; }    // an axis-aligned rectangle or box: contains() tests each axis alone
};

}  // namespace peridot

export namespace peridot {

// A solid region with value semantics. Only used while building point clouds and
// regions, never in a hot loop, so type erasure through a virtual node is fine.
class Shape {
 public:
  Shape() = default;
  explicit Shape(std::shared_ptr<const ShapeNode> node, int dim) : node_(std::move(node)), dim_(dim) {}
  bool contains(const Vec3& p) const { return node_ && node_->contains(p); }
  // For a point outside: the nearest surface point and the inward normal there. Known for
  // rectangles, boxes, disks, spheres and their unions; empty otherwise.
  std::optional<SurfacePoint> project(const Vec3& p) const { return node_ ? node_->project(p) : std::nullopt; }
  bool projects() const { return node_ && node_->projects(); }
  // An axis-aligned rectangle or box (its bounds): a point is inside when each coordinate is.
  bool is_box() const { return node_ && node_->is_box(); }
  Aabb bounds() const { return node_ ? node_->bounds() : Aabb{}; }
  int dimension() const { return dim_; }
  bool empty() const { return !node_; }

 private:
  std::shared_ptr<const ShapeNode> node_;
  int dim_ = 0;
};

// 1D: the segment [lo_x, hi_x] of a bar.
Shape interval(double lo, double hi);
Shape rectangle(Vec3 lo, Vec3 hi);
Shape box(Vec3 lo, Vec3 hi);
Shape disk(Vec3 center, double radius);
Shape sphere(Vec3 center, double radius);
Shape annulus(Vec3 center, double inner_radius, double outer_radius);
// Hollow cylinder with its axis along z, between z0 and z1.
Shape cylinder_shell(Vec3 center, double inner_radius, double outer_radius, double z0, double z1);
Shape polygon(std::vector<Vec3> vertices);
Shape unite(Shape a, Shape b);
Shape subtract(Shape a, Shape b);

}  // namespace peridot

namespace peridot {

namespace {

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument(what);
}

struct RectNode final : ShapeNode {
  Vec3 lo, hi;
  int dim;
  RectNode(Vec3 l, Vec3 h, int d) : lo(l), hi(h), dim(d) {}
  bool contains(const Vec3& p) const override {
    for (int k = 0; k < dim; ++k)
      if (p[k] < lo[k] || p[k] > hi[k]) return false;
    return true;
  }
  Aabb bounds() const override { return {lo, hi}; }
  std::optional<SurfacePoint> project(const Vec3& p) const override {
    Vec3 q = p;
    for (int k = 0; k < dim; ++k) q[k] = std::clamp(p[k], lo[k], hi[k]);
    const Vec3 d = q - p;
    const double len = std::sqrt(dot(d, d));
    if (len == 0) return std::nullopt;  // inside
    return SurfacePoint{q, (1.0 / len) * d};
  }
  bool projects() const override { return true; }
  bool is_box() const override { return true; }
};

struct BallNode final : ShapeNode {
  Vec3 c;
  double r_in, r_out;
  int dim;
  BallNode(Vec3 center, double ri, double ro, int d) : c(center), r_in(ri), r_out(ro), dim(d) {}
  bool contains(const Vec3& p) const override {
    double d2 = 0;
    for (int k = 0; k < dim; ++k) d2 += (p[k] - c[k]) * (p[k] - c[k]);
    return d2 <= r_out * r_out && d2 >= r_in * r_in;
  }
  Aabb bounds() const override {
    Aabb b{c, c};
    for (int k = 0; k < dim; ++k) {
      b.lo[k] -= r_out;
      b.hi[k] += r_out;
    }
    return b;
  }
  std::optional<SurfacePoint> project(const Vec3& p) const override {
    if (r_in > 0) return std::nullopt;
    Vec3 d = p - c;
    if (dim == 2) d[2] = 0;
    const double len = std::sqrt(dot(d, d));
    if (len <= r_out) return std::nullopt;
    const Vec3 e = (1.0 / len) * d;
    return SurfacePoint{c + r_out * e, -1.0 * e};
  }
  bool projects() const override { return r_in == 0; }
};

struct ShellNode final : ShapeNode {
  BallNode ring;
  double z0, z1;
  ShellNode(Vec3 c, double ri, double ro, double a, double b) : ring(c, ri, ro, 2), z0(a), z1(b) {}
  bool contains(const Vec3& p) const override { return p[2] >= z0 && p[2] <= z1 && ring.contains(p); }
  Aabb bounds() const override {
    Aabb b = ring.bounds();
    b.lo[2] = z0;
    b.hi[2] = z1;
    return b;
  }
};

struct PolygonNode final : ShapeNode {
  std::vector<Vec3> v;
  explicit PolygonNode(std::vector<Vec3> vertices) : v(std::move(vertices)) {}
  bool contains(const Vec3& p) const override {  // even-odd rule
    bool inside = false;
    for (std::size_t i = 0, j = v.size() - 1; i < v.size(); j = i++) {
      const bool straddles = (v[i][1] > p[1]) != (v[j][1] > p[1]);
      if (straddles && p[0] < (v[j][0] - v[i][0]) * (p[1] - v[i][1]) / (v[j][1] - v[i][1]) + v[i][0])
        inside = !inside;
    }
    return inside;
  }
  Aabb bounds() const override {
    Aabb b{v.front(), v.front()};
    for (const auto& q : v)
      for (int k = 0; k < 2; ++k) {
        b.lo[k] = std::min(b.lo[k], q[k]);
        b.hi[k] = std::max(b.hi[k], q[k]);
      }
    return b;
  }
};

struct CsgNode final : ShapeNode {
  Shape a, b;
  bool is_union;
  CsgNode(Shape x, Shape y, bool u) : a(std::move(x)), b(std::move(y)), is_union(u) {}
  bool contains(const Vec3& p) const override {
    return is_union ? (a.contains(p) || b.contains(p)) : (a.contains(p) && !b.contains(p));
  }
  std::optional<SurfacePoint> project(const Vec3& p) const override {
    if (!is_union) return std::nullopt;
    const auto x = a.project(p), y = b.project(p);
    if (!x || !y) return x ? x : y;
    return norm(x->point - p) <= norm(y->point - p) ? x : y;
  }
  bool projects() const override { return is_union && a.projects() && b.projects(); }
  Aabb bounds() const override {
    if (!is_union) return a.bounds();
    Aabb x = a.bounds(), y = b.bounds();
    for (int k = 0; k < 3; ++k) {
      x.lo[k] = std::min(x.lo[k], y.lo[k]);
      x.hi[k] = std::max(x.hi[k], y.hi[k]);
    }
    return x;
  }
};

void require_ordered(Vec3 lo, Vec3 hi, int dim, const char* name) {
  for (int k = 0; k < dim; ++k)
    require(hi[k] > lo[k], std::string(name) + ": max must exceed min in every direction");
}

}  // namespace

Shape interval(double lo, double hi) {
  require(hi > lo, "interval: max must exceed min");
  return Shape(std::make_shared<RectNode>(Vec3{lo, 0, 0}, Vec3{hi, 0, 0}, 1), 1);
}
Shape rectangle(Vec3 lo, Vec3 hi) {
  require_ordered(lo, hi, 2, "rectangle");
  lo[2] = hi[2] = 0;
  return Shape(std::make_shared<RectNode>(lo, hi, 2), 2);
}
Shape box(Vec3 lo, Vec3 hi) {
  require_ordered(lo, hi, 3, "box");
  return Shape(std::make_shared<RectNode>(lo, hi, 3), 3);
}
Shape disk(Vec3 center, double radius) {
  require(radius > 0, "disk: radius must be > 0");
  return Shape(std::make_shared<BallNode>(center, 0.0, radius, 2), 2);
}
Shape sphere(Vec3 center, double radius) {
  require(radius > 0, "sphere: radius must be > 0");
  return Shape(std::make_shared<BallNode>(center, 0.0, radius, 3), 3);
}
Shape annulus(Vec3 center, double inner_radius, double outer_radius) {
  require(inner_radius >= 0 && outer_radius > inner_radius, "annulus: need 0 <= inner_radius < outer_radius");
  return Shape(std::make_shared<BallNode>(center, inner_radius, outer_radius, 2), 2);
}
Shape cylinder_shell(Vec3 center, double inner_radius, double outer_radius, double z0, double z1) {
  require(inner_radius >= 0 && outer_radius > inner_radius, "cylinder_shell: need 0 <= inner_radius < outer_radius");
  require(z1 > z0, "cylinder_shell: need z1 > z0");
  return Shape(std::make_shared<ShellNode>(center, inner_radius, outer_radius, z0, z1), 3);
}
Shape polygon(std::vector<Vec3> vertices) {
  require(vertices.size() >= 3, "polygon: needs at least 3 vertices");
  return Shape(std::make_shared<PolygonNode>(std::move(vertices)), 2);
}
Shape unite(Shape a, Shape b) {
  require(a.dimension() == b.dimension(), "union: shapes must have the same dimension");
  const int d = a.dimension();
  return Shape(std::make_shared<CsgNode>(std::move(a), std::move(b), true), d);
}
Shape subtract(Shape a, Shape b) {
  require(a.dimension() == b.dimension(), "difference: shapes must have the same dimension");
  const int d = a.dimension();
  return Shape(std::make_shared<CsgNode>(std::move(a), std::move(b), false), d);
}

}  // namespace peridot
