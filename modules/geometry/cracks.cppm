export module peridot.geometry:cracks;
import peridot.std;
import :vec;

export namespace peridot {

// 2D crack: a line segment in the xy plane.
struct CrackSegment {
  Vec3 a, b;
};

// 3D crack: the planar parallelogram origin + s*edge1 + t*edge2, s, t in [0, 1].
struct CrackRectangle {
  Vec3 origin, edge1, edge2;
};

using Crack = std::variant<CrackSegment, CrackRectangle>;

// True when the open segment p-q properly crosses the crack: its end points lie strictly on
// opposite sides, so a bond that only touches or runs alongside the crack survives.
bool crosses(const CrackSegment& c, const Vec3& p, const Vec3& q);
bool crosses(const CrackRectangle& c, const Vec3& p, const Vec3& q);
bool crosses(const Crack& c, const Vec3& p, const Vec3& q);
bool crosses_any(const std::vector<Crack>& cracks, const Vec3& p, const Vec3& q);

}  // namespace peridot

namespace peridot {

namespace {
double orient(const Vec3& a, const Vec3& b, const Vec3& c) {
  return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}
}  // namespace

bool crosses(const CrackSegment& c, const Vec3& p, const Vec3& q) {
  const double o1 = orient(c.a, c.b, p), o2 = orient(c.a, c.b, q);
  const double o3 = orient(p, q, c.a), o4 = orient(p, q, c.b);
  return o1 * o2 < 0 && o3 * o4 < 0;
}

bool crosses(const CrackRectangle& c, const Vec3& p, const Vec3& q) {
  const Vec3 n = cross(c.edge1, c.edge2);
  const double dp = dot(n, p - c.origin), dq = dot(n, q - c.origin);
  if (!(dp * dq < 0)) return false;
  const double t = dp / (dp - dq);
  const Vec3 x = p + t * (q - p) - c.origin;
  // Coordinates of x in the (edge1, edge2) basis via the 2x2 Gram system.
  const double a11 = dot(c.edge1, c.edge1), a12 = dot(c.edge1, c.edge2), a22 = dot(c.edge2, c.edge2);
  const double b1 = dot(x, c.edge1), b2 = dot(x, c.edge2);
  const double det = a11 * a22 - a12 * a12;
  const double s = (b1 * a22 - b2 * a12) / det, r = (a11 * b2 - a12 * b1) / det;
  return s > 0 && s < 1 && r > 0 && r < 1;
}

bool crosses(const Crack& c, const Vec3& p, const Vec3& q) {
  return std::visit([&](const auto& k) { return crosses(k, p, q); }, c);
}

bool crosses_any(const std::vector<Crack>& cracks, const Vec3& p, const Vec3& q) {
  for (const auto& c : cracks)
    if (crosses(c, p, q)) return true;
  return false;
}

}  // namespace peridot
