// A field of saved VTU output, as `peridot render` draws it: re-rendering needs no run.
export module peridot.render:saved_field;
import peridot.std;
import peridot.io;
import :options;

export namespace peridot {

// The point array `name` of one VTU file, owned, and a RenderField that views it: coloured by
// the array (by its magnitude if it has several components) over the reference positions, 2D
// when every z is 0, with the file's displacement when it has one, at `time` (a .pvd series'
// entry) and the step of the file name (<name>_<step>.vtu). Movable, not copyable: the view
// points into the owned arrays.
struct SavedField {
  std::array<std::vector<double>, 3> x, u;
  std::vector<double> values;
  RenderField field;

  SavedField() = default;
  SavedField(SavedField&&) = default;
  SavedField& operator=(SavedField&&) = default;
  SavedField(const SavedField&) = delete;
  SavedField& operator=(const SavedField&) = delete;
};

// Throws std::runtime_error naming the file when it has no point array `name`.
inline SavedField read_saved_field(const std::filesystem::path& vtu, const std::string& name, double time = 0) {
  VtuData d = read_vtu(vtu);
  const auto* a = d.find(name);
  if (!a) throw std::runtime_error(fmt::format("{}: no point array named '{}'", vtu.string(), name));
  SavedField s;
  const std::size_t n = d.x[0].size();
  const auto c = std::size_t(a->components);
  s.values.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    double m = 0;
    for (std::size_t k = 0; k < c; ++k) m += a->values[i * c + k] * a->values[i * c + k];
    s.values[i] = c == 1 ? a->values[i] : std::sqrt(m);
  }
  // read_vtu guarantees components x points values; a displacement must have 3 of them.
  if (const auto* disp = d.find("displacement"); disp && disp->components == 3)
    for (std::size_t k = 0; k < 3; ++k) {
      s.u[k].resize(n);
      for (std::size_t i = 0; i < n; ++i) s.u[k][i] = disp->values[3 * i + k];
    }
  bool flat = true;
  for (double z : d.x[2]) flat = flat && z == 0.0;
  s.x = {std::move(d.x[0]), std::move(d.x[1]), std::move(d.x[2])};
  s.field.dim = flat ? 2 : 3;
  s.field.x = {s.x[0], s.x[1], s.x[2]};
  s.field.u = {s.u[0], s.u[1], s.u[2]};
  s.field.values = s.values;
  s.field.field_name = name;
  s.field.time = std::isnan(time) ? 0.0 : time;
  const auto stem = vtu.stem().string();
  const auto us = stem.rfind('_');
  s.field.step = us == std::string::npos ? 0 : std::size_t(std::strtoull(stem.c_str() + us + 1, nullptr, 10));
  return s;
}

}  // namespace peridot
