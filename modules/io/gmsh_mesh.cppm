module;
#include <dlfcn.h>
#include <limits.h>
#include <malloc.h>
#include <sys/mman.h>
#include <fcntl.h>
#include <unistd.h>
#include <omp.h>
#include <stdint.h>
#include <gmshc.h>
export module peridot.io:gmsh_mesh;
import peridot.std;
import peridot.discretization;

export namespace peridot {

// Reads a 2D mesh of 3-node triangles: a .msh file (format v2 or v4) or a .geo file meshed
// on the fly with characteristic length `mesh_size` [m] (0: the sizes in the .geo file;
// ignored for a .msh).
//
// Nodes are those used by triangles, in increasing Gmsh node tag, numbered 0..n-1; z must be 0.
// Triangles come out counter-clockwise: a surface whose triangles all run clockwise (meshed
// with normal -z) is flipped; a surface with both orientations is an error. Physical groups of
// dimension 0-2 become `groups` (the nodes of the group's elements); an unnamed group is called
// "group<tag>" in 2D and "<dim>d_group<tag>" in 0D/1D, and groups sharing a name are merged.
// Every error is a std::invalid_argument naming the file. Gmsh is a process-wide singleton:
// this initialises and finalises it per call under a lock, so do not use the Gmsh API
// elsewhere in the process at the same time.
//
// `before_meshing`, when set, is called for a .geo file before Gmsh meshes its surfaces, with an
// estimate of the node count and the element size [m], so a caller can refuse (throw) a mesh
// that would not fit before Gmsh spends minutes and gigabytes on it. The estimate is the model's
// bounding-box area over the area of a node of equilateral triangles, (sqrt(3)/2) h^2, with h
// the mesh size or, for sizes set in the .geo, the mean edge of its 1D mesh of the curves.
using MeshEstimateCheck = std::function<void(double nodes, double element_size)>;
// Who reads a .msh file: Peridot itself (the default: the file's text and the mesh, no Gmsh;
// 0.4 of Gmsh's time and about half its memory on a 230,629-node mesh), or Gmsh (the
// reference the tests compare with).
enum class MshReader { peridot, gmsh };
TriangleMesh read_gmsh_mesh(const std::filesystem::path& file, double mesh_size = 0, const MeshEstimateCheck& before_meshing = {},
                            MshReader reader = MshReader::peridot);

// The same for a 3D mesh of 4-node tetrahedra (a .geo is meshed in 3D). Tetrahedra come out
// positively oriented: a volume whose tetrahedra all have negative volume is flipped; a volume
// with both orientations is an error. Physical groups of dimension 0-3 become `groups`, an
// unnamed one "group<tag>" in 3D and "<dim>d_group<tag>" below. The node estimate is the
// bounding-box volume over h^3 / sqrt(2), about six regular tetrahedra of edge h per node.
TetMesh read_gmsh_tet_mesh(const std::filesystem::path& file, double mesh_size = 0, const MeshEstimateCheck& before_meshing = {},
                           MshReader reader = MshReader::peridot);

// Meshes `file` (a .geo; a .msh is read) as read_gmsh_mesh (dim 2) or read_gmsh_tet_mesh (dim 3)
// does, checks the mesh as they do, and writes the mesh Gmsh made to `out` as an ASCII .msh
// (format 4.1, with the model's physical groups), which they read back as the same mesh, its
// coordinates to Gmsh's 16 significant digits. Returns the node count. Input errors are
// std::invalid_argument naming `file`; a failed write is a std::runtime_error naming `out`.
std::size_t write_gmsh_mesh(const std::filesystem::path& file, double mesh_size, int dim, const std::filesystem::path& out,
                            const MeshEstimateCheck& before_meshing = {});

// A .msh file read as a stream, for a reader that keeps part of the mesh only (a rank of a
// distributed run). The sections before $Nodes are read whole into the header; then every
// node, and every element after the block it belongs to, goes to the visitor in file order. The
// file is checked as read_gmsh_mesh checks it, except what needs every node at once (that node
// and element tags are unique, that an element's nodes exist): the caller sees the nodes it
// keeps. The file is mapped, not copied, and the pages already read are handed back as it goes,
// so the reader's memory does not grow with the file. Errors: std::invalid_argument naming the
// file and line.
struct MshHeader {
  std::map<std::pair<int, long long>, std::string> names;                 // (dim, physical tag) -> name
  std::map<std::pair<int, long long>, std::vector<long long>> physicals;  // (dim, entity) -> physical tags
  std::array<std::vector<long long>, 4> entities;                        // 4.1: every entity by dimension
};
struct MshVisitor {
  bool nodes_only = false;  // stop after $Nodes (the elements are neither read nor checked)
  std::function<void(std::size_t tag, const std::array<double, 3>& x)> node;        // may be empty
  std::function<void(int dim, int type, long long entity)> block;                   // may be empty
  std::function<void(std::size_t tag, std::span<const std::size_t> nodes)> element;  // may be empty
};
MshHeader stream_msh(const std::filesystem::path& file, const MshVisitor& visit);
// Node tag -> a value: an array over the tags where they are dense (Gmsh numbers nodes 1..n),
// else sorted pairs. Two allocations, not one per node as a hash map makes (glibc keeps those
// resident once freed, under the run's set-up). Used by the whole-mesh reader and by a rank
// that reads its part (read_mesh_part).
class TagMap {
 public:
  explicit TagMap(std::span<const std::size_t> tags)
      : dense_(!tags.empty() && *std::max_element(tags.begin(), tags.end()) <= 4 * tags.size() + 1024) {
    if (dense_) values_.assign(*std::max_element(tags.begin(), tags.end()) + 1, -1);
    else pairs_.reserve(tags.size());
  }
  void set(std::size_t tag, std::int64_t value) {
    if (!dense_) return pairs_.push_back({tag, value});
    values_[tag] = value;
  }
  void done() { std::sort(pairs_.begin(), pairs_.end()); }
  std::int64_t find(std::size_t tag) const {  // -1: absent
    if (dense_) return tag < values_.size() ? values_[tag] : -1;
    const auto it = std::lower_bound(pairs_.begin(), pairs_.end(), std::pair<std::size_t, std::int64_t>{tag, std::numeric_limits<std::int64_t>::min()});
    return it != pairs_.end() && it->first == tag ? it->second : -1;
  }

 private:
  bool dense_;
  std::vector<std::int64_t> values_;
  std::vector<std::pair<std::size_t, std::int64_t>> pairs_;
};

// Gmsh's node count and dimension of its element types 1-19 ({0, -1} for others).
std::pair<int, int> msh_element_shape(int type);
// What read_gmsh_mesh (dim 2) or read_gmsh_tet_mesh (dim 3) require of the element types a file
// holds (the Gmsh types of its non-empty blocks): the dimension's one linear type, none above.
void require_msh_element_types(const std::filesystem::path& file, int dim, std::span<const int> types);
// A physical group's node-set name, as the readers name it: its name, or for an unnamed group
// "group<tag>" at the mesh's dimension and "<dim>d_group<tag>" below.
std::string msh_group_name(const std::string& name, int dim, long long tag, int mesh_dim);

}  // namespace peridot

namespace peridot {
namespace {


[[noreturn]] void fail(const std::filesystem::path& file, const std::string& why) {
  throw std::invalid_argument(fmt::format("{}: {}", file.string(), why));
}

// Gmsh is opened on first use (dlopen) through its C API, not linked: libgmsh brings 92 shared
// libraries (OpenCASCADE, FLTK, GDAL's tree), which cost every Peridot process 0.12 s of
// dynamic loading at start-up although most runs read no mesh. The function types come from
// gmshc.h, so the compiler checks every call. PERIDOT_GMSH_LIBRARY is the soname CMake found.
struct GmshC {
#define PERIDOT_GMSH_FUNCTIONS(X)                                                                        \
  X(Free) X(Initialize) X(Finalize) X(Open) X(Write) X(OptionSetNumber) X(LoggerStart) X(LoggerStop) X(LoggerGet) \
  X(LoggerGetLastError) X(ModelGetEntities) X(ModelGetPhysicalGroups) X(ModelGetPhysicalName)          \
  X(ModelGetBoundingBox) X(ModelMeshGenerate) X(ModelMeshClear) X(ModelMeshGetNodes) X(ModelMeshGetNode) \
  X(ModelMeshGetNodesForPhysicalGroup) X(ModelMeshGetElements) X(ModelMeshGetElementTypes)             \
  X(ModelMeshGetElementProperties) X(ModelMeshGetElementsByType)
#define PERIDOT_GMSH_POINTER(name) decltype(&::gmsh##name) name = nullptr;
  PERIDOT_GMSH_FUNCTIONS(PERIDOT_GMSH_POINTER)
#undef PERIDOT_GMSH_POINTER
};

const GmshC& gmsh_c() {
  static const GmshC api = [] {
    void* lib = dlopen(PERIDOT_GMSH_LIBRARY, RTLD_NOW | RTLD_LOCAL);
    if (!lib) throw std::runtime_error(fmt::format("Gmsh support: cannot load {}: {}", PERIDOT_GMSH_LIBRARY, dlerror()));
    GmshC c;
#define PERIDOT_GMSH_LOAD(name)                                                                            \
  c.name = reinterpret_cast<decltype(c.name)>(dlsym(lib, "gmsh" #name));                                  \
  if (!c.name) throw std::runtime_error(fmt::format("Gmsh support: {} lacks gmsh{}", PERIDOT_GMSH_LIBRARY, #name));
    PERIDOT_GMSH_FUNCTIONS(PERIDOT_GMSH_LOAD)
#undef PERIDOT_GMSH_LOAD
    return c;  // never dlclose'd: Gmsh keeps process-wide state
  }();
  return api;
}

// The few calls Peridot makes, with the C++ API's error convention: a failure throws the
// message as a std::string.
namespace gm {

using DimTags = std::vector<std::pair<int, int>>;

void check(int ierr, const char* call) {
  if (!ierr) return;
  std::string message = fmt::format("gmsh{} failed", call);
  char* last = nullptr;
  int e = 0;
  gmsh_c().LoggerGetLastError(&last, &e);
  if (!e && last && *last) message = last;
  if (last) gmsh_c().Free(last);
  throw message;
}

// Copies and frees an array Gmsh allocated.
template <class T>
std::vector<T> take(T* p, std::size_t n) {
  std::vector<T> v(p, p + n);
  if (p) gmsh_c().Free(p);
  return v;
}

std::string take_string(char* p) {
  std::string s = p ? p : "";
  if (p) gmsh_c().Free(p);
  return s;
}

DimTags take_pairs(int* p, std::size_t n) {
  DimTags v(n / 2);
  for (std::size_t k = 0; k < v.size(); ++k) v[k] = {p[2 * k], p[2 * k + 1]};
  if (p) gmsh_c().Free(p);
  return v;
}

void initialize() {
  int e = 0;
  gmsh_c().Initialize(0, nullptr, 0, &e);
  check(e, "Initialize");
}
void finalize() {
  int e = 0;
  gmsh_c().Finalize(&e);
  check(e, "Finalize");
}
void set_number(const char* name, double value) {
  int e = 0;
  gmsh_c().OptionSetNumber(name, value, &e);
  check(e, "OptionSetNumber");
}
void logger_start() {
  int e = 0;
  gmsh_c().LoggerStart(&e);
  check(e, "LoggerStart");
}
void logger_stop() {
  int e = 0;
  gmsh_c().LoggerStop(&e);
  check(e, "LoggerStop");
}
std::vector<std::string> logger_get() {
  char** log = nullptr;
  std::size_t n = 0;
  int e = 0;
  gmsh_c().LoggerGet(&log, &n, &e);
  std::vector<std::string> lines;
  for (std::size_t k = 0; k < n; ++k) lines.push_back(take_string(log[k]));
  if (log) gmsh_c().Free(log);
  check(e, "LoggerGet");
  return lines;
}
void open(const std::string& file) {
  int e = 0;
  gmsh_c().Open(file.c_str(), &e);
  check(e, "Open");
}
void write(const std::string& file) {
  int e = 0;
  gmsh_c().Write(file.c_str(), &e);
  check(e, "Write");
}
void generate(int dim) {
  int e = 0;
  gmsh_c().ModelMeshGenerate(dim, &e);
  check(e, "ModelMeshGenerate");
}
void clear_mesh() {
  int e = 0;
  gmsh_c().ModelMeshClear(nullptr, 0, &e);
  check(e, "ModelMeshClear");
}
DimTags entities(int dim) {
  int* p = nullptr;
  std::size_t n = 0;
  int e = 0;
  gmsh_c().ModelGetEntities(&p, &n, dim, &e);
  auto v = take_pairs(p, n);
  check(e, "ModelGetEntities");
  return v;
}
DimTags physical_groups() {
  int* p = nullptr;
  std::size_t n = 0;
  int e = 0;
  gmsh_c().ModelGetPhysicalGroups(&p, &n, -1, &e);
  auto v = take_pairs(p, n);
  check(e, "ModelGetPhysicalGroups");
  return v;
}
std::string physical_name(int dim, int tag) {
  char* p = nullptr;
  int e = 0;
  gmsh_c().ModelGetPhysicalName(dim, tag, &p, &e);
  auto s = take_string(p);
  check(e, "ModelGetPhysicalName");
  return s;
}
std::array<double, 6> bounding_box() {
  std::array<double, 6> b{};
  int e = 0;
  gmsh_c().ModelGetBoundingBox(-1, -1, &b[0], &b[1], &b[2], &b[3], &b[4], &b[5], &e);
  check(e, "ModelGetBoundingBox");
  return b;
}
// Every node of the model: tags and x, y, z per tag.
void nodes(std::vector<std::size_t>& tags, std::vector<double>& coord) {
  std::size_t* t = nullptr;
  double *c = nullptr, *u = nullptr;
  std::size_t nt = 0, nc = 0, nu = 0;
  int e = 0;
  gmsh_c().ModelMeshGetNodes(&t, &nt, &c, &nc, &u, &nu, -1, -1, 0, 0, &e);
  tags = take(t, nt), coord = take(c, nc);
  take(u, nu);
  check(e, "ModelMeshGetNodes");
}
std::vector<double> node(std::size_t tag) {
  double *c = nullptr, *u = nullptr;
  std::size_t nc = 0, nu = 0;
  int e = 0;
  gmsh_c().ModelMeshGetNode(tag, &c, &nc, &u, &nu, &e);
  auto x = take(c, nc);
  take(u, nu);
  check(e, "ModelMeshGetNode");
  return x;
}
void nodes_for_physical_group(int dim, int tag, std::vector<std::size_t>& tags, std::vector<double>& coord) {
  std::size_t* t = nullptr;
  double* c = nullptr;
  std::size_t nt = 0, nc = 0;
  int e = 0;
  gmsh_c().ModelMeshGetNodesForPhysicalGroup(dim, tag, &t, &nt, &c, &nc, &e);
  tags = take(t, nt), coord = take(c, nc);
  check(e, "ModelMeshGetNodesForPhysicalGroup");
}
std::vector<int> element_types() {
  int* p = nullptr;
  std::size_t n = 0;
  int e = 0;
  gmsh_c().ModelMeshGetElementTypes(&p, &n, -1, -1, &e);
  auto v = take(p, n);
  check(e, "ModelMeshGetElementTypes");
  return v;
}
struct ElementProperties {
  std::string name;
  int dim = 0;
};
ElementProperties element_properties(int type) {
  char* name = nullptr;
  int dim = 0, order = 0, nodes = 0, primary = 0, e = 0;
  double* local = nullptr;
  std::size_t nl = 0;
  gmsh_c().ModelMeshGetElementProperties(type, &name, &dim, &order, &nodes, &local, &nl, &primary, &e);
  take(local, nl);
  ElementProperties p{take_string(name), dim};
  check(e, "ModelMeshGetElementProperties");
  return p;
}
void elements_by_type(int type, std::vector<std::size_t>& tags, std::vector<std::size_t>& nodes, int entity) {
  std::size_t *t = nullptr, *c = nullptr;
  std::size_t nt = 0, nc = 0;
  int e = 0;
  gmsh_c().ModelMeshGetElementsByType(type, &t, &nt, &c, &nc, entity, 0, 1, &e);
  tags = take(t, nt), nodes = take(c, nc);
  check(e, "ModelMeshGetElementsByType");
}
// The node tags of every element of dimension dim, one array per element type.
std::vector<std::vector<std::size_t>> element_nodes(int dim) {
  int* types = nullptr;
  std::size_t ntypes = 0, ntags_n = 0, nnodes_n = 0;
  std::size_t **tags = nullptr, **nodes = nullptr, *ntags = nullptr, *nnodes = nullptr;
  int e = 0;
  gmsh_c().ModelMeshGetElements(&types, &ntypes, &tags, &ntags, &ntags_n, &nodes, &nnodes, &nnodes_n, dim, -1, &e);
  std::vector<std::vector<std::size_t>> out;
  for (std::size_t k = 0; k < ntags_n; ++k) take(tags[k], ntags[k]);
  for (std::size_t k = 0; k < nnodes_n; ++k) out.push_back(take(nodes[k], nnodes[k]));
  take(types, ntypes);
  for (void* p : {static_cast<void*>(tags), static_cast<void*>(ntags), static_cast<void*>(nodes), static_cast<void*>(nnodes)})
    if (p) gmsh_c().Free(p);
  check(e, "ModelMeshGetElements");
  return out;
}

}  // namespace gm

// How Gmsh 4.8 fails: initialize() sets General.AbortOnError = 2, so the first error throws a
// std::string (not a std::exception). Thrown out of the .geo parser (which also reads any file
// that does not start with $MeshFormat), it leaves the unread rest of that file in the lexer
// buffer, which even finalize() keeps, so every later file fails with "syntax error". So we
// set AbortOnError = 0, let the parser run to the end of the file, and collect the errors from
// the logger instead; a missing file is not an error at all. A fresh session per call also
// restores every option to its default.
//
// Gmsh's initialize() also sets the calling thread's OpenMP thread count to its
// General.NumThreads (1): every later parallel region of the run would then run on one thread
// whatever --threads said (measured: a .geo deck ran as fast on 2 threads as on 1). The
// session puts the count back.
struct GmshSession {
  int threads = omp_get_max_threads();
  GmshSession() {
    gm::initialize();
    gm::set_number("General.Terminal", 0);
    gm::set_number("General.Verbosity", 1);  // errors only, and they reach the logger
    gm::set_number("General.AbortOnError", 0);
    gm::logger_start();
  }
  ~GmshSession() {
    try {
      gm::logger_stop();
      gm::finalize();
    } catch (...) {
    }
    // Gmsh frees its mesh in small blocks that glibc keeps mapped; hand them back, or they stay
    // resident under the run's set-up (measured: a 0.14-0.19 GB lower peak for 2.3e5 nodes).
    malloc_trim(0);
    omp_set_num_threads(threads);
  }
  GmshSession(const GmshSession&) = delete;
  GmshSession& operator=(const GmshSession&) = delete;
};

void throw_logged_error() {
  const auto log = gm::logger_get();
  const std::string error = "Error: ";
  for (const auto& line : log)
    if (line.starts_with(error)) throw line.substr(error.size());
}

// ---- checking a .msh file before Gmsh parses it ----
// Gmsh 4.8's .msh readers trust the file: a count that disagrees with the lines after it, an
// element with too few nodes or a section out of order ends in a failed assert (abort), a
// crash or an allocation without bound. So Peridot reads the file once itself, token by token
// as Gmsh's fscanf does, and hands it on only if it is well formed: ASCII format 2.2 or 4.1,
// the sections $MeshFormat, $PhysicalNames, $Entities (4.1), $Nodes and $Elements, counts
// that match, tags that exist, finite coordinates. Any other file is refused, naming the
// line. (A file that does not start with $MeshFormat would go to Gmsh's .geo interpreter,
// which runs commands and writes files: a .msh is never a script.)

struct MshCursor {
  const std::filesystem::path& file;
  std::string_view text;
  std::size_t pos = 0;
  std::size_t line = 1;
  bool mapped = false;       // text is a page-aligned mapping of the file
  std::size_t released = 0;  // the mapping's pages before this offset were handed back

  // A mapped file's pages behind the cursor, every 64 MiB: file-backed pages count in a
  // process's resident memory until dropped.
  void release() {
    constexpr std::size_t chunk = std::size_t(64) << 20;
    if (!mapped || pos - released < chunk) return;
    const std::size_t upto = pos & ~(chunk - 1);
    if (upto <= released) return;
    madvise(const_cast<char*>(text.data()) + released, upto - released, MADV_DONTNEED);
    released = upto;
  }

  [[noreturn]] void bad(const std::string& why) const { fail(file, fmt::format("Gmsh cannot read it: line {}: {}", line, why)); }

  void skip_space() {
    while (pos < text.size() && std::isspace(static_cast<unsigned char>(text[pos]))) line += text[pos++] == '\n';
  }
  bool at_end() {
    skip_space();
    return pos >= text.size();
  }
  std::string_view token(const char* what) {
    skip_space();
    if (pos >= text.size()) bad(fmt::format("the file ends where {} should be", what));
    const std::size_t b = pos;
    while (pos < text.size() && !std::isspace(static_cast<unsigned char>(text[pos]))) ++pos;
    return text.substr(b, pos - b);
  }
  static std::string shown(std::string_view t) { return t.size() <= 30 ? std::string(t) : fmt::format("{}...", t.substr(0, 30)); }
  // A whole number in [lo, hi]: Gmsh reads tags as int, counts as size_t.
  long long integer(const char* what, long long lo, long long hi) {
    const auto t = token(what);
    long long v = 0;
    const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
    if (ec != std::errc() || end != t.data() + t.size()) bad(fmt::format("{} = '{}' is not a whole number", what, shown(t)));
    if (v < lo || v > hi) bad(fmt::format("{} = {} is out of range [{}, {}]", what, v, lo, hi));
    return v;
  }
  double real(const char* what) {
    const auto t = token(what);
    double v = 0;
    const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
    if (ec != std::errc() || end != t.data() + t.size() || !std::isfinite(v)) bad(fmt::format("{} = '{}' is not a finite number", what, shown(t)));
    return v;
  }
  void expect(std::string_view word) {
    const auto t = token(word.data());
    if (t != word) bad(fmt::format("expected {}, found '{}'", word, shown(t)));
  }
  // The rest of the line (Gmsh reads a physical name with fgets into 256 bytes).
  std::string_view rest_of_line() {
    while (pos < text.size() && (text[pos] == ' ' || text[pos] == '\t')) ++pos;
    const std::size_t b = pos;
    while (pos < text.size() && text[pos] != '\n') ++pos;
    auto r = text.substr(b, pos - b);
    while (!r.empty() && std::isspace(static_cast<unsigned char>(r.back()))) r.remove_suffix(1);
    return r;
  }
};

constexpr long long kMaxTag = INT32_MAX;

// Nodes and dimension of Gmsh's element types 1-19 (first and second order, and the point).
struct ElementShape {
  int nodes, dim;
};
constexpr std::array<ElementShape, 20> kElementShapes{{{0, -1}, {2, 1}, {3, 2}, {4, 2}, {4, 3}, {8, 3}, {6, 3}, {5, 3}, {3, 1}, {6, 2},
                                                      {9, 2}, {10, 3}, {27, 3}, {18, 3}, {14, 3}, {1, 0}, {8, 2}, {20, 3}, {15, 3}, {13, 3}}};

// A count, bounded by the bytes left: every entry it counts takes at least two.
std::size_t count(MshCursor& c, const char* what) {
  return std::size_t(c.integer(what, 0, (long long)(c.text.size() - c.pos) / 2 + 1));
}

void require_unique(MshCursor& c, std::vector<long long> tags, const char* what) {
  std::ranges::sort(tags);
  if (const auto it = std::adjacent_find(tags.begin(), tags.end()); it != tags.end()) c.bad(fmt::format("{} tag {} appears twice", what, *it));
}

// What a .msh file holds, as read (and checked) by Peridot: every node, the elements in
// blocks of one dimension, entity and type (file order), physical names and the physical tags
// of each entity.
struct MshFile : MshHeader {
  std::vector<std::size_t> node_tags;  // file order
  std::vector<double> coord;           // x, y, z per node
  struct Block {
    int dim = 0, type = 0;
    long long entity = 0;
    std::vector<std::size_t> tags, nodes;  // tags >= 1, checked
  };
  std::vector<Block> blocks;
};

void physical_names(MshCursor& c, MshHeader& out) {
  const std::size_t n = count(c, "the number of physical names");
  for (std::size_t k = 0; k < n; ++k) {
    const int dim = int(c.integer("a physical name's dimension", 0, 3));
    const auto tag = c.integer("a physical name's tag", -kMaxTag, kMaxTag);
    const auto name = c.rest_of_line();
    if (name.size() < 2 || name.front() != '"' || name.back() != '"' || name.size() > 200 ||
        name.substr(1, name.size() - 2).find('"') != std::string_view::npos)
      c.bad("a physical name must be one \"quoted\" name of at most 198 characters on its line");
    out.names[{dim, tag}] = std::string(name.substr(1, name.size() - 2));
  }
  c.expect("$EndPhysicalNames");
}

// The sections' readers hand what they read to a sink: node(tag, xyz), block(dim, type, entity)
// before the elements of a block, element(tag, node tags). Element and node tags are checked
// unique where the sink keeps them (read_msh); a streaming reader checks the counts only.

// Format 2.2: $Nodes: n, then "tag x y z"; $Elements: n, then "tag type ntags tags... nodes..."
// (the first tag is the physical group, the second the elementary entity).
template <class Sink>
void nodes_v2(MshCursor& c, Sink& sink) {
  const std::size_t n = count(c, "the number of nodes");
  for (std::size_t k = 0; k < n; ++k) {
    const auto tag = std::size_t(c.integer("a node tag", 1, kMaxTag));
    std::array<double, 3> x{};
    for (int a = 0; a < 3; ++a) x[std::size_t(a)] = c.real(std::array{"a node's x", "a node's y", "a node's z"}[std::size_t(a)]);
    sink.node(tag, x);
    c.release();
  }
  c.expect("$EndNodes");
}

template <class Sink>
void elements_v2(MshCursor& c, MshHeader& header, Sink& sink) {
  const std::size_t n = count(c, "the number of elements");
  int dim = -1, type = -1;
  long long block_entity = 0;
  std::array<std::size_t, 27> nodes{};
  for (std::size_t k = 0; k < n; ++k) {
    const auto tag = c.integer("an element tag", 1, kMaxTag);
    const auto t = c.integer("element type", 1, 19);
    const auto shape = kElementShapes[std::size_t(t)];
    const auto ntags = c.integer("an element's number of tags", 0, 64);
    long long physical = 0, entity = 0;
    for (long long q = 0; q < ntags; ++q) {
      const auto v = c.integer("an element's tag", -kMaxTag, kMaxTag);
      if (q == 0) physical = v;
      if (q == 1) entity = v;
    }
    if (dim != shape.dim || block_entity != entity || type != int(t)) {
      dim = shape.dim, type = int(t), block_entity = entity;
      sink.block(dim, type, entity);
    }
    for (int a = 0; a < shape.nodes; ++a) nodes[std::size_t(a)] = std::size_t(c.integer("an element's node", 1, kMaxTag));
    sink.element(c, std::size_t(tag), std::span<const std::size_t>(nodes.data(), std::size_t(shape.nodes)));
    if (physical != 0) {
      auto& ph = header.physicals[{shape.dim, entity}];
      if (std::ranges::find(ph, physical) == ph.end()) ph.push_back(physical);
    }
    c.release();
  }
  c.expect("$EndElements");
}

// Format 4.1: entities by dimension, then nodes and elements in blocks of one entity each.
using Entities = std::array<std::vector<long long>, 4>;  // sorted tags per dimension

void entities_v4(MshCursor& c, Entities& entities, MshHeader& out) {
  std::array<std::size_t, 4> n{};
  for (int d = 0; d < 4; ++d) n[std::size_t(d)] = count(c, "a number of entities");
  for (int d = 0; d < 4; ++d) {
    for (std::size_t k = 0; k < n[std::size_t(d)]; ++k) {
      const auto entity = c.integer("an entity tag", 1, kMaxTag);
      entities[std::size_t(d)].push_back(entity);
      for (int b = 0; b < (d == 0 ? 3 : 6); ++b) c.real("an entity's coordinate");
      const std::size_t physicals = count(c, "an entity's number of physical tags");
      for (std::size_t p = 0; p < physicals; ++p) {
        const auto physical = c.integer("a physical tag", -kMaxTag, kMaxTag);
        auto& tags = out.physicals[{d, entity}];
        if (std::ranges::find(tags, physical) == tags.end()) tags.push_back(physical);
      }
      if (d == 0) continue;
      const std::size_t bounding = count(c, "an entity's number of bounding entities");
      for (std::size_t b = 0; b < bounding; ++b) {
        const auto t = c.integer("a bounding entity", -kMaxTag, kMaxTag);
        if (!std::ranges::binary_search(entities[std::size_t(d - 1)], t < 0 ? -t : t))
          c.bad(fmt::format("a {}D entity is bounded by {}D entity {}, which $Entities does not list", d, d - 1, t));
      }
    }
    std::ranges::sort(entities[std::size_t(d)]);
    require_unique(c, entities[std::size_t(d)], "entity");
  }
  c.expect("$EndEntities");
}

long long block_entity(MshCursor& c, const Entities* entities, int dim) {
  const auto tag = c.integer("a block's entity tag", 1, kMaxTag);
  if (entities && !std::ranges::binary_search((*entities)[std::size_t(dim)], tag))
    c.bad(fmt::format("a block belongs to {}D entity {}, which $Entities does not list", dim, tag));
  return tag;
}

// A 4.1 node block lists its tags, then their coordinates: the tags wait in `tags` (one block's).
template <class Sink>
void nodes_v4(MshCursor& c, const Entities* entities, Sink& sink) {
  const std::size_t blocks = count(c, "the number of node blocks"), total = count(c, "the number of nodes");
  const auto lo = c.integer("the least node tag", 0, kMaxTag), hi = c.integer("the greatest node tag", 0, kMaxTag);
  std::size_t seen = 0;
  std::vector<std::size_t> tags;
  for (std::size_t b = 0; b < blocks; ++b) {
    const int dim = int(c.integer("a node block's dimension", 0, 3));
    block_entity(c, entities, dim);
    c.integer("a node block's parametric flag (parametric nodes are not read)", 0, 0);
    const std::size_t n = count(c, "a node block's number of nodes");
    tags.clear();
    for (std::size_t k = 0; k < n; ++k) {
      tags.push_back(std::size_t(c.integer("a node tag", 1, kMaxTag)));
      if ((long long)tags.back() < lo || (long long)tags.back() > hi)
        c.bad(fmt::format("node tag {} is outside the header's range [{}, {}]", tags.back(), lo, hi));
    }
    seen += n;
    if (seen > total) c.bad(fmt::format("more nodes than the {} the $Nodes header gives", total));
    for (std::size_t k = 0; k < n; ++k) {
      std::array<double, 3> x{};
      for (int a = 0; a < 3; ++a) x[std::size_t(a)] = c.real(std::array{"a node's x", "a node's y", "a node's z"}[std::size_t(a)]);
      sink.node(tags[k], x);
      c.release();
    }
  }
  if (seen != total) c.bad(fmt::format("{} nodes, but the $Nodes header gives {}", seen, total));
  c.expect("$EndNodes");
}

template <class Sink>
void elements_v4(MshCursor& c, const Entities* entities, Sink& sink) {
  const std::size_t blocks = count(c, "the number of element blocks"), total = count(c, "the number of elements");
  const auto lo = c.integer("the least element tag", 0, kMaxTag), hi = c.integer("the greatest element tag", 0, kMaxTag);
  std::size_t seen = 0;
  std::array<std::size_t, 27> nodes{};
  for (std::size_t b = 0; b < blocks; ++b) {
    const int dim = int(c.integer("an element block's dimension", 0, 3));
    const auto entity = block_entity(c, entities, dim);
    const auto type = c.integer("element type", 1, 19);
    const auto shape = kElementShapes[std::size_t(type)];
    if (shape.dim != dim) c.bad(fmt::format("{}D elements in a block of a {}D entity", shape.dim, dim));
    const std::size_t n = count(c, "an element block's number of elements");
    sink.block(dim, int(type), entity);
    for (std::size_t k = 0; k < n; ++k) {
      const auto tag = c.integer("an element tag", 1, kMaxTag);
      if (tag < lo || tag > hi) c.bad(fmt::format("element tag {} is outside the header's range [{}, {}]", tag, lo, hi));
      for (int a = 0; a < shape.nodes; ++a) nodes[std::size_t(a)] = std::size_t(c.integer("an element's node", 1, kMaxTag));
      if (++seen > total) c.bad(fmt::format("more elements than the {} the $Elements header gives", total));
      sink.element(c, std::size_t(tag), std::span<const std::size_t>(nodes.data(), std::size_t(shape.nodes)));
      c.release();
    }
  }
  if (seen != total) c.bad(fmt::format("{} elements, but the $Elements header gives {}", seen, total));
  c.expect("$EndElements");
}

// The sections in their order, each handed to its reader: the header's sections into `header`,
// nodes and elements to the sink. after_nodes() runs between $Nodes and $Elements.
template <class Sink>
void read_sections(MshCursor& c, MshHeader& header, Sink& sink) {
  if (c.token("$MeshFormat") != "$MeshFormat") c.bad("a .msh file starts with $MeshFormat");
  const auto version = c.token("the format version");
  if (version != "2.2" && version != "4.1") c.bad(fmt::format("format version '{}'; Peridot reads .msh 2.2 and 4.1", MshCursor::shown(version)));
  const bool v4 = version == "4.1";
  c.integer("the file type (binary files are not read: write ASCII, Mesh.Binary = 0)", 0, 0);
  c.integer("the data size", 8, 8);
  c.expect("$EndMeshFormat");
  Entities entities;
  bool has_entities = false, has_nodes = false, has_elements = false, has_names = false;
  while (!c.at_end()) {
    const auto section = c.token("a section");
    const auto once = [&](bool& seen) {
      if (seen) c.bad(fmt::format("a second {} section", section));
      seen = true;
    };
    if (section == "$PhysicalNames" && !has_nodes) {
      once(has_names);
      physical_names(c, header);
    } else if (section == "$Entities" && v4 && !has_nodes) {
      once(has_entities);
      entities_v4(c, entities, header);
    } else if (section == "$Nodes" && !has_elements) {
      once(has_nodes);
      if (v4) nodes_v4(c, has_entities ? &entities : nullptr, sink);
      else nodes_v2(c, sink);
      sink.after_nodes(c);
    } else if (section == "$Elements" && has_nodes) {
      once(has_elements);
      if (v4) elements_v4(c, has_entities ? &entities : nullptr, sink);
      else elements_v2(c, header, sink);
      sink.after_elements(c);
    } else {
      c.bad(fmt::format("section '{}' is not read here, or out of order: expected {}$PhysicalNames, $Nodes, then $Elements",
                        MshCursor::shown(section), v4 ? "$Entities, " : ""));
    }
  }
  if (!has_elements) c.bad("the file has no $Elements section");
  if (has_entities) header.entities = entities;
}

// read_msh's sink: every node and element kept, node and element tags unique, an element's
// nodes among the nodes.
struct KeepAll {
  MshFile& out;
  std::vector<long long> nodes;  // sorted, once $Nodes is read
  std::vector<long long> element_tags;
  void node(std::size_t tag, const std::array<double, 3>& x) {
    out.node_tags.push_back(tag);
    out.coord.insert(out.coord.end(), x.begin(), x.end());
  }
  void after_nodes(MshCursor& c) {
    nodes.assign(out.node_tags.begin(), out.node_tags.end());
    std::ranges::sort(nodes);
    require_unique(c, nodes, "node");
  }
  void block(int dim, int type, long long entity) { out.blocks.push_back({dim, type, entity, {}, {}}); }
  void element(MshCursor& c, std::size_t tag, std::span<const std::size_t> element_nodes) {
    auto& block = out.blocks.back();
    block.tags.push_back(tag);
    element_tags.push_back((long long)tag);
    for (auto node : element_nodes) {
      if (!std::ranges::binary_search(nodes, (long long)node))
        c.bad(fmt::format("element {} refers to node {}, which $Nodes does not list", tag, node));
      block.nodes.push_back(node);
    }
  }
  void after_elements(MshCursor& c) { require_unique(c, std::move(element_tags), "element"); }
};

// stream_msh's sink: the visitor's callbacks.
struct Visit {
  const MshVisitor& v;
  void node(std::size_t tag, const std::array<double, 3>& x) {
    if (v.node) v.node(tag, x);
  }
  struct Stop {};
  void after_nodes(MshCursor&) {
    if (v.nodes_only) throw Stop{};
  }
  void block(int dim, int type, long long entity) {
    if (v.block) v.block(dim, type, entity);
  }
  void element(MshCursor&, std::size_t tag, std::span<const std::size_t> nodes) {
    if (v.element) v.element(tag, nodes);
  }
  void after_elements(MshCursor&) {}
};

// The file mapped read-only, unmapped and closed at scope end.
struct MappedFile {
  int fd = -1;
  void* data = nullptr;
  std::size_t size = 0;
  explicit MappedFile(const std::filesystem::path& file) {
    fd = ::open(file.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) fail(file, "cannot open it");
    std::error_code ec;
    size = std::size_t(std::filesystem::file_size(file, ec));
    if (ec) fail(file, "cannot read its size");
    if (size == 0) return;
    data = mmap(nullptr, size, PROT_READ, MAP_PRIVATE, fd, 0);
    if (data == MAP_FAILED) data = nullptr, fail(file, "cannot map it");
    madvise(data, size, MADV_SEQUENTIAL);
  }
  ~MappedFile() {
    if (data) munmap(data, size);
    if (fd >= 0) ::close(fd);
  }
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;
};

MshFile read_msh(const std::filesystem::path& file) {
  MshFile out;
  std::ifstream in(file, std::ios::binary);
  if (!in) fail(file, "cannot open it");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  MshCursor c{file, text};
  KeepAll sink{out, {}, {}};
  read_sections(c, out, sink);
  return out;
}

// What differs between reading triangles and tetrahedra.
template <class Mesh>
struct Elements;
template <>
struct Elements<TriangleMesh> {
  static constexpr int dim = 2, gmsh_type = 2, nodes = 3;  // Gmsh's linear 3-node triangle
  static constexpr const char *name = "triangle", *plural = "triangles", *entity = "surface";
  static auto& of(TriangleMesh& m) { return m.triangles; }
  static double size(const TriangleMesh& m, std::size_t e) { return m.area(e); }
};
template <>
struct Elements<TetMesh> {
  static constexpr int dim = 3, gmsh_type = 4, nodes = 4;  // Gmsh's linear 4-node tetrahedron
  static constexpr const char *name = "tetrahedron", *plural = "tetrahedra", *entity = "volume";
  static auto& of(TetMesh& m) { return m.tetrahedra; }
  static double size(const TetMesh& m, std::size_t e) { return m.volume(e); }
};

// A meshed model as extract reads it, from Gmsh's API (a .geo Gmsh meshed) or from a .msh
// file read here (model_of_file).
struct MeshModel {
  std::vector<std::size_t> node_tags;  // every node of the model
  std::vector<double> coord;           // x, y, z per node
  struct Type {
    std::string name;
    int id, dim;
  };
  std::vector<Type> types;  // the element types present
  // The entities of the mesh's dimension in Gmsh's order (ascending tag), each with its
  // elements of the mesh's linear type, in the file's order: tags, and node tags per element.
  struct Entity {
    int tag;
    std::vector<std::size_t> elements, connectivity;
  };
  std::vector<Entity> entities;
  // The physical groups of dimension up to the mesh's: their name ("" when unnamed) and the
  // nodes of their elements (Gmsh's nodes for a physical group).
  struct Group {
    int dim, tag;
    std::string name;
    std::vector<std::size_t> nodes;
  };
  std::vector<Group> groups;
};

// The element types of the model's top dimension must be the one linear type Mesh holds.
template <class Mesh>
void require_element_type(const std::filesystem::path& file, const MeshModel& model) {
  using E = Elements<Mesh>;
  std::string kinds, higher;
  bool wanted = false, others = false;
  for (const auto& [name, type, dim] : model.types) {
    if (dim > E::dim) higher += (higher.empty() ? "" : ", ") + name;
    if (dim != E::dim) continue;  // lower ones only carry boundary groups
    kinds += (kinds.empty() ? "" : ", ") + name;
    (type == E::gmsh_type ? wanted : others) = true;
  }
  if (!higher.empty())
    fail(file, fmt::format("it holds {}D elements ({}): a {}D mesh, not a {}D one", E::dim + 1, higher, E::dim + 1, E::dim));
  if (others) fail(file, fmt::format("mixed element types: {}; only linear {}-node {} are supported", kinds, E::nodes, E::plural));
  if (!wanted) fail(file, fmt::format("the mesh contains no {}{}", E::plural, E::dim == 3 ? " (a 2D mesh is read with dimension 2)" : ""));
}

// The model Gmsh holds (after opening a file, and meshing a .geo).
template <class Mesh>
MeshModel model_from_gmsh() {
  using E = Elements<Mesh>;
  MeshModel m;
  for (int type : gm::element_types()) {
    auto [name, dim] = gm::element_properties(type);
    m.types.push_back({std::move(name), type, dim});
  }
  gm::nodes(m.node_tags, m.coord);
  for (const auto& [dim, tag] : gm::entities(E::dim)) {
    auto& e = m.entities.emplace_back(MeshModel::Entity{tag, {}, {}});
    gm::elements_by_type(E::gmsh_type, e.elements, e.connectivity, tag);
  }
  for (const auto& [dim, tag] : gm::physical_groups()) {
    if (dim > E::dim) continue;
    auto& g = m.groups.emplace_back(MeshModel::Group{dim, tag, gm::physical_name(dim, tag), {}});
    // Not getNodes(dim, entity, includeBoundary): after reading a v2 file the nodes on
    // entities outside any physical group belong to no entity, and a group would miss them.
    std::vector<double> coord;
    gm::nodes_for_physical_group(dim, tag, g.nodes, coord);
  }
  return m;
}

// Gmsh's names of its element types 1-19.
constexpr std::array<const char*, 20> kElementNames{"",          "Line 2",        "Triangle 3",    "Quadrilateral 4", "Tetrahedron 4",
                                                    "Hexahedron 8", "Prism 6",     "Pyramid 5",     "Line 3",          "Triangle 6",
                                                    "Quadrilateral 9", "Tetrahedron 10", "Hexahedron 27", "Prism 18",  "Pyramid 14",
                                                    "Point",     "Quadrilateral 8", "Hexahedron 20", "Prism 15",      "Pyramid 13"};

// The model of a .msh file, read here rather than by Gmsh, as Gmsh's API would give it: a
// process reading the 230,629-node hole_precrack mesh through Gmsh peaked at 184 MB and took
// 1.5 s (the file's check included), through this at 100 MB and 0.6 s (the file's text and
// the arrays below). Tested against Gmsh's own reading of .msh files of both versions, 2D and
// 3D (test_gmsh_mesh).
template <class Mesh>
MeshModel model_of_file(const std::filesystem::path& file) {
  using E = Elements<Mesh>;
  MshFile f = read_msh(file);
  MeshModel m;
  m.node_tags = std::move(f.node_tags);
  m.coord = std::move(f.coord);
  std::set<int> types;
  for (const auto& b : f.blocks)
    if (!b.tags.empty()) types.insert(b.type);
  for (int t : types) m.types.push_back({kElementNames[std::size_t(t)], t, kElementShapes[std::size_t(t)].dim});
  // Physical groups: every (dimension, tag) an entity carries; their nodes, those of the
  // elements of every entity that carries it.
  std::set<std::pair<int, long long>> groups;
  for (const auto& [entity, tags] : f.physicals)
    for (long long t : tags)
      if (entity.first <= E::dim) groups.insert({entity.first, t});
  for (const auto& [dim, tag] : groups) {
    const auto name = f.names.find({dim, tag});
    auto& g = m.groups.emplace_back(MeshModel::Group{dim, int(tag), name == f.names.end() ? std::string() : name->second, {}});
    for (const auto& b : f.blocks) {
      if (b.dim != dim) continue;
      const auto p = f.physicals.find({dim, b.entity});
      if (p != f.physicals.end() && std::ranges::find(p->second, tag) != p->second.end()) g.nodes.insert(g.nodes.end(), b.nodes.begin(), b.nodes.end());
    }
  }
  // Entities of the mesh's dimension: those $Entities lists (4.1) and those elements name. The
  // blocks' arrays move into them (a 4.1 file has one block per entity and type).
  std::set<long long> top(f.entities[std::size_t(E::dim)].begin(), f.entities[std::size_t(E::dim)].end());
  for (const auto& b : f.blocks)
    if (b.dim == E::dim) top.insert(b.entity);
  for (long long tag : top) {
    auto& e = m.entities.emplace_back(MeshModel::Entity{int(tag), {}, {}});
    for (auto& b : f.blocks)
      if (b.dim == E::dim && b.entity == tag && b.type == E::gmsh_type) {
        if (e.elements.empty()) {
          e.elements = std::move(b.tags);
          e.connectivity = std::move(b.nodes);
        } else {
          e.elements.insert(e.elements.end(), b.tags.begin(), b.tags.end());
          e.connectivity.insert(e.connectivity.end(), b.nodes.begin(), b.nodes.end());
        }
      }
  }
  return m;
}

template <class Mesh>
Mesh extract(const std::filesystem::path& file, const MeshModel& model) {
  using E = Elements<Mesh>;
  require_element_type<Mesh>(file, model);
  const auto& tags = model.node_tags;
  const auto& coord = model.coord;
  TagMap where(tags);  // node tag -> position in coord
  for (std::size_t i = 0; i < tags.size(); ++i) where.set(tags[i], std::int64_t(i));
  where.done();

  // Elements per entity, since orientation is a property of the entity.
  const auto& entities = model.entities;
  std::vector<std::size_t> used;
  for (const auto& e : entities) used.insert(used.end(), e.connectivity.begin(), e.connectivity.end());
  std::ranges::sort(used);
  used.erase(std::unique(used.begin(), used.end()), used.end());
  if (used.size() > std::size_t(INT32_MAX)) fail(file, "more than 2^31 nodes");

  Mesh mesh;
  TagMap index(used);  // node tag -> mesh node
  for (std::size_t tag : used) {
    const auto at = where.find(tag);
    if (at < 0) fail(file, fmt::format("a {} refers to node {}, which does not exist", E::name, tag));
    const double* x = &coord[3 * std::size_t(at)];
    index.set(tag, std::int64_t(mesh.nodes.size()));
    mesh.nodes.push_back({x[0], x[1], x[2]});
  }
  index.done();
  if constexpr (E::dim == 2) {
    // Relative to the mesh size, so that round-off in a written file does not count.
    const Aabb b = mesh.bounds();
    const double flat = 1e-10 * std::max({b.hi[0] - b.lo[0], b.hi[1] - b.lo[1], 1e-300});
    for (std::size_t i = 0; i < mesh.nodes.size(); ++i) {
      if (std::abs(mesh.nodes[i][2]) > flat)
        fail(file, fmt::format("the mesh is not planar in z = 0: node {} has z = {:g} m", used[i], mesh.nodes[i][2]));
      mesh.nodes[i][2] = 0;
    }
  }

  auto& out = E::of(mesh);
  for (const auto& entity : entities) {
    const std::size_t first = out.size(), count = entity.elements.size();
    std::size_t positive = 0, negative = 0;
    for (std::size_t e = 0; e < count; ++e) {
      const std::size_t* n = &entity.connectivity[std::size_t(E::nodes) * e];
      auto& element = out.emplace_back();
      for (std::size_t a = 0; a < std::size_t(E::nodes); ++a) element[a] = std::int32_t(index.find(n[a]));  // used: present
      const double v = E::size(mesh, out.size() - 1);
      positive += v > 0, negative += v < 0;
    }
    if (positive > 0 && negative > 0) {
      // The minority orientation is the inverted one.
      for (std::size_t e = 0; e < count; ++e)
        if (positive >= negative ? E::size(mesh, first + e) < 0 : E::size(mesh, first + e) > 0)
          fail(file, fmt::format("inverted element {}: its nodes run opposite to the other {} of {} {}", entity.elements[e], E::plural, E::entity,
                                 entity.tag));
    }
    // Swapping two nodes turns the orientation of a triangle or a tetrahedron.
    if (negative > 0 && positive == 0)
      for (std::size_t t = first; t < out.size(); ++t) std::swap(out[t][1], out[t][2]);
  }
  try {
    validate(mesh);
  } catch (const std::invalid_argument& e) {
    fail(file, e.what());
  }

  for (const auto& g : model.groups) {
    auto& nodes = mesh.groups[msh_group_name(g.name, g.dim, g.tag, E::dim)];
    for (std::size_t t : g.nodes)
      if (const auto i = index.find(t); i >= 0) nodes.push_back(std::int32_t(i));
    std::ranges::sort(nodes);
    nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
  }
  return mesh;
}

}  // namespace

namespace {

// The model's bounding box over the space one node takes: two equilateral triangles of edge h
// in 2D, about six regular tetrahedra (h^3 / sqrt(2)) in 3D.
double nodes_in_box(double h, int dim) {
  const auto [x0, y0, z0, x1, y1, z1] = gm::bounding_box();
  const double area = std::max(x1 - x0, 0.0) * std::max(y1 - y0, 0.0);
  if (dim == 2) return area / (std::sqrt(3.0) / 2.0 * h * h);
  return area * std::max(z1 - z0, 0.0) / (h * h * h / std::sqrt(2.0));
}

// The mean edge of the 1D mesh of every curve: the sizes the .geo asks for, on its boundary.
double mean_curve_edge() {
  const auto nodes = gm::element_nodes(1);
  double length = 0;
  std::size_t edges = 0;
  for (std::size_t t = 0; t < nodes.size(); ++t)
    for (std::size_t e = 0; e + 1 < nodes[t].size(); e += 2) {
      const auto a = gm::node(nodes[t][e]), b = gm::node(nodes[t][e + 1]);
      if (a.size() < 2 || b.size() < 2) continue;
      length += std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a.size() > 2 ? (a[2] - b[2]) * (a[2] - b[2]) : 0.0));
      ++edges;
    }
  return edges ? length / double(edges) : 0.0;
}

}  // namespace

namespace {

// One lock for every reader: Gmsh is a process-wide singleton.
std::mutex& gmsh_lock() {
  static std::mutex lock;
  return lock;
}

template <class Mesh>
Mesh read_gmsh(const std::filesystem::path& file, double mesh_size, const MeshEstimateCheck& before_meshing,
               const std::filesystem::path* write_to = nullptr, MshReader reader = MshReader::peridot) {
  constexpr int dim = Elements<Mesh>::dim;
  const bool geo = file.extension() == ".geo";
  if (!(mesh_size >= 0) || !std::isfinite(mesh_size))
    fail(file, fmt::format("mesh size must be a finite number >= 0 (0: the sizes in the file), not {:g}", mesh_size));
  std::error_code ec;
  // Gmsh opens a missing file without a word and returns an empty model.
  if (!std::filesystem::is_regular_file(file, ec)) fail(file, "no such file");

  if (!geo && !write_to && reader == MshReader::peridot) {
    Mesh mesh = extract<Mesh>(file, model_of_file<Mesh>(file));
    malloc_trim(0);  // the file's text and arrays, handed back before the set-up allocates
    return mesh;
  }
  // Gmsh's .msh readers trust the file: it is checked first.
  if (!geo) read_msh(file);

  const std::lock_guard lock(gmsh_lock());
  try {
    GmshSession session;
    gm::open(file.string());
    throw_logged_error();
    if (geo) {
      if (mesh_size > 0) {
        // Min = max clamps every size Gmsh computes (from points, curvature or fields of the
        // .geo) to mesh_size, so no other size option matters. Set after open(), since the
        // .geo may set these options itself.
        gm::set_number("Mesh.MeshSizeMin", mesh_size);
        gm::set_number("Mesh.MeshSizeMax", mesh_size);
        gm::clear_mesh();  // a "Mesh 2;" or "Mesh 3;" in the .geo would otherwise stand
      }
      if (before_meshing) {
        double h = mesh_size;
        if (!(h > 0)) {
          gm::generate(1);  // cheap: the curves only
          throw_logged_error();
          h = mean_curve_edge();
        }
        if (h > 0) before_meshing(nodes_in_box(h, dim), h);
      }
      gm::generate(dim);
      throw_logged_error();
    }
    Mesh mesh = extract<Mesh>(file, model_from_gmsh<Mesh>());
    if (write_to) {
      gm::set_number("Mesh.MshFileVersion", 4.1);
      gm::set_number("Mesh.Binary", 0);  // the only kind check_msh reads
      try {
        gm::write(write_to->string());
        throw_logged_error();
      } catch (const std::string& e) {
        throw std::runtime_error(fmt::format("{}: Gmsh cannot write it: {}", write_to->string(), e));
      }
      if (!std::filesystem::is_regular_file(*write_to, ec)) throw std::runtime_error(write_to->string() + ": Gmsh did not write it");
    }
    return mesh;
  } catch (const std::invalid_argument&) {
    throw;
  } catch (const std::runtime_error& e) {
    if (write_to && std::string_view(e.what()).starts_with(write_to->string())) throw;
    fail(file, std::string("Gmsh cannot read it: ") + e.what());
  } catch (const std::string& e) {
    fail(file, "Gmsh cannot read it: " + e);
  } catch (const std::exception& e) {
    fail(file, std::string("Gmsh cannot read it: ") + e.what());
  } catch (...) {
    fail(file, "Gmsh cannot read it");
  }
}

}  // namespace

TriangleMesh read_gmsh_mesh(const std::filesystem::path& file, double mesh_size, const MeshEstimateCheck& before_meshing, MshReader reader) {
  return read_gmsh<TriangleMesh>(file, mesh_size, before_meshing, nullptr, reader);
}

TetMesh read_gmsh_tet_mesh(const std::filesystem::path& file, double mesh_size, const MeshEstimateCheck& before_meshing, MshReader reader) {
  return read_gmsh<TetMesh>(file, mesh_size, before_meshing, nullptr, reader);
}

MshHeader stream_msh(const std::filesystem::path& file, const MshVisitor& visit) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) fail(file, "no such file");
  const MappedFile map(file);
  MshCursor c{file, std::string_view(static_cast<const char*>(map.data), map.size)};
  c.mapped = map.data != nullptr;
  MshHeader header;
  Visit sink{visit};
  try {
    read_sections(c, header, sink);
  } catch (const Visit::Stop&) {
  }
  return header;
}

void require_msh_element_types(const std::filesystem::path& file, int dim, std::span<const int> types) {
  MeshModel model;
  for (int t : types) model.types.push_back({kElementNames[std::size_t(t)], t, kElementShapes[std::size_t(t)].dim});
  if (dim == 3) require_element_type<TetMesh>(file, model);
  else require_element_type<TriangleMesh>(file, model);
}

std::string msh_group_name(const std::string& name, int dim, long long tag, int mesh_dim) {
  if (!name.empty()) return name;
  return dim == mesh_dim ? fmt::format("group{}", tag) : fmt::format("{}d_group{}", dim, tag);
}

std::pair<int, int> msh_element_shape(int type) {
  if (type < 1 || type > 19) return {0, -1};
  return {kElementShapes[std::size_t(type)].nodes, kElementShapes[std::size_t(type)].dim};
}

std::size_t write_gmsh_mesh(const std::filesystem::path& file, double mesh_size, int dim, const std::filesystem::path& out,
                            const MeshEstimateCheck& before_meshing) {
  if (dim != 2 && dim != 3) fail(file, fmt::format("dimension {}: a mesh is 2D (triangles) or 3D (tetrahedra)", dim));
  if (dim == 2) return read_gmsh<TriangleMesh>(file, mesh_size, before_meshing, &out).nodes.size();
  return read_gmsh<TetMesh>(file, mesh_size, before_meshing, &out).nodes.size();
}

}  // namespace peridot
