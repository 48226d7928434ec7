module;
#include <array>
#include <charconv>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>
#include <fmt/core.h>
export module peridot.io:vtu;
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

// Steps and VTU files listed in a .pvd written by PvdSeries.
std::vector<std::pair<double, std::filesystem::path>> read_pvd(const std::filesystem::path& file);

}  // namespace peridot

namespace peridot {

namespace {

void write_atomically(const std::filesystem::path& file, const std::string& text_head, const std::vector<char>& blob,
                      const std::string& text_tail) {
  const auto tmp = file.string() + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary);
    if (!out) throw std::runtime_error(fmt::format("cannot write {}", tmp));
    out << text_head;
    out.write(blob.data(), std::streamsize(blob.size()));
    out << text_tail;
    if (!out) throw std::runtime_error(fmt::format("write failed: {}", tmp));
  }
  std::filesystem::rename(tmp, file);
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

std::string attribute(const std::string& tag, const std::string& name) {
  const auto p = tag.find(name + "=\"");
  if (p == std::string::npos) return {};
  const auto b = p + name.size() + 2;
  return tag.substr(b, tag.find('"', b) - b);
}

}  // namespace

void write_vtu(const std::filesystem::path& file, const PointCloud& pc, std::span<const NamedField> fields) {
  const std::size_t n = pc.size();
  Appender a;
  std::string xml = "<?xml version=\"1.0\"?>\n"
                    "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n"
                    "<UnstructuredGrid>\n";
  // Mesh discretizations are written as their triangles, so ParaView shows a surface;
  // point clouds as vertex cells.
  const bool tri = !pc.triangles.empty();
  const std::size_t cells = tri ? pc.triangles.size() : n;
  xml += fmt::format("<Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\n<PointData>\n", n, cells);
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
  // Vertex cells (VTK type 1) or triangles (type 5). Stored as Int64 via the same byte appender.
  const std::size_t per = tri ? 3 : 1;
  std::vector<std::int64_t> conn(cells * per), offs(cells);
  std::vector<std::uint8_t> types(cells, tri ? 5 : 1);
  for (std::size_t c = 0; c < cells; ++c) {
    for (std::size_t a = 0; a < per; ++a) conn[c * per + a] = tri ? std::int64_t(pc.triangles[c][a]) : std::int64_t(c);
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

namespace {

VtuData read_pieces(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw std::runtime_error(fmt::format("{}: cannot open PVTU file", file.string()));
  const std::string all((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  VtuData d;
  std::size_t pos = 0, pieces = 0;
  while ((pos = all.find("<Piece ", pos)) != std::string::npos) {
    const auto end = all.find('>', pos);
    const VtuData p = read_vtu(file.parent_path() / attribute(all.substr(pos, end - pos), "Source"));
    pos = end;
    const std::size_t offset = d.x[0].size();
    for (int k = 0; k < 3; ++k) d.x[k].insert(d.x[k].end(), p.x[k].begin(), p.x[k].end());
    for (const auto& a : p.arrays) {
      auto* mine = const_cast<VtuData::Array*>(d.find(a.name));
      if (!mine) {
        if (pieces) throw std::runtime_error(fmt::format("{}: array '{}' is missing from a piece", file.string(), a.name));
        d.arrays.push_back({a.name, a.components, {}});
        mine = &d.arrays.back();
      }
      mine->values.insert(mine->values.end(), a.values.begin(), a.values.end());
    }
    for (auto c : p.connectivity) d.connectivity.push_back(c + std::int64_t(offset));
    d.cells += p.cells;
    ++pieces;
  }
  if (!pieces) throw std::runtime_error(fmt::format("{}: no pieces listed", file.string()));
  return d;
}

}  // namespace

VtuData read_vtu(const std::filesystem::path& file) {
  if (file.extension() == ".pvtu") return read_pieces(file);
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error(fmt::format("{}: cannot open VTU file", file.string()));
  const std::string all((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto marker = all.find("<AppendedData encoding=\"raw\">");
  if (marker == std::string::npos) throw std::runtime_error(fmt::format("{}: not a Peridot VTU (no raw appended data)", file.string()));
  if (all.rfind("</VTKFile>") == std::string::npos) throw std::runtime_error(fmt::format("{}: truncated VTU (no closing tag)", file.string()));
  const auto base = all.find('_', marker) + 1;
  VtuData d;
  if (const auto piece = all.find("<Piece"); piece != std::string::npos && piece < marker)
    d.cells = std::stoull(attribute(all.substr(piece, all.find('>', piece) - piece), "NumberOfCells"));
  std::size_t pos = 0;
  const auto read_block = [&](std::uint64_t off) {
    std::uint64_t bytes = 0;
    if (base + off + 8 > all.size()) throw std::runtime_error(fmt::format("{}: truncated VTU", file.string()));
    std::memcpy(&bytes, all.data() + base + off, 8);
    if (base + off + 8 + bytes > all.size() || bytes % 8) throw std::runtime_error(fmt::format("{}: truncated VTU", file.string()));
    std::vector<double> v(bytes / 8);
    std::memcpy(v.data(), all.data() + base + off + 8, bytes);
    return v;
  };
  while ((pos = all.find("<DataArray", pos)) != std::string::npos && pos < marker) {
    const auto end = all.find('>', pos);
    const std::string tag = all.substr(pos, end - pos);
    pos = end;
    if (attribute(tag, "type") == "Int64" && attribute(tag, "Name") == "connectivity") {
      // Same block layout as Float64: 8-byte values after a UInt64 byte count.
      const auto raw = read_block(std::stoull(attribute(tag, "offset")));
      d.connectivity.resize(raw.size());
      std::memcpy(d.connectivity.data(), raw.data(), raw.size() * 8);
    }
    if (attribute(tag, "type") != "Float64") continue;
    const auto name = attribute(tag, "Name");
    const int comps = std::stoi(attribute(tag, "NumberOfComponents"));
    auto values = read_block(std::stoull(attribute(tag, "offset")));
    if (name == "Points") {
      const std::size_t n = values.size() / 3;
      for (int k = 0; k < 3; ++k) {
        d.x[k].resize(n);
        for (std::size_t i = 0; i < n; ++i) d.x[k][i] = values[3 * i + k];
      }
    } else {
      d.arrays.push_back({name, comps, std::move(values)});
    }
  }
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
  std::ifstream in(file);
  if (!in) throw std::runtime_error(fmt::format("{}: cannot open PVD file", file.string()));
  const std::string all((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::vector<std::pair<double, std::filesystem::path>> out;
  std::size_t pos = 0;
  while ((pos = all.find("<DataSet", pos)) != std::string::npos) {
    const auto end = all.find('>', pos);
    const std::string tag = all.substr(pos, end - pos);
    pos = end;
    out.emplace_back(std::stod(attribute(tag, "timestep")), file.parent_path() / attribute(tag, "file"));
  }
  if (out.empty()) throw std::runtime_error(fmt::format("{}: no datasets listed", file.string()));
  return out;
}

}  // namespace peridot
