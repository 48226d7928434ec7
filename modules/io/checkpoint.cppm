module;
#include <fcntl.h>
#include <hdf5.h>
#include <unistd.h>

#include <limits.h>
export module peridot.io:checkpoint;
import peridot.std;

export namespace peridot {

// Version of the HDF5 layout below; a reader refuses any other.
// 2: HDF5 1.8 file format (checksummed metadata); version 1 files are refused.
inline constexpr int checkpoint_format_version = 2;

// An explicit run's restart point as plain data: what identifies the run, and everything the
// solver needs to continue bit for bit. The bond state is one byte per directed bond, whoever
// owns it (today Body::bonds.intact).
//
// HDF5 layout: root attributes format = "peridot-checkpoint", version, deck_name, deck_hash,
// dim, points, bonds, dt, scheme, step, time, external_work, broken, and bond_layout where it is
// not ""; datasets u, v, f (double, 3 x points) and bond_state (uint8, bonds).
struct Checkpoint {
  std::string deck_name;
  std::uint64_t deck_hash = 0;  // Problem::content_hash
  int dim = 0;
  std::uint64_t points = 0;
  std::uint64_t bonds = 0;      // directed
  double dt = 0;
  std::string scheme;           // solver.scheme
  std::uint64_t step = 0;
  double time = 0;
  std::array<std::vector<double>, 3> u, v, f;
  std::vector<std::uint8_t> bond_state;
  double external_work = 0;
  std::uint64_t broken = 0;
  std::vector<std::uint64_t> row_bonds;  // per point, only where some points were read (read_checkpoint_points)
  // How bond_state is laid out: "" as the body stores it (a list's rows, point after point; a
  // lattice stencil's padded grid in checkpoints written before "point_offsets"), or
  // "point_offsets": a stencil's states point after point, one per stencil offset, whatever the
  // grid's padding (so parts written by N ranks assemble into it). Attribute bond_layout.
  std::string bond_layout;
};

// Writes <file>.tmp, flushes it to disk and renames it over file, so a run killed at any moment
// leaves the previous checkpoint (or none) readable, never a partial one. Throws
// std::runtime_error on I/O failure; array sizes must match points and bonds.
void write_checkpoint(const std::filesystem::path& file, const Checkpoint& c);

// A checkpoint written by N MPI ranks at once, none of which holds the whole body: each rank
// writes a part (its owned points' global ids, u, v, f and the states of their bond rows, row
// after row) at checkpoint_part_path(file, rank, step), then rank 0 writes `file` as an index:
// the root attributes above plus `parts` and `part_name` (the index's file name, which the
// parts' names extend), without datasets. The index is written last and replaced atomically,
// and a part's name holds its step, so a run killed at any moment leaves an index whose parts
// are all on disk. read_checkpoint reads either kind whole, finding the parts in the index's
// directory.
struct CheckpointPart {
  std::uint64_t step = 0;
  int part = 0, parts = 1;
  std::vector<std::uint64_t> ids;               // global point ids, any order
  std::array<std::vector<double>, 3> u, v, f;   // per listed point
  std::vector<std::uint64_t> row_bonds;         // bond states per listed point
  std::vector<std::uint8_t> bond_state;         // their rows, one after another
  // The box of the listed points' reference positions (lo x, y, z, hi x, y, z), where the writer
  // knows them: a reader looking for points elsewhere skips the part (dataset box, optional).
  std::optional<std::array<double, 6>> box;
};
std::filesystem::path checkpoint_part_path(const std::filesystem::path& file, int part, std::uint64_t step);
// Both write under a .tmp name, flush, and rename; they throw std::runtime_error on I/O failure.
void write_checkpoint_part(const std::filesystem::path& file, const CheckpointPart& p);
// `c`'s attributes (its arrays are not written) and the number of parts.
void write_checkpoint_index(const std::filesystem::path& file, const Checkpoint& c, int parts);

// Reads and checks a checkpoint: a missing, truncated or foreign file, another format version,
// an HDF5 file without metadata checksums (superblock version < 2), sizes the file cannot hold,
// arrays whose sizes disagree with points and bonds, non-finite values (dt, time,
// external_work, u, v, f), dt <= 0, or a time other than step x dt throw std::runtime_error
// naming the file and the attribute or dataset. An index also needs every part, each of its
// step, holding each point once and together the bonds the index counts.
Checkpoint read_checkpoint(const std::filesystem::path& file);

// A checkpoint's root attributes only (no array is read), with the number of parts of an index
// in `parts` (0: a whole checkpoint). Throws as read_checkpoint does on a file it cannot open.
Checkpoint read_checkpoint_attributes(const std::filesystem::path& file, int& parts);
// Whether `file` is the index of a checkpoint in parts (false: a whole checkpoint).
bool checkpoint_in_parts(const std::filesystem::path& file);

// The points `ids` (ascending global ids) of a checkpoint in parts, for an MPI rank that holds
// only those: the attributes; u, v and f per listed point, in that order; their bond rows one
// after another, and row_bonds per listed point. Parts are read one at a time, so the memory is
// the largest part's plus the result, never the whole body. Checks as read_checkpoint does,
// except that a point nobody asked for is not checked for being listed twice (the parts' point
// and bond totals are).
// `where`: the box of the listed points' reference positions, where the reader knows it; parts
// whose box (CheckpointPart::box) lies apart from it hold none of them, and only their counts
// are read.
Checkpoint read_checkpoint_points(const std::filesystem::path& file, std::span<const std::int64_t> ids,
                                  const std::optional<std::array<double, 6>>& where = std::nullopt);

// The same from a whole (one-file) checkpoint, whose rows the reader locates itself: row_start
// and row_bonds per listed point (parallel::row_starts from the deck's rows). Reads only those
// points' u, v, f and rows, never the whole body. Checks as read_checkpoint does.
Checkpoint read_whole_checkpoint_points(const std::filesystem::path& file, std::span<const std::int64_t> ids, std::span<const std::uint64_t> row_start,
                                        std::span<const std::uint64_t> row_bonds);

}  // namespace peridot

namespace peridot {

namespace {

// An HDF5 identifier closed on scope exit.
class Handle {
 public:
  Handle(hid_t id, herr_t (*close)(hid_t)) : id_(id), close_(close) {}
  ~Handle() {
    if (id_ >= 0) close_(id_);
  }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  Handle(Handle&& o) noexcept : id_(std::exchange(o.id_, -1)), close_(o.close_) {}
  Handle& operator=(Handle&&) = delete;
  hid_t get() const { return id_; }
  bool ok() const { return id_ >= 0; }

 private:
  hid_t id_;
  herr_t (*close_)(hid_t);
};

// HDF5 prints its error stack by default; this library reports errors itself.
void quiet_hdf5() { H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr); }

// File access without locks: a checkpoint is written under its own .tmp name and read only
// after the rename, and HDF5's locks fail on some parallel file systems.
void no_file_locking([[maybe_unused]] hid_t fapl) {
#if H5_VERSION_GE(1, 10, 7)
  H5Pset_file_locking(fapl, false, true);
#endif
}

// HDF5's 1.8 file format and later (superblock version 2 or more) checksum every piece of
// metadata, and HDF5 verifies them before decoding any: a corrupt checkpoint is refused
// cleanly. The older format has no checksums, and libhdf5 (1.10) overruns buffers and
// allocates without bound on a corrupt one, so read_checkpoint refuses it unread.
void checksummed_metadata(hid_t fapl) {
  if (H5Pset_libver_bounds(fapl, H5F_LIBVER_V18, H5F_LIBVER_LATEST) < 0) throw std::runtime_error("HDF5: cannot select the 1.8 file format");
}
constexpr unsigned min_superblock_version = 2;

// ---- writing ----

struct Writer {
  hid_t file;
  std::string name;

  void check(herr_t status, const std::string& what) const {
    if (status < 0) throw std::runtime_error(fmt::format("{}: cannot write {}", name, what));
  }
  void attribute(const char* key, hid_t type, const void* value) const {
    Handle space(H5Screate(H5S_SCALAR), H5Sclose);
    Handle a(H5Acreate2(file, key, type, space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
    if (!a.ok()) check(-1, key);
    check(H5Awrite(a.get(), type, value), key);
  }
  void text(const char* key, const std::string& value) const {
    Handle type(H5Tcopy(H5T_C_S1), H5Tclose);
    check(H5Tset_size(type.get(), value.empty() ? 1 : value.size()), key);
    attribute(key, type.get(), value.empty() ? "" : value.data());
  }
  void dataset(const char* key, hid_t type, int rank, const hsize_t* dims, const void* data) const {
    Handle space(H5Screate_simple(rank, dims, nullptr), H5Sclose);
    Handle d(H5Dcreate2(file, key, type, space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Dclose);
    if (!d.ok()) check(-1, key);
    // An empty dataset has no data to write (a zero-sized H5Dwrite is still valid, but skip it).
    bool empty = false;
    for (int k = 0; k < rank; ++k) empty = empty || dims[k] == 0;
    if (!empty) check(H5Dwrite(d.get(), type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), key);
  }
};

// fsync a file or directory, so the rename below publishes data that is on disk.
void sync_path(const std::filesystem::path& p, int flags) {
  const int fd = ::open(p.c_str(), flags);
  if (fd < 0) throw std::runtime_error(fmt::format("{}: cannot open to sync", p.string()));
  const int rc = ::fsync(fd);
  ::close(fd);
  if (rc != 0) throw std::runtime_error(fmt::format("{}: fsync failed", p.string()));
}

// A new HDF5 file in the checksummed format.
Handle create_file(const std::filesystem::path& tmp) {
  Handle fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
  no_file_locking(fapl.get());
  checksummed_metadata(fapl.get());
  Handle file(H5Fcreate(tmp.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl.get()), H5Fclose);
  if (!file.ok()) throw std::runtime_error(fmt::format("{}: cannot create checkpoint file", tmp.string()));
  return file;
}

void flush(const Handle& file, const std::filesystem::path& tmp) {
  if (H5Fflush(file.get(), H5F_SCOPE_GLOBAL) < 0) throw std::runtime_error(fmt::format("{}: cannot flush checkpoint", tmp.string()));
}

// The root attributes of a whole checkpoint or an index.
void write_header(const Writer& w, const Checkpoint& c) {
  const int version = checkpoint_format_version;
  w.text("format", "peridot-checkpoint");
  w.attribute("version", H5T_NATIVE_INT, &version);
  w.text("deck_name", c.deck_name);
  w.attribute("deck_hash", H5T_NATIVE_UINT64, &c.deck_hash);
  w.attribute("dim", H5T_NATIVE_INT, &c.dim);
  w.attribute("points", H5T_NATIVE_UINT64, &c.points);
  w.attribute("bonds", H5T_NATIVE_UINT64, &c.bonds);
  w.attribute("dt", H5T_NATIVE_DOUBLE, &c.dt);
  w.text("scheme", c.scheme);
  w.attribute("step", H5T_NATIVE_UINT64, &c.step);
  w.attribute("time", H5T_NATIVE_DOUBLE, &c.time);
  w.attribute("external_work", H5T_NATIVE_DOUBLE, &c.external_work);
  w.attribute("broken", H5T_NATIVE_UINT64, &c.broken);
  if (!c.bond_layout.empty()) w.text("bond_layout", c.bond_layout);
}

// u, v and f as 3 x n datasets.
void write_fields(const Writer& w, const std::array<std::vector<double>, 3>& u, const std::array<std::vector<double>, 3>& v,
                  const std::array<std::vector<double>, 3>& f, std::uint64_t n) {
  const std::array<std::pair<const char*, const std::array<std::vector<double>, 3>*>, 3> fields{{{"u", &u}, {"v", &v}, {"f", &f}}};
  std::vector<double> rows(3 * n);
  for (const auto& [key, field] : fields) {
    for (int k = 0; k < 3; ++k) std::copy((*field)[k].begin(), (*field)[k].end(), rows.begin() + std::ptrdiff_t(k * n));
    const hsize_t dims[2] = {3, n};
    w.dataset(key, H5T_NATIVE_DOUBLE, 2, dims, rows.data());
  }
}

void write_hdf5(const std::filesystem::path& tmp, const Checkpoint& c) {
  const Handle file = create_file(tmp);
  const Writer w{file.get(), tmp.string()};
  write_header(w, c);
  write_fields(w, c.u, c.v, c.f, c.points);
  const hsize_t nb[1] = {c.bonds};
  w.dataset("bond_state", H5T_NATIVE_UINT8, 1, nb, c.bond_state.data());
  flush(file, tmp);
}

void write_index(const std::filesystem::path& tmp, const Checkpoint& c, int parts, const std::string& name) {
  const Handle file = create_file(tmp);
  const Writer w{file.get(), tmp.string()};
  write_header(w, c);
  w.attribute("parts", H5T_NATIVE_INT, &parts);
  // The parts are named after the index as written; a copied or renamed index finds them in
  // its own directory under that name.
  w.text("part_name", name);
  flush(file, tmp);
}

void write_part(const std::filesystem::path& tmp, const CheckpointPart& p) {
  const Handle file = create_file(tmp);
  const Writer w{file.get(), tmp.string()};
  const int version = checkpoint_format_version;
  const std::uint64_t n = p.ids.size(), bonds = p.bond_state.size();
  w.text("format", "peridot-checkpoint-part");
  w.attribute("version", H5T_NATIVE_INT, &version);
  w.attribute("step", H5T_NATIVE_UINT64, &p.step);
  w.attribute("part", H5T_NATIVE_INT, &p.part);
  w.attribute("parts", H5T_NATIVE_INT, &p.parts);
  w.attribute("points", H5T_NATIVE_UINT64, &n);
  w.attribute("bonds", H5T_NATIVE_UINT64, &bonds);
  const hsize_t np[1] = {n}, nb[1] = {bonds};
  w.dataset("ids", H5T_NATIVE_UINT64, 1, np, p.ids.data());
  write_fields(w, p.u, p.v, p.f, n);
  w.dataset("row_bonds", H5T_NATIVE_UINT64, 1, np, p.row_bonds.data());
  w.dataset("bond_state", H5T_NATIVE_UINT8, 1, nb, p.bond_state.data());
  if (p.box) {
    const hsize_t six[1] = {6};
    w.dataset("box", H5T_NATIVE_DOUBLE, 1, six, p.box->data());
  }
  flush(file, tmp);
}

// ---- reading ----

struct Reader {
  hid_t file;
  std::string name;

  [[noreturn]] void fail(const std::string& what) const {
    throw std::runtime_error(fmt::format("{}: not a readable Peridot checkpoint: {}", name, what));
  }
  void attribute(const char* key, hid_t type, void* value) const {
    if (H5Aexists(file, key) <= 0) fail(fmt::format("attribute '{}' is missing", key));
    Handle a(H5Aopen(file, key, H5P_DEFAULT), H5Aclose);
    if (!a.ok() || H5Aread(a.get(), type, value) < 0) fail(fmt::format("attribute '{}' cannot be read", key));
  }
  std::string text(const char* key) const {
    if (H5Aexists(file, key) <= 0) fail(fmt::format("attribute '{}' is missing", key));
    Handle a(H5Aopen(file, key, H5P_DEFAULT), H5Aclose);
    Handle type(a.ok() ? H5Aget_type(a.get()) : -1, H5Tclose);
    if (!type.ok() || H5Tget_class(type.get()) != H5T_STRING || H5Tis_variable_str(type.get()) != 0)
      fail(fmt::format("attribute '{}' is not a fixed-length string", key));
    const std::size_t size = H5Tget_size(type.get());
    if (size == 0 || size > (1u << 20)) fail(fmt::format("attribute '{}' has size {}", key, size));
    std::string s(size, '\0');
    if (H5Aread(a.get(), type.get(), s.data()) < 0) fail(fmt::format("attribute '{}' cannot be read", key));
    s.resize(s.find('\0') == std::string::npos ? s.size() : s.find('\0'));
    return s;
  }
  // Reads a dataset whose shape must be exactly `dims`.
  void dataset(const char* key, hid_t type, int rank, const hsize_t* dims, void* data) const {
    if (H5Lexists(file, key, H5P_DEFAULT) <= 0) fail(fmt::format("dataset '{}' is missing", key));
    Handle d(H5Dopen2(file, key, H5P_DEFAULT), H5Dclose);
    Handle space(d.ok() ? H5Dget_space(d.get()) : -1, H5Sclose);
    if (!space.ok()) fail(fmt::format("dataset '{}' cannot be opened", key));
    hsize_t got[2] = {0, 0};
    const int r = H5Sget_simple_extent_ndims(space.get());
    if (r != rank || H5Sget_simple_extent_dims(space.get(), got, nullptr) != rank)
      fail(fmt::format("dataset '{}' has rank {}, expected {}", key, r, rank));
    bool empty = false;
    for (int k = 0; k < rank; ++k) {
      if (got[k] != dims[k]) fail(fmt::format("dataset '{}' has {} entries along axis {}, expected {}", key, got[k], k, dims[k]));
      empty = empty || dims[k] == 0;
    }
    if (!empty && H5Dread(d.get(), type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0)
      fail(fmt::format("dataset '{}' cannot be read (truncated file?)", key));
  }
  // Reads the runs [start, start + count) along the last axis of a dataset shaped `dims`
  // (every row of the first axis where rank = 2), row after row, runs in the given order
  // (ascending, apart), into data.
  void runs(const char* key, hid_t type, int rank, const hsize_t* dims, const std::vector<std::pair<hsize_t, hsize_t>>& runs, void* data) const {
    if (H5Lexists(file, key, H5P_DEFAULT) <= 0) fail(fmt::format("dataset '{}' is missing", key));
    Handle d(H5Dopen2(file, key, H5P_DEFAULT), H5Dclose);
    Handle space(d.ok() ? H5Dget_space(d.get()) : -1, H5Sclose);
    if (!space.ok()) fail(fmt::format("dataset '{}' cannot be opened", key));
    hsize_t got[2] = {0, 0};
    if (H5Sget_simple_extent_ndims(space.get()) != rank || H5Sget_simple_extent_dims(space.get(), got, nullptr) != rank)
      fail(fmt::format("dataset '{}' does not have rank {}", key, rank));
    for (int k = 0; k < rank; ++k)
      if (got[k] != dims[k]) fail(fmt::format("dataset '{}' has {} entries along axis {}, expected {}", key, got[k], k, dims[k]));
    hsize_t total = 0;
    H5Sselect_none(space.get());
    for (const auto& [start, count] : runs) {
      if (count == 0) continue;
      const hsize_t at[2] = {0, start}, n[2] = {rank == 2 ? dims[0] : count, count};
      const hsize_t at1[1] = {start}, n1[1] = {count};
      if (H5Sselect_hyperslab(space.get(), H5S_SELECT_OR, rank == 2 ? at : at1, nullptr, rank == 2 ? n : n1, nullptr) < 0)
        fail(fmt::format("dataset '{}': cannot select entries {} to {}", key, start, start + count));
      total += count;
    }
    if (total == 0) return;
    const hsize_t all[1] = {total * (rank == 2 ? dims[0] : 1)};
    Handle memory(H5Screate_simple(1, all, nullptr), H5Sclose);
    if (H5Dread(d.get(), type, memory.get(), space.get(), H5P_DEFAULT, data) < 0)
      fail(fmt::format("dataset '{}' cannot be read (truncated file?)", key));
  }
};

// Writes through `write` into <file>.tmp, syncs it and renames it over `file`.
void publish(const std::filesystem::path& file, const std::function<void(const std::filesystem::path&)>& write) {
  quiet_hdf5();
  const std::filesystem::path tmp = file.string() + ".tmp";
  // A failed write (a full disk) leaves the last checkpoint as it was and no .tmp behind.
  try {
    write(tmp);
    sync_path(tmp, O_RDONLY);
    std::error_code ec;
    std::filesystem::rename(tmp, file, ec);
    if (ec) throw std::runtime_error(fmt::format("cannot rename {} to {}: {}", tmp.string(), file.string(), ec.message()));
  } catch (const std::exception& e) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw std::runtime_error(fmt::format("cannot write checkpoint {}: {}", file.string(), e.what()));
  }
  const auto dir = file.parent_path().empty() ? std::filesystem::path(".") : file.parent_path();
  sync_path(dir, O_RDONLY | O_DIRECTORY);
}

}  // namespace

void write_checkpoint(const std::filesystem::path& file, const Checkpoint& c) {
  for (const auto* field : {&c.u, &c.v, &c.f})
    for (const auto& comp : *field)
      if (comp.size() != c.points) throw std::invalid_argument(fmt::format("checkpoint: a field has {} values for {} points", comp.size(), c.points));
  if (c.bond_state.size() != c.bonds)
    throw std::invalid_argument(fmt::format("checkpoint: bond_state has {} entries for {} bonds", c.bond_state.size(), c.bonds));
  publish(file, [&](const std::filesystem::path& tmp) { write_hdf5(tmp, c); });
}

std::filesystem::path checkpoint_part_path(const std::filesystem::path& file, int part, std::uint64_t step) {
  return file.string() + fmt::format(".part{}.step{}", part, step);
}

void write_checkpoint_part(const std::filesystem::path& file, const CheckpointPart& p) {
  const std::size_t n = p.ids.size();
  for (const auto* field : {&p.u, &p.v, &p.f})
    for (const auto& comp : *field)
      if (comp.size() != n) throw std::invalid_argument(fmt::format("checkpoint part: a field has {} values for {} points", comp.size(), n));
  if (p.row_bonds.size() != n) throw std::invalid_argument(fmt::format("checkpoint part: {} row lengths for {} points", p.row_bonds.size(), n));
  std::uint64_t total = 0;
  for (auto b : p.row_bonds) total += b;
  if (total != p.bond_state.size())
    throw std::invalid_argument(fmt::format("checkpoint part: rows of {} bonds, {} states", total, p.bond_state.size()));
  publish(checkpoint_part_path(file, p.part, p.step), [&](const std::filesystem::path& tmp) { write_part(tmp, p); });
}

void write_checkpoint_index(const std::filesystem::path& file, const Checkpoint& c, int parts) {
  if (parts < 1) throw std::invalid_argument(fmt::format("checkpoint index: {} parts", parts));
  publish(file, [&](const std::filesystem::path& tmp) { write_index(tmp, c, parts, file.filename().string()); });
}

namespace {

// HDF5's signature, then the superblock version (HDF5 spec, "Superblock"). Peridot writes no
// user block, so the signature is at offset 0.
unsigned superblock_version(const std::filesystem::path& file) {
  constexpr unsigned char signature[8] = {0x89, 'H', 'D', 'F', '\r', '\n', 0x1a, '\n'};
  unsigned char head[9] = {};
  std::FILE* f = std::fopen(file.c_str(), "rb");
  const std::size_t got = f ? std::fread(head, 1, sizeof head, f) : 0;
  if (f) std::fclose(f);
  if (got < sizeof head || std::memcmp(head, signature, sizeof signature) != 0)
    throw std::runtime_error(fmt::format("{}: not a readable Peridot checkpoint: not an HDF5 file (truncated or corrupt?)", file.string()));
  return head[8];
}

// The first non-finite value of a field, as "component k, point i = value", or "".
std::string first_non_finite(const std::array<std::vector<double>, 3>& field) {
  for (std::size_t k = 0; k < 3; ++k)
    for (std::size_t i = 0; i < field[k].size(); ++i)
      if (!std::isfinite(field[k][i])) return fmt::format("component {}, point {} = {}", k, i, field[k][i]);
  return "";
}

// What a run needs of the numbers: finite, dt > 0, and time = step x dt as the solver computes
// it (t = double(step) * dt, so equal but for a few ulps; step 0 is t = 0 exactly).
void check_values(const Reader& r, const Checkpoint& c) {
  if (!std::isfinite(c.dt) || !(c.dt > 0)) r.fail(fmt::format("attribute 'dt' = {} s; allowed a finite number > 0", c.dt));
  if (!std::isfinite(c.time)) r.fail(fmt::format("attribute 'time' = {} s; allowed a finite number", c.time));
  if (!std::isfinite(c.external_work)) r.fail(fmt::format("attribute 'external_work' = {} J; allowed a finite number", c.external_work));
  const double expected = double(c.step) * c.dt;
  const double tolerance = 4 * std::numeric_limits<double>::epsilon() * std::abs(expected);
  if (c.step == 0 ? c.time != 0 : !(std::abs(c.time - expected) <= tolerance))
    r.fail(fmt::format("attribute 'time' = {:.17g} s is not step x dt = {} x {:.17g} s = {:.17g} s (to 4 ulps)", c.time, c.step, c.dt,
                       expected));
  for (const auto& [key, field] : {std::pair{"u", &c.u}, std::pair{"v", &c.v}, std::pair{"f", &c.f}})
    if (const auto bad = first_non_finite(*field); !bad.empty()) r.fail(fmt::format("dataset '{}' holds a non-finite value: {}", key, bad));
}

}  // namespace

namespace {

// Opens a file that must be checksummed HDF5, before libhdf5 decodes anything of it.
Handle open_checked(const std::filesystem::path& file) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec))
    throw std::runtime_error(fmt::format("{}: cannot open checkpoint file (missing, or not a regular file)", file.string()));
  quiet_hdf5();
  // Before HDF5 decodes anything: only checksummed metadata is safe to hand to libhdf5.
  if (const unsigned sb = superblock_version(file); sb < min_superblock_version)
    throw std::runtime_error(fmt::format("{}: not a readable Peridot checkpoint: HDF5 superblock version {}, without metadata checksums; "
                                         "Peridot writes and reads version {} or later (a checkpoint from an older Peridot: rerun)",
                                         file.string(), sb, min_superblock_version));
  if (H5Fis_hdf5(file.c_str()) <= 0)
    throw std::runtime_error(fmt::format("{}: not a readable Peridot checkpoint: not an HDF5 file (truncated or corrupt?)", file.string()));
  Handle fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
  no_file_locking(fapl.get());
  Handle h(H5Fopen(file.c_str(), H5F_ACC_RDONLY, fapl.get()), H5Fclose);
  if (!h.ok()) throw std::runtime_error(fmt::format("{}: not a readable Peridot checkpoint: HDF5 cannot open it (truncated or corrupt?)", file.string()));
  return h;
}

void require_format(const Reader& r, const char* format) {
  if (r.text("format") != format) r.fail(fmt::format("attribute 'format' is not '{}'", format));
  int version = 0;
  r.attribute("version", H5T_NATIVE_INT, &version);
  if (version != checkpoint_format_version)
    r.fail(fmt::format("format version {}; this build reads version {}", version, checkpoint_format_version));
}

// Sizes come from the file: bound them by what it can hold (`per_point` bytes a point, one a
// bond) before allocating, in floating point so that nothing wraps.
void require_room(const Reader& r, const std::filesystem::path& file, std::uint64_t points, std::uint64_t bonds, double per_point) {
  std::error_code ec;
  const auto bytes = std::filesystem::file_size(file, ec);
  if (ec || double(points) * per_point + double(bonds) > double(bytes))
    r.fail(fmt::format("attributes 'points' = {} and 'bonds' = {} need {:.4g} bytes of data; the file has {}", points, bonds,
                       double(points) * per_point + double(bonds), ec ? 0 : bytes));
  if (points > std::uint64_t(INT32_MAX)) r.fail(fmt::format("attribute 'points' = {}; at most 2^31 - 1 points are indexed", points));
}

// Reads u, v and f (3 x n) into the first n entries of each component; with `points`, only
// those runs of the datasets' `n` columns, `count` points in all.
void read_fields(const Reader& r, std::uint64_t n, std::array<std::array<std::vector<double>, 3>*, 3> out,
                 const std::vector<std::pair<hsize_t, hsize_t>>* points = nullptr, std::uint64_t count = 0) {
  if (!points) count = n;
  std::vector<double> rows(3 * count);
  const hsize_t dims[2] = {3, n};
  const char* keys[3] = {"u", "v", "f"};
  for (std::size_t q = 0; q < 3; ++q) {
    if (points) r.runs(keys[q], H5T_NATIVE_DOUBLE, 2, dims, *points, rows.data());
    else r.dataset(keys[q], H5T_NATIVE_DOUBLE, 2, dims, rows.data());
    for (std::size_t k = 0; k < 3; ++k)
      (*out[q])[k].assign(rows.begin() + std::ptrdiff_t(k * count), rows.begin() + std::ptrdiff_t((k + 1) * count));
  }
}

// One part of an index, read and checked against the index's attributes.
struct Piece {
  std::uint64_t points = 0, bonds = 0;  // the part's counts, read even where its arrays are not
  std::vector<std::uint64_t> ids, row_bonds;
  std::vector<std::uint8_t> states;
  std::array<std::vector<double>, 3> u, v, f;
};

std::string part_name(const Reader& index) {
  const std::string name = index.text("part_name");
  if (name.empty() || name.find('/') != std::string::npos) index.fail(fmt::format("attribute 'part_name' = '{}' is not a file name", name));
  return name;
}

// Whether two boxes (lo x, y, z, hi x, y, z) share a point.
bool boxes_meet(const std::array<double, 6>& a, const std::array<double, 6>& b) {
  for (std::size_t k = 0; k < 3; ++k)
    if (a[k + 3] < b[k] || b[k + 3] < a[k]) return false;
  return true;
}

// `where`: skip the arrays of a part whose box lies apart from it.
Piece read_piece(const std::filesystem::path& file, const Reader& index, const std::string& name, const Checkpoint& c, int p, int parts,
                 const std::optional<std::array<double, 6>>& where = std::nullopt) {
  const auto path = checkpoint_part_path(file.parent_path() / name, p, c.step);
  if (!std::filesystem::exists(path))
    index.fail(fmt::format("part {} of {} ({}) is missing; a checkpoint written on {} ranks needs all its parts beside it", p, parts,
                           path.string(), parts));
  const Handle h = open_checked(path);
  const Reader r{h.get(), path.string()};
  require_format(r, "peridot-checkpoint-part");
  std::uint64_t step = 0, n = 0, nb = 0;
  int part = -1, of = 0;
  r.attribute("step", H5T_NATIVE_UINT64, &step);
  r.attribute("part", H5T_NATIVE_INT, &part);
  r.attribute("parts", H5T_NATIVE_INT, &of);
  r.attribute("points", H5T_NATIVE_UINT64, &n);
  r.attribute("bonds", H5T_NATIVE_UINT64, &nb);
  if (step != c.step || part != p || of != parts)
    r.fail(fmt::format("it is part {} of {} at step {}; the index {} needs part {} of {} at step {}", part, of, step, file.string(), p, parts,
                       c.step));
  require_room(r, path, n, nb, 88);
  if (n > c.points || nb > c.bonds) r.fail(fmt::format("{} points and {} bonds; the whole body has {} and {}", n, nb, c.points, c.bonds));
  Piece piece;
  piece.points = n;
  piece.bonds = nb;
  if (where && H5Lexists(h.get(), "box", H5P_DEFAULT) > 0) {
    std::array<double, 6> box{};
    const hsize_t six[1] = {6};
    r.dataset("box", H5T_NATIVE_DOUBLE, 1, six, box.data());
    if (!boxes_meet(box, *where)) return piece;
  }
  piece.ids.resize(n);
  piece.row_bonds.resize(n);
  piece.states.resize(nb);
  const hsize_t np[1] = {n}, nbs[1] = {nb};
  r.dataset("ids", H5T_NATIVE_UINT64, 1, np, piece.ids.data());
  r.dataset("row_bonds", H5T_NATIVE_UINT64, 1, np, piece.row_bonds.data());
  r.dataset("bond_state", H5T_NATIVE_UINT8, 1, nbs, piece.states.data());
  read_fields(r, n, {&piece.u, &piece.v, &piece.f});
  std::uint64_t sum = 0;
  for (std::size_t j = 0; j < n; ++j) {
    if (piece.ids[j] >= c.points) r.fail(fmt::format("dataset 'ids' holds point {}; the body has {}", piece.ids[j], c.points));
    if (piece.row_bonds[j] > nb - sum) r.fail(fmt::format("dataset 'row_bonds' lists more than the part's {} bond states", nb));
    sum += piece.row_bonds[j];
  }
  if (sum != nb) r.fail(fmt::format("dataset 'row_bonds' sums to {}, not the part's {} bond states", sum, nb));
  return piece;
}

// An index's parts, put together in global order: u, v, f by point id, and the bond rows in
// point order (the whole body's bond order).
void read_parts(const std::filesystem::path& file, const Reader& index, Checkpoint& c, int parts) {
  std::vector<std::uint64_t> row(c.points, std::numeric_limits<std::uint64_t>::max());  // bonds per point; max: not seen yet
  for (auto* field : {&c.u, &c.v, &c.f})
    for (auto& comp : *field) comp.assign(c.points, 0.0);
  std::vector<Piece> pieces;
  std::uint64_t bonds = 0;
  const std::string name = part_name(index);
  for (int p = 0; p < parts; ++p) {
    Piece piece = read_piece(file, index, name, c, p, parts);
    for (std::size_t j = 0; j < piece.ids.size(); ++j) {
      const auto id = piece.ids[j];
      if (row[id] != std::numeric_limits<std::uint64_t>::max()) index.fail(fmt::format("point {} is listed twice among the parts", id));
      row[id] = piece.row_bonds[j];
      for (std::size_t k = 0; k < 3; ++k) c.u[k][id] = piece.u[k][j], c.v[k][id] = piece.v[k][j], c.f[k][id] = piece.f[k][j];
    }
    bonds += piece.states.size();
    for (auto* field : {&piece.u, &piece.v, &piece.f})
      for (auto& comp : *field) comp = {};
    pieces.push_back(std::move(piece));
  }
  for (std::uint64_t i = 0; i < c.points; ++i)
    if (row[i] == std::numeric_limits<std::uint64_t>::max()) index.fail(fmt::format("no part holds point {}", i));
  if (bonds != c.bonds) index.fail(fmt::format("the parts hold {} bond states; attribute 'bonds' = {}", bonds, c.bonds));
  // Rows in point order.
  std::vector<std::uint64_t> start(c.points + 1, 0);
  for (std::uint64_t i = 0; i < c.points; ++i) start[i + 1] = start[i] + row[i];
  c.bond_state.resize(c.bonds);
  for (const auto& piece : pieces) {
    std::uint64_t at = 0;
    for (std::size_t j = 0; j < piece.ids.size(); ++j) {
      std::copy_n(piece.states.begin() + std::ptrdiff_t(at), piece.row_bonds[j], c.bond_state.begin() + std::ptrdiff_t(start[piece.ids[j]]));
      at += piece.row_bonds[j];
    }
  }
}

// The root attributes every checkpoint file has; `parts` gets the index's part count (0 for a
// whole checkpoint).
Checkpoint read_header(const Reader& r, hid_t file, int& parts) {
  require_format(r, "peridot-checkpoint");
  Checkpoint c;
  c.deck_name = r.text("deck_name");
  r.attribute("deck_hash", H5T_NATIVE_UINT64, &c.deck_hash);
  r.attribute("dim", H5T_NATIVE_INT, &c.dim);
  r.attribute("points", H5T_NATIVE_UINT64, &c.points);
  r.attribute("bonds", H5T_NATIVE_UINT64, &c.bonds);
  r.attribute("dt", H5T_NATIVE_DOUBLE, &c.dt);
  c.scheme = r.text("scheme");
  r.attribute("step", H5T_NATIVE_UINT64, &c.step);
  r.attribute("time", H5T_NATIVE_DOUBLE, &c.time);
  r.attribute("external_work", H5T_NATIVE_DOUBLE, &c.external_work);
  r.attribute("broken", H5T_NATIVE_UINT64, &c.broken);
  if (c.dim < 1 || c.dim > 3) r.fail(fmt::format("attribute 'dim' = {}; allowed 1, 2 or 3", c.dim));
  if (H5Aexists(file, "bond_layout") > 0) {
    c.bond_layout = r.text("bond_layout");
    if (c.bond_layout != "point_offsets") r.fail(fmt::format("attribute 'bond_layout' = '{}'; allowed 'point_offsets'", c.bond_layout));
  }
  parts = 0;
  if (H5Aexists(file, "parts") > 0) {
    r.attribute("parts", H5T_NATIVE_INT, &parts);
    if (parts < 1 || parts > (1 << 20)) r.fail(fmt::format("attribute 'parts' = {}; allowed 1 to 2^20", parts));
    if (c.points > std::uint64_t(INT32_MAX)) r.fail(fmt::format("attribute 'points' = {}; at most 2^31 - 1 points are indexed", c.points));
  }
  return c;
}

}  // namespace

Checkpoint read_checkpoint(const std::filesystem::path& file) {
  const Handle h = open_checked(file);
  const Reader r{h.get(), file.string()};
  int parts = 0;
  Checkpoint c = read_header(r, h.get(), parts);
  if (parts > 0) {
    read_parts(file, r, c, parts);
  } else {
    // 72 bytes a point for u, v and f, one a bond.
    require_room(r, file, c.points, c.bonds, 72);
    read_fields(r, c.points, {&c.u, &c.v, &c.f});
    c.bond_state.resize(c.bonds);
    const hsize_t nb[1] = {c.bonds};
    r.dataset("bond_state", H5T_NATIVE_UINT8, 1, nb, c.bond_state.data());
  }
  check_values(r, c);
  return c;
}

Checkpoint read_checkpoint_attributes(const std::filesystem::path& file, int& parts) {
  const Handle h = open_checked(file);
  const Reader r{h.get(), file.string()};
  return read_header(r, h.get(), parts);
}

bool checkpoint_in_parts(const std::filesystem::path& file) {
  int parts = 0;
  read_checkpoint_attributes(file, parts);
  return parts > 0;
}

Checkpoint read_checkpoint_points(const std::filesystem::path& file, std::span<const std::int64_t> ids,
                                  const std::optional<std::array<double, 6>>& where) {
  const Handle h = open_checked(file);
  const Reader r{h.get(), file.string()};
  int parts = 0;
  Checkpoint c = read_header(r, h.get(), parts);
  if (parts == 0) r.fail("it is a whole checkpoint, not an index of parts");
  for (std::size_t j = 0; j < ids.size(); ++j)
    if (ids[j] < 0 || std::uint64_t(ids[j]) >= c.points || (j > 0 && ids[j] <= ids[j - 1]))
      throw std::invalid_argument(fmt::format("read_checkpoint_points: ids must ascend within the checkpoint's {} points", c.points));
  const std::size_t n = ids.size();
  for (auto* field : {&c.u, &c.v, &c.f})
    for (auto& comp : *field) comp.assign(n, 0.0);
  c.row_bonds.assign(n, std::numeric_limits<std::uint64_t>::max());
  // Rows arrive part by part: kept per listed point, then laid out in the listed order.
  std::vector<std::vector<std::uint8_t>> rows(n);
  const std::string name = part_name(r);
  std::uint64_t points = 0, bonds = 0;
  for (int p = 0; p < parts; ++p) {
    const Piece piece = read_piece(file, r, name, c, p, parts, where);
    points += piece.points;
    bonds += piece.bonds;
    std::uint64_t at = 0;
    for (std::size_t j = 0; j < piece.ids.size(); at += piece.row_bonds[j], ++j) {
      const auto it = std::lower_bound(ids.begin(), ids.end(), std::int64_t(piece.ids[j]));
      if (it == ids.end() || *it != std::int64_t(piece.ids[j])) continue;
      const auto q = std::size_t(it - ids.begin());
      if (c.row_bonds[q] != std::numeric_limits<std::uint64_t>::max()) r.fail(fmt::format("point {} is listed twice among the parts", piece.ids[j]));
      c.row_bonds[q] = piece.row_bonds[j];
      rows[q].assign(piece.states.begin() + std::ptrdiff_t(at), piece.states.begin() + std::ptrdiff_t(at + piece.row_bonds[j]));
      for (std::size_t k = 0; k < 3; ++k) c.u[k][q] = piece.u[k][j], c.v[k][q] = piece.v[k][j], c.f[k][q] = piece.f[k][j];
    }
  }
  if (points != c.points) r.fail(fmt::format("the parts hold {} points; attribute 'points' = {}", points, c.points));
  if (bonds != c.bonds) r.fail(fmt::format("the parts hold {} bond states; attribute 'bonds' = {}", bonds, c.bonds));
  for (std::size_t q = 0; q < n; ++q) {
    if (c.row_bonds[q] == std::numeric_limits<std::uint64_t>::max()) r.fail(fmt::format("no part holds point {}", ids[q]));
    c.bond_state.insert(c.bond_state.end(), rows[q].begin(), rows[q].end());
  }
  check_values(r, c);
  return c;
}

Checkpoint read_whole_checkpoint_points(const std::filesystem::path& file, std::span<const std::int64_t> ids, std::span<const std::uint64_t> row_start,
                                        std::span<const std::uint64_t> row_bonds) {
  const Handle h = open_checked(file);
  const Reader r{h.get(), file.string()};
  int parts = 0;
  Checkpoint c = read_header(r, h.get(), parts);
  if (parts > 0) r.fail("it is an index of parts, not a whole checkpoint");
  if (ids.size() != row_start.size() || ids.size() != row_bonds.size())
    throw std::invalid_argument("read_whole_checkpoint_points: ids, row_start and row_bonds differ in length");
  require_room(r, file, c.points, c.bonds, 72);
  const std::size_t n = ids.size();
  std::vector<std::pair<hsize_t, hsize_t>> points, rows;
  for (std::size_t j = 0; j < n; ++j) {
    if (ids[j] < 0 || std::uint64_t(ids[j]) >= c.points || (j > 0 && ids[j] <= ids[j - 1]))
      throw std::invalid_argument(fmt::format("read_whole_checkpoint_points: ids must ascend within the checkpoint's {} points", c.points));
    if (row_start[j] > c.bonds || row_bonds[j] > c.bonds - row_start[j])
      r.fail(fmt::format("point {}'s row ends at bond {}; attribute 'bonds' = {}", ids[j], row_start[j] + row_bonds[j], c.bonds));
    // Consecutive points and rows read as one run each.
    if (!points.empty() && points.back().first + points.back().second == hsize_t(ids[j])) ++points.back().second;
    else points.push_back({hsize_t(ids[j]), 1});
    if (!rows.empty() && rows.back().first + rows.back().second == row_start[j]) rows.back().second += row_bonds[j];
    else if (row_bonds[j] > 0) rows.push_back({row_start[j], row_bonds[j]});
  }
  read_fields(r, c.points, {&c.u, &c.v, &c.f}, &points, n);
  std::uint64_t states = 0;
  for (auto b : row_bonds) states += b;
  c.bond_state.resize(states);
  const hsize_t nb[1] = {c.bonds};
  r.runs("bond_state", H5T_NATIVE_UINT8, 1, nb, rows, c.bond_state.data());
  c.row_bonds.assign(row_bonds.begin(), row_bonds.end());
  check_values(r, c);
  return c;
}

}  // namespace peridot
