export module peridot.io:vtu;
import peridot.std;
import :files;
import peridot.discretization;

export namespace peridot {

// A nodal array for output: 1 or 3 components (2D vectors are written with z = 0).
struct NamedField {
  std::string name;
  int components = 1;
  std::array<std::span<const double>, 3> data;
};

// Unstructured-grid VTU of vertex cells at the reference positions, binary appended
// (raw, UInt64 headers), Float64 data. Written to a temporary file and renamed, so a
// reader never sees a half-written file.
void write_vtu(const std::filesystem::path& file, const PointCloud& points, std::span<const NamedField> fields);

// The .pvtu of a dataset written as one piece per rank (`pieces`, file names next to it, each a
// write_vtu of that rank's points with `fields`): ParaView opens it as one dataset.
void write_pvtu(const std::filesystem::path& file, std::span<const std::string> pieces, std::span<const NamedField> fields);

// Arrays read back from a VTU written by write_vtu (or a .pvtu: its pieces, concatenated).
struct VtuData {
  std::array<std::vector<double>, 3> x;
  struct Array {
    std::string name;
    int components;
    std::vector<double> values;  // interleaved
  };
  std::vector<Array> arrays;
  std::size_t cells = 0;                      // NumberOfCells
  std::vector<std::int64_t> connectivity;     // cell node indices, concatenated
  const Array* find(const std::string& name) const;
};
// What it returns is whole: every array has components (1 to 9) x points values and every
// connectivity entry is a point index, 1, 3 or 4 per cell. Anything else (a missing, truncated
// or foreign file, a count or offset past the end of the file) is a std::runtime_error
// naming the file and the field; a .pvtu's pieces must be distinct .vtu files next to it.
VtuData read_vtu(const std::filesystem::path& file);

// A ParaView .pvd collection that is rewritten (atomically) after each new step file.
class PvdSeries {
 public:
  PvdSeries(std::filesystem::path directory, std::string basename);
  // Writes <basename>_<step>.vtu and updates <basename>.pvd; returns the VTU path.
  std::filesystem::path write(double time, std::size_t step, const PointCloud& points, std::span<const NamedField> fields);
  // One rank's piece of a step written on `ranks` ranks: every rank writes
  // <basename>_<step>_<rank>.vtu; rank 0 then (after all pieces exist) calls add_pieces, which
  // writes <basename>_<step>.pvtu and lists it in the .pvd.
  std::filesystem::path write_piece(std::size_t step, int rank, const PointCloud& points, std::span<const NamedField> fields);
  std::filesystem::path add_pieces(double time, std::size_t step, int ranks, std::span<const NamedField> fields);
  // A restarted run: keeps the steps before `step` that an existing .pvd lists, so the series
  // goes on with the files of the first run (an unreadable .pvd starts a new series).
  void resume(std::size_t step);
  const std::filesystem::path& pvd() const { return pvd_; }

 private:
  std::filesystem::path dir_, pvd_;
  std::string base_;
  std::vector<std::pair<double, std::string>> entries_;
  void write_pvd() const;
};

// Steps and VTU files listed in a .pvd written by PvdSeries (finite times, non-empty names).
std::vector<std::pair<double, std::filesystem::path>> read_pvd(const std::filesystem::path& file);

}  // namespace peridot

namespace peridot {

namespace {

void write_atomically(const std::filesystem::path& file, const std::string& text_head, const std::vector<char>& blob,
                      const std::string& text_tail) {
  write_file_atomically(file, {text_head, std::string_view(blob.data(), blob.size()), text_tail});
}

struct Appender {
  std::vector<char> blob;
  std::uint64_t add(const std::vector<double>& v) {
    const std::uint64_t offset = blob.size();
    const std::uint64_t bytes = v.size() * sizeof(double);
    const auto* h = reinterpret_cast<const char*>(&bytes);
    blob.insert(blob.end(), h, h + sizeof bytes);
    const auto* d = reinterpret_cast<const char*>(v.data());
    blob.insert(blob.end(), d, d + bytes);
    return offset;
  }
};

std::vector<double> interleave(const std::array<std::span<const double>, 3>& c, int comps, std::size_t n) {
  std::vector<double> v(n * std::size_t(comps), 0.0);
  for (std::size_t i = 0; i < n; ++i)
    for (int k = 0; k < comps; ++k) v[i * comps + k] = c[k].empty() ? 0.0 : c[k][i];
  return v;
}

}  // namespace

void write_vtu(const std::filesystem::path& file, const PointCloud& pc, std::span<const NamedField> fields) {
  const std::size_t n = pc.size();
  Appender a;
  std::string xml = "<?xml version=\"1.0\"?>\n"
                    "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n"
                    "<UnstructuredGrid>\n";
  // Mesh discretizations are written as their elements, so ParaView shows a surface (triangles)
  // or a solid (tetrahedra); point clouds as vertex cells.
  const bool tri = !pc.triangles.empty(), tet = !tri && !pc.tetrahedra.empty();
  const std::size_t cells = tri ? pc.triangles.size() : tet ? pc.tetrahedra.size() : n;
  xml += fmt::format("<Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\n<PointData>\n", n, cells);
  const std::size_t per = tri ? 3 : tet ? 4 : 1;
  // The appended data's exact size up front: grown by doubling, the blob of the 638k-point
  // Kalthoff-Winkler run peaked at twice its 77 MB while it moved (the run's peak rose 176 MiB).
  std::uint64_t total = 8 + 24 * std::uint64_t(n) + 3 * 8 + std::uint64_t(cells) * (8 * per + 8 + 1);
  for (const auto& f : fields) total += 8 + 8 * std::uint64_t(f.components) * n;
  a.blob.reserve(total);
  for (const auto& f : fields) {
    for (int k = 0; k < f.components; ++k)
      if (f.data[k].size() != n && !f.data[k].empty()) throw std::invalid_argument("write_vtu: field '" + f.name + "' has the wrong length");
    const auto off = a.add(interleave(f.data, f.components, n));
    xml += fmt::format("<DataArray type=\"Float64\" Name=\"{}\" NumberOfComponents=\"{}\" format=\"appended\" offset=\"{}\"/>\n",
                       f.name, f.components, off);
  }
  xml += "</PointData>\n<Points>\n";
  const auto poff = a.add(interleave({pc.x[0], pc.x[1], pc.x[2]}, 3, n));
  xml += fmt::format("<DataArray type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\" format=\"appended\" offset=\"{}\"/>\n", poff);
  xml += "</Points>\n<Cells>\n";
  // Vertex cells (VTK type 1), triangles (type 5) or tetrahedra (type 10). Stored as Int64 via
  // the same byte appender.
  std::vector<std::int64_t> conn(cells * per), offs(cells);
  std::vector<std::uint8_t> types(cells, tri ? 5 : tet ? 10 : 1);
  for (std::size_t c = 0; c < cells; ++c) {
    for (std::size_t a = 0; a < per; ++a)
      conn[c * per + a] = tri ? std::int64_t(pc.triangles[c][a]) : tet ? std::int64_t(pc.tetrahedra[c][a]) : std::int64_t(c);
    offs[c] = std::int64_t((c + 1) * per);
  }
  auto add_raw = [&](const void* p, std::uint64_t bytes) {
    const std::uint64_t off = a.blob.size();
    const auto* h = reinterpret_cast<const char*>(&bytes);
    a.blob.insert(a.blob.end(), h, h + sizeof bytes);
    a.blob.insert(a.blob.end(), static_cast<const char*>(p), static_cast<const char*>(p) + bytes);
    return off;
  };
  xml += fmt::format("<DataArray type=\"Int64\" Name=\"connectivity\" format=\"appended\" offset=\"{}\"/>\n", add_raw(conn.data(), conn.size() * 8));
  xml += fmt::format("<DataArray type=\"Int64\" Name=\"offsets\" format=\"appended\" offset=\"{}\"/>\n", add_raw(offs.data(), offs.size() * 8));
  xml += fmt::format("<DataArray type=\"UInt8\" Name=\"types\" format=\"appended\" offset=\"{}\"/>\n", add_raw(types.data(), types.size()));
  xml += "</Cells>\n</Piece>\n</UnstructuredGrid>\n<AppendedData encoding=\"raw\">\n_";
  write_atomically(file, xml, a.blob, "\n</AppendedData>\n</VTKFile>\n");
}

void write_pvtu(const std::filesystem::path& file, std::span<const std::string> pieces, std::span<const NamedField> fields) {
  std::string xml = "<?xml version=\"1.0\"?>\n"
                    "<VTKFile type=\"PUnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n"
                    "<PUnstructuredGrid GhostLevel=\"0\">\n<PPointData>\n";
  for (const auto& f : fields)
    xml += fmt::format("<PDataArray type=\"Float64\" Name=\"{}\" NumberOfComponents=\"{}\"/>\n", f.name, f.components);
  xml += "</PPointData>\n<PPoints>\n<PDataArray type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\"/>\n</PPoints>\n"
         "<PCells>\n<PDataArray type=\"Int64\" Name=\"connectivity\"/>\n<PDataArray type=\"Int64\" Name=\"offsets\"/>\n"
         "<PDataArray type=\"UInt8\" Name=\"types\"/>\n</PCells>\n";
  for (const auto& piece : pieces) xml += fmt::format("<Piece Source=\"{}\"/>\n", piece);
  xml += "</PUnstructuredGrid>\n</VTKFile>\n";
  write_atomically(file, xml, {}, "");
}

const VtuData::Array* VtuData::find(const std::string& name) const {
  for (const auto& a : arrays)
    if (a.name == name) return &a;
  return nullptr;
}

// ---- reading ----
// Every count, offset and size comes from the file: each is bounded by the bytes the file
// holds before anything is allocated, with arithmetic that cannot wrap, and what is read is
// checked for the shape VtuData promises (the renderer indexes by it).

namespace {

[[noreturn]] void refuse(const std::filesystem::path& file, const std::string& what) {
  throw std::runtime_error(fmt::format("{}: {}", file.string(), what));
}

// A value from the file as shown in a message: at most 40 characters.
std::string in_quotes(std::string_view v) {
  return v.size() <= 40 ? fmt::format("'{}'", v) : fmt::format("'{}...' ({} characters)", v.substr(0, 40), v.size());
}

// The value of attribute `name` of an XML tag ("" and found = false when absent). Matched
// after whitespace, so that "Name" is not found inside "FileName".
std::string attribute(std::string_view tag, std::string_view name, bool* found = nullptr) {
  for (std::size_t p = tag.find(name); p != std::string_view::npos; p = tag.find(name, p + 1)) {
    const std::size_t b = p + name.size();
    if (p == 0 || !std::isspace(static_cast<unsigned char>(tag[p - 1])) || tag.substr(b, 2) != "=\"") continue;
    const std::size_t e = tag.find('"', b + 2);
    if (e == std::string_view::npos) break;
    if (found) *found = true;
    return std::string(tag.substr(b + 2, e - b - 2));
  }
  if (found) *found = false;
  return {};
}

std::string_view tag_at(const std::string& all, std::size_t pos) {
  const auto end = all.find('>', pos);
  return std::string_view(all).substr(pos, end == std::string::npos ? std::string::npos : end - pos);
}

// An attribute that must be a whole number in [0, max]; `what` names the tag in messages.
std::uint64_t count_attribute(const std::filesystem::path& file, std::string_view tag, std::string_view name, const std::string& what,
                              std::uint64_t max, const char* why) {
  bool found = false;
  const auto text = attribute(tag, name, &found);
  if (!found) refuse(file, fmt::format("{}: attribute {} is missing", what, name));
  std::uint64_t v = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (text.empty() || ec != std::errc() || end != text.data() + text.size())
    refuse(file, fmt::format("{}: {} = {} is not a whole number in [0, {}]", what, name, in_quotes(text), max));
  if (v > max) refuse(file, fmt::format("{}: {} = {} is out of range: at most {} ({})", what, name, v, max, why));
  return v;
}

// The values of one appended block: a UInt64 byte count, then that many bytes of 8-byte values.
// `data` is the appended section (after its '_').
std::vector<double> read_block(const std::filesystem::path& file, std::string_view data, std::uint64_t offset, const std::string& what) {
  if (offset > data.size() || data.size() - offset < 8)
    refuse(file, fmt::format("truncated VTU: {} at offset {} has no room for its 8-byte size in the {} bytes of appended data", what, offset,
                             data.size()));
  std::uint64_t bytes = 0;
  std::memcpy(&bytes, data.data() + offset, 8);
  const std::uint64_t room = data.size() - offset - 8;
  if (bytes > room)
    refuse(file, fmt::format("truncated VTU: {} at offset {} declares {} bytes, but only {} follow", what, offset, bytes, room));
  if (bytes % 8) refuse(file, fmt::format("{}: {} bytes is not a whole number of 8-byte values", what, bytes));
  std::vector<double> v(bytes / 8);
  if (bytes) std::memcpy(v.data(), data.data() + offset + 8, bytes);
  return v;
}

// What VtuData promises: every array holds components x points values, and the connectivity
// names points that exist, 1, 3 or 4 per cell.
void require_consistent(const std::filesystem::path& file, const VtuData& d) {
  const std::size_t n = d.x[0].size();
  for (const auto& a : d.arrays)
    if (a.values.size() != n * std::size_t(a.components))
      refuse(file, fmt::format("point array '{}' has {} values; {} points x {} components need {}", a.name, a.values.size(), n, a.components,
                               n * std::size_t(a.components)));
  for (std::size_t k = 0; k < d.connectivity.size(); ++k)
    if (d.connectivity[k] < 0 || std::uint64_t(d.connectivity[k]) >= n)
      refuse(file, fmt::format("connectivity[{}] = {} is not a point index in [0, {})", k, d.connectivity[k], n));
  // Vertex cells, triangles or tetrahedra (NumberOfCells is bounded by the file size: 4 x cells
  // cannot wrap).
  const std::size_t entries = d.connectivity.size();
  if (entries && entries != d.cells && entries != 3 * d.cells && entries != 4 * d.cells)
    refuse(file, fmt::format("connectivity has {} entries for NumberOfCells = {} (1, 3 or 4 per cell)", entries, d.cells));
}

std::string read_whole(const std::filesystem::path& file, const char* kind) {
  std::error_code ec;
  // Not a FIFO or a device: those have no end to read to.
  if (!std::filesystem::is_regular_file(file, ec)) refuse(file, fmt::format("cannot open {} file (missing, or not a regular file)", kind));
  std::ifstream in(file, std::ios::binary);
  if (!in) refuse(file, fmt::format("cannot open {} file", kind));
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

VtuData read_pieces(const std::filesystem::path& file) {
  const std::string all = read_whole(file, "PVTU");
  VtuData d;
  std::vector<std::string> seen;
  std::size_t pos = 0;
  while ((pos = all.find("<Piece ", pos)) != std::string::npos) {
    const auto tag = tag_at(all, pos);
    pos += tag.size();
    const auto source = attribute(tag, "Source");
    const std::filesystem::path piece(source);
    // Pieces are the .vtu files next to the .pvtu that write_pvtu lists, each once: so no piece
    // is another .pvtu (endless recursion) and no file is read twice (memory without bound).
    if (source.empty() || piece.is_absolute() || piece.extension() != ".vtu")
      refuse(file, fmt::format("Piece Source = {}: expected the name of a .vtu file next to the .pvtu", in_quotes(source)));
    for (const auto& s : seen)
      if (s == source) refuse(file, fmt::format("Piece Source = {} is listed twice", in_quotes(source)));
    seen.push_back(source);
    const VtuData p = read_vtu(file.parent_path() / piece);
    const std::size_t offset = d.x[0].size();
    for (int k = 0; k < 3; ++k) d.x[k].insert(d.x[k].end(), p.x[k].begin(), p.x[k].end());
    for (const auto& a : p.arrays) {
      auto* mine = const_cast<VtuData::Array*>(d.find(a.name));
      if (!mine) {
        if (seen.size() > 1) refuse(file, fmt::format("array '{}' is missing from a piece before {}", a.name, in_quotes(source)));
        d.arrays.push_back({a.name, a.components, {}});
        mine = &d.arrays.back();
      }
      if (mine->components != a.components)
        refuse(file, fmt::format("array '{}' has {} components in {} but {} in an earlier piece", a.name, a.components, in_quotes(source),
                                 mine->components));
      mine->values.insert(mine->values.end(), a.values.begin(), a.values.end());
    }
    for (auto c : p.connectivity) d.connectivity.push_back(c + std::int64_t(offset));
    d.cells += p.cells;
  }
  if (seen.empty()) refuse(file, "no pieces listed");
  // An array missing from a later piece leaves its values short of the points.
  require_consistent(file, d);
  return d;
}

}  // namespace

VtuData read_vtu(const std::filesystem::path& file) {
  if (file.extension() == ".pvtu") return read_pieces(file);
  const std::string all = read_whole(file, "VTU");
  const auto marker = all.find("<AppendedData encoding=\"raw\">");
  if (marker == std::string::npos) refuse(file, "not a Peridot VTU (no raw appended data)");
  if (all.rfind("</VTKFile>") == std::string::npos) refuse(file, "truncated VTU (no closing tag)");
  const auto underscore = all.find('_', marker);
  if (underscore == std::string::npos) refuse(file, "truncated VTU (no '_' starts the appended data)");
  const std::string_view data = std::string_view(all).substr(underscore + 1);
  // Each point has 3 coordinates of 8 bytes, each cell at least an 8-byte offset.
  const std::uint64_t max_points = data.size() / 24, max_cells = data.size() / 8;
  const char* why = "what the appended data can hold";
  VtuData d;
  bool has_points_count = false;
  std::uint64_t points = 0;
  if (const auto piece = all.find("<Piece"); piece != std::string::npos && piece < marker) {
    const auto tag = tag_at(all, piece);
    d.cells = count_attribute(file, tag, "NumberOfCells", "Piece", max_cells, why);
    attribute(tag, "NumberOfPoints", &has_points_count);
    if (has_points_count) points = count_attribute(file, tag, "NumberOfPoints", "Piece", max_points, why);
  }
  bool has_points = false;
  std::size_t pos = 0;
  while ((pos = all.find("<DataArray", pos)) != std::string::npos && pos < marker) {
    const auto tag = tag_at(all, pos);
    pos += tag.size();
    const auto type = attribute(tag, "type"), name = attribute(tag, "Name");
    const bool connectivity = type == "Int64" && name == "connectivity";
    if (type != "Float64" && !connectivity) continue;
    const std::string what = fmt::format("DataArray {}", in_quotes(name));
    const auto offset = count_attribute(file, tag, "offset", what, data.size(), "the size of the appended data");
    auto values = read_block(file, data, offset, what);
    if (connectivity) {
      // Same block layout as Float64: 8-byte values after a UInt64 byte count.
      d.connectivity.resize(values.size());
      if (!values.empty()) std::memcpy(d.connectivity.data(), values.data(), values.size() * 8);
      continue;
    }
    bool has_comps = false;
    attribute(tag, "NumberOfComponents", &has_comps);
    const int comps = has_comps ? int(count_attribute(file, tag, "NumberOfComponents", what, 9, "scalars to 3 x 3 tensors")) : 1;
    if (comps < 1) refuse(file, fmt::format("{}: NumberOfComponents = 0; allowed 1 to 9", what));
    if (values.size() % std::size_t(comps))
      refuse(file, fmt::format("{}: {} values are not whole tuples of {} components", what, values.size(), comps));
    if (name == "Points") {
      if (comps != 3) refuse(file, fmt::format("{}: NumberOfComponents = {}; points have 3", what, comps));
      if (has_points) refuse(file, "two Points arrays");
      has_points = true;
      const std::size_t n = values.size() / 3;
      for (int k = 0; k < 3; ++k) {
        d.x[k].resize(n);
        for (std::size_t i = 0; i < n; ++i) d.x[k][i] = values[3 * i + std::size_t(k)];
      }
    } else {
      d.arrays.push_back({name, comps, std::move(values)});
    }
  }
  if (!has_points) refuse(file, "no Points array");
  if (has_points_count && points != d.x[0].size())
    refuse(file, fmt::format("Piece NumberOfPoints = {}, but the Points array holds {}", points, d.x[0].size()));
  require_consistent(file, d);
  return d;
}

PvdSeries::PvdSeries(std::filesystem::path directory, std::string basename)
    : dir_(std::move(directory)), pvd_(dir_ / (basename + ".pvd")), base_(std::move(basename)) {}

std::filesystem::path PvdSeries::write(double time, std::size_t step, const PointCloud& pc, std::span<const NamedField> fields) {
  const std::string name = fmt::format("{}_{:07d}.vtu", base_, step);
  write_vtu(dir_ / name, pc, fields);
  entries_.emplace_back(time, name);
  write_pvd();
  return dir_ / name;
}

std::filesystem::path PvdSeries::write_piece(std::size_t step, int rank, const PointCloud& pc, std::span<const NamedField> fields) {
  const auto file = dir_ / fmt::format("{}_{:07d}_{}.vtu", base_, step, rank);
  write_vtu(file, pc, fields);
  return file;
}

std::filesystem::path PvdSeries::add_pieces(double time, std::size_t step, int ranks, std::span<const NamedField> fields) {
  std::vector<std::string> pieces;
  for (int r = 0; r < ranks; ++r) pieces.push_back(fmt::format("{}_{:07d}_{}.vtu", base_, step, r));
  const std::string name = fmt::format("{}_{:07d}.pvtu", base_, step);
  write_pvtu(dir_ / name, pieces, fields);
  entries_.emplace_back(time, name);
  write_pvd();
  return dir_ / name;
}

void PvdSeries::write_pvd() const {
  std::string xml = "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"1.0\">\n<Collection>\n";
  for (const auto& [t, f] : entries_) xml += fmt::format("<DataSet timestep=\"{:.9e}\" part=\"0\" file=\"{}\"/>\n", t, f);
  xml += "</Collection>\n</VTKFile>\n";
  write_atomically(pvd_, xml, {}, "");
}

void PvdSeries::resume(std::size_t step) {
  entries_.clear();
  std::error_code ec;
  if (!std::filesystem::exists(pvd_, ec)) return;
  std::vector<std::pair<double, std::filesystem::path>> listed;
  try {
    listed = read_pvd(pvd_);
  } catch (const std::exception&) {
    return;
  }
  const std::string prefix = base_ + "_";
  for (const auto& [time, path] : listed) {
    const auto name = path.filename().string();
    const bool pieces = name.ends_with(".pvtu");
    if (!name.starts_with(prefix) || !(name.ends_with(".vtu") || pieces)) continue;
    std::size_t s = 0;
    const char* end = name.data() + name.size() - (pieces ? 5 : 4);
    const auto [p, err] = std::from_chars(name.data() + prefix.size(), end, s);
    if (err == std::errc() && p == end && s < step) entries_.emplace_back(time, name);
  }
}

std::vector<std::pair<double, std::filesystem::path>> read_pvd(const std::filesystem::path& file) {
  const std::string all = read_whole(file, "PVD");
  std::vector<std::pair<double, std::filesystem::path>> out;
  std::size_t pos = 0;
  while ((pos = all.find("<DataSet", pos)) != std::string::npos) {
    const auto tag = tag_at(all, pos);
    pos += tag.size();
    const auto timestep = attribute(tag, "timestep"), name = attribute(tag, "file");
    double t = 0;
    const auto [end, ec] = std::from_chars(timestep.data(), timestep.data() + timestep.size(), t);
    if (timestep.empty() || ec != std::errc() || end != timestep.data() + timestep.size() || !std::isfinite(t))
      refuse(file, fmt::format("DataSet {}: timestep = {} is not a finite number", out.size(), in_quotes(timestep)));
    if (name.empty()) refuse(file, fmt::format("DataSet {}: the file attribute is missing or empty", out.size()));
    out.emplace_back(t, file.parent_path() / name);
  }
  if (out.empty()) refuse(file, "no datasets listed");
  return out;
}

}  // namespace peridot
