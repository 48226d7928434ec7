export module peridot.render:options;
import peridot.std;

export namespace peridot {

// What to draw: plain arrays, so callers without a Body (the DDS viewer, the .pvd
// re-renderer) can render too. Every non-empty span holds one entry per point.
struct RenderField {
  int dim = 2;                                   // 2 or 3
  std::array<std::span<const double>, 3> x;      // reference positions [m]; 2D may leave x[2] empty
  std::array<std::span<const double>, 3> u;      // displacements [m]; empty spans: none
  std::span<const double> values;                // nodal field to colour by (e.g. damage); NaN drawn grey
  std::string field_name = "damage";
  double time = 0;                               // [s], or what time_label names
  std::string time_label;                        // what `time` is when not seconds (load factor, linear solve); empty: time [s]
  std::size_t step = 0;
  double spacing = 0;                            // point spacing h [m] (3D slice thickness); 0: estimated
};

struct RenderOptions {
  int width = 1200;                              // image width [px], 16..16384
  int height = 0;                                // 0: from the body's aspect ratio (+ title, colorbar, scale bar)
  bool deformed = false;                         // draw x + magnification * u
  double magnification = 1.0;                    // >= 0
  std::optional<double> vmin, vmax;              // colour range; default [0, 1] for damage, data range otherwise
  std::string title;                             // default: "<field>  t = <time> s  step <n>" (or "<time_label> <time>")
  // 3D: a slice keeps points with |x[axis] - slice_position| <= h/2; a projection draws
  // every point onto the plane, the largest value in front.
  enum class View3D { slice, projection } view3d = View3D::slice;
  int axis = 2;                                  // normal of the slice/projection plane (3D)
  std::optional<double> slice_position;          // [m]; default: mid-plane of the body
  double point_size = 0;                         // drawn square side [m]; 0: estimated so the body looks solid
};

// A field held in parts by several processes (MPI ranks), each drawing its own points: the
// parts agree on the frame, colour range and point count through these element-wise
// reductions, and the image is the one a single part holding every point would draw (each
// pixel shows the largest colour level of the squares covering it, whatever their order).
// The defaults are one part. Parts leave RenderField::spacing and RenderOptions::point_size
// non-zero: the spacing estimate needs every point's neighbours (estimate_spacing_samples).
struct RenderParts {
  bool root = true;                                       // the part that receives the image
  std::function<void(std::span<double>)> sum, max;        // over the parts, in place, on every part
  std::function<void(std::span<std::int16_t>)> max_to_root;  // over the parts, needed on the root only
  bool one() const { return !sum; }
};

}  // namespace peridot
