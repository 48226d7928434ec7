module;
#include <dlfcn.h>
#include <stdio.h>
#include <unistd.h>

#include "parallel_backend.h"

export module peridot.parallel:runtime;
import peridot.std;

export namespace peridot::parallel {

// PETSc and MPI start once per process: from main (so that mpirun ranks know their rank before
// they read a deck) or lazily at the first distributed solve. Both live in a shared library
// opened then (parallel_backend.h), so serial runs that never solve on PETSc neither load them
// nor pay for starting them.
void start();
bool started();
// True when mpirun (OpenMPI, or a PMI launcher) started this process: main then starts MPI
// before anything else, so that ranks other than 0 stay quiet.
bool launched_by_mpirun();
int rank();   // 0 before start
int ranks();  // 1 before start

// Sums over all ranks in place (collective; a no-op before start).
void sum_over_ranks(std::uint64_t& value);
// Collective reductions; on one rank (or before start) they return the value.
double sum_over_ranks(double value);
double min_over_ranks(double value);
// Ends every rank of a distributed run with `code`: a rank that failed cannot leave the others
// waiting in a collective. A no-op on one rank.
void abort_all(int code);
int max_over_ranks(int value);
void barrier();
// Element-wise integer sums over all ranks, in place (collective; exact, so order-free).
void sum_over_ranks(std::span<std::int64_t> values);
// Element-wise maxima over all ranks, in place on every rank (collective; exact).
void max_over_ranks(std::span<double> values);
// Element-wise maxima over all ranks, in place on rank 0 (collective; exact).
void max_to_root(std::span<std::int16_t> values);
// Every rank's value, in rank order (collective; one entry on one rank).
std::vector<std::uint64_t> all_gather(std::uint64_t value);
// Rank 0's bytes on every rank, replacing theirs (collective; a no-op on one rank).
void broadcast_from_root(std::vector<std::uint8_t>& bytes);
// Rank r's share, made on rank 0 by make(r) and sent, one rank at a time, so that rank 0 holds
// its own share and one other at once (collective; make runs on rank 0 only; one rank: make(0)).
std::vector<std::uint8_t> scatter_from_root(const std::function<std::vector<std::uint8_t>(int)>& make);
// Where other ranks hold given points: for each k, the index of global id ids[k] in the
// ascending list `held` of rank owner[k], answered by that rank (collective; every rank passes
// its own `held`). -1 where that rank does not hold the id. Lets a rank that built only its
// own part find its ghosts on their owners without any rank holding every rank's layout.
std::vector<std::int64_t> index_on_owners(std::span<const std::int64_t> ids, std::span<const int> owner,
                                          std::span<const std::int64_t> held);

// Where each listed point's row starts in the rows of all points laid out in global id order:
// for each k, the sum of `lengths` over every id below ids[k], whichever rank lists it
// (collective; every id in [0, global_size) listed by one rank, ids ascending on each). Each
// rank sums one contiguous block of ids, so no rank holds every point's length.
std::vector<std::uint64_t> row_starts(std::span<const std::int64_t> ids, std::span<const std::uint64_t> lengths, std::uint64_t global_size);

// A failure on one rank must end every rank, whatever the phase, or the others wait forever in
// the phase's next collective. Two ways, chosen by whether the phase itself holds collectives:
//  - together(phase, f): f holds none. Every rank runs f, then all learn whether any failed:
//    the failed rank throws its own message prefixed with its rank and phase, the others throw
//    naming the lowest failed rank and the phase; std::invalid_argument when the failure was an
//    input error (so all exit 2), else std::runtime_error. All ranks leave the phase together.
//  - or_abort(phase, f): f holds collectives. A rank whose f throws prints
//    "error: rank R, <phase>: <what>" and ends the job with MPI_Abort(1).
// On one rank both just run f.
// is_input tells input errors (exit 2) from others; none given: std::invalid_argument and kin.
enum class Failure : int { none = 0, runtime = 1, input = 2 };
using InputErrorTest = bool (*)(const std::exception&);
Failure failure_of(const std::exception& e, InputErrorTest is_input);
void rethrow_together(std::string_view phase, Failure mine, std::exception_ptr error);
[[noreturn]] void abort_from(std::string_view phase, const std::exception& e);

// Test-only: throws std::runtime_error("injected failure ...") when PERIDOT_INJECT_FAILURE is
// "<phase>@<rank>" for this phase and rank, so tests can fail one rank at any phase.
void inject_failure(std::string_view phase);

template <class F>
void together(std::string_view phase, F&& f, InputErrorTest is_input = nullptr) {
  Failure mine = Failure::none;
  std::exception_ptr error;
  try {
    inject_failure(phase);
    f();
  } catch (const std::exception& e) {
    mine = failure_of(e, is_input);
    error = std::current_exception();
  }
  rethrow_together(phase, mine, error);
}

template <class F>
decltype(auto) or_abort(std::string_view phase, F&& f) {
  try {
    inject_failure(phase);
    return f();
  } catch (const std::exception& e) {
    if (ranks() == 1) throw;
    abort_from(phase, e);
  }
}

// PETSc options given on the command line (`-ksp_type gmres -pc_type hypre`). They are inserted
// after a deck's `solver.petsc_options` at every solve, so the command line wins.
void set_command_line_options(std::string options);
const std::string& command_line_options();

// Splits argv into Peridot's arguments and PETSc's: a token of the form -word_word (one dash, a
// lower-case letter, at least one '_' , as every PETSc option has) starts a PETSc option and
// takes the next token as its value unless that starts another option.
struct SplitArguments {
  std::vector<char*> peridot;  // argv[0] first
  std::string petsc;           // joined, for PetscOptionsInsertString
};
SplitArguments split_petsc_arguments(int argc, char** argv);

}  // namespace peridot::parallel

// For the module's own units only.
namespace peridot::parallel {

// The PETSc and MPI backend's table, opened at the first call (throws std::runtime_error naming
// the library when it cannot be opened), and whether it has been.
const PeridotParallelBackend& backend();
bool backend_loaded();
// Throws a backend call's error again as the exception it was.
void rethrow(const PeridotError& error);

}  // namespace peridot::parallel

namespace peridot::parallel {

namespace {

std::atomic<const PeridotParallelBackend*>& loaded() {
  static std::atomic<const PeridotParallelBackend*> table{nullptr};
  return table;
}

std::string& cli_options() {
  static std::string s;
  return s;
}

bool is_petsc_option(std::string_view t) {
  if (t.size() < 3 || t[0] != '-' || t[1] < 'a' || t[1] > 'z') return false;
  bool underscore = false;
  for (char c : t.substr(1)) {
    if (c == '_') underscore = true;
    else if (!((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9'))) return false;
  }
  return underscore;
}

}  // namespace

const PeridotParallelBackend& backend() {
  static std::mutex opening;
  if (const auto* t = loaded().load()) return *t;
  std::lock_guard lock(opening);
  if (const auto* t = loaded().load()) return *t;
  // PERIDOT_PETSC_BACKEND, else a copy beside the executable (a build tree moved elsewhere),
  // else where the build wrote it.
  const char* own = std::getenv("PERIDOT_PETSC_BACKEND");
  std::string path = own && *own ? own : peridot_petsc_backend_path();
  if (!(own && *own)) {
    char self[4096];
    const auto n = readlink("/proc/self/exe", self, sizeof self - 1);
    std::error_code ec;
    const auto beside = std::filesystem::path(std::string(self, std::size_t(n > 0 ? n : 0))).parent_path() / std::filesystem::path(path).filename();
    if (n > 0 && std::filesystem::exists(beside, ec)) path = beside.string();
  }
  // Global, as MPI's own plugins expect of the library that loads them.
  void* library = dlopen(path.c_str(), RTLD_NOW | RTLD_GLOBAL);
  if (!library) throw std::runtime_error(fmt::format("PETSc and MPI: cannot open {} ({})", path, dlerror()));
  const auto entry = reinterpret_cast<const PeridotParallelBackend* (*)()>(dlsym(library, "peridot_parallel_backend"));
  if (!entry) throw std::runtime_error(fmt::format("PETSc and MPI: {} has no peridot_parallel_backend", path));
  loaded().store(entry());
  return *loaded().load();
}

bool backend_loaded() { return loaded().load() != nullptr; }

void rethrow(const PeridotError& e) {
  if (e.kind == 2) throw std::invalid_argument(e.message);
  if (e.kind == 3) throw std::length_error(e.message);
  throw std::runtime_error(e.message);
}

void start() {
  PeridotError error{};
  if (backend().start(launched_by_mpirun() ? 0 : 1, &error)) rethrow(error);
}

bool launched_by_mpirun() {
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"})
    if (std::getenv(v)) return true;
  return false;
}

bool started() { return backend_loaded() && backend().started(); }

int rank() { return started() ? backend().rank() : 0; }

int ranks() { return started() ? backend().size() : 1; }

void sum_over_ranks(std::uint64_t& value) {
  if (!started()) return;
  backend().allreduce(&value, 1, peridot_u64, peridot_sum);
}

double sum_over_ranks(double value) {
  if (ranks() > 1) backend().allreduce(&value, 1, peridot_f64, peridot_sum);
  return value;
}

double min_over_ranks(double value) {
  if (ranks() > 1) backend().allreduce(&value, 1, peridot_f64, peridot_min);
  return value;
}

int max_over_ranks(int value) {
  if (ranks() > 1) backend().allreduce(&value, 1, peridot_i32, peridot_max);
  return value;
}

void barrier() {
  if (ranks() > 1) backend().barrier();
}

void sum_over_ranks(std::span<std::int64_t> values) {
  if (ranks() > 1) backend().allreduce(values.data(), int(values.size()), peridot_i64, peridot_sum);
}

void max_over_ranks(std::span<double> values) {
  if (ranks() > 1) backend().allreduce(values.data(), int(values.size()), peridot_f64, peridot_max);
}

void max_to_root(std::span<std::int16_t> values) {
  if (ranks() <= 1) return;
  backend().reduce_to_root(values.data(), int(values.size()), peridot_i16, peridot_max);
}

std::vector<std::uint64_t> all_gather(std::uint64_t value) {
  std::vector<std::uint64_t> out(std::size_t(ranks()), value);
  if (ranks() > 1) backend().allgather(&value, out.data(), 1, peridot_u64);
  return out;
}

// MPI counts are int: byte arrays go in pieces of at most 1 GiB.
constexpr std::uint64_t piece = std::uint64_t(1) << 30;

std::vector<std::uint8_t> scatter_from_root(const std::function<std::vector<std::uint8_t>(int)>& make) {
  if (rank() == 0) {
    for (int r = 1; r < ranks(); ++r) {
      const auto part = make(r);
      std::uint64_t size = part.size();
      backend().send(&size, 1, peridot_u64, r);
      for (std::uint64_t at = 0; at < size; at += piece)
        backend().send(part.data() + at, int(std::min(piece, size - at)), peridot_u8, r);
    }
    return make(0);
  }
  std::uint64_t size = 0;
  backend().recv(&size, 1, peridot_u64, 0);
  std::vector<std::uint8_t> mine(size);
  for (std::uint64_t at = 0; at < size; at += piece)
    backend().recv(mine.data() + at, int(std::min(piece, size - at)), peridot_u8, 0);
  return mine;
}

void broadcast_from_root(std::vector<std::uint8_t>& bytes) {
  if (ranks() <= 1) return;
  std::uint64_t size = bytes.size();
  backend().bcast(&size, 1, peridot_u64);
  bytes.resize(size);
  for (std::uint64_t at = 0; at < size; at += piece)
    backend().bcast(bytes.data() + at, int(std::min(piece, size - at)), peridot_u8);
}

std::vector<std::uint64_t> row_starts(std::span<const std::int64_t> ids, std::span<const std::uint64_t> lengths, std::uint64_t global_size) {
  if (ids.size() != lengths.size()) throw std::invalid_argument("row_starts: ids and lengths differ in length");
  const int n = ranks();
  // Block b holds ids [first[b], first[b + 1]).
  std::vector<std::uint64_t> first(std::size_t(n) + 1);
  for (int b = 0; b <= n; ++b) first[std::size_t(b)] = std::uint64_t((unsigned __int128)global_size * std::uint64_t(b) / std::uint64_t(n));
  const auto block_of = [&](std::int64_t g) { return int(std::upper_bound(first.begin(), first.end(), std::uint64_t(g)) - first.begin()) - 1; };
  const auto block_start = [&](int b) { return first[std::size_t(b)]; };
  std::vector<int> send_count(std::size_t(n), 0), recv_count(std::size_t(n), 0);
  for (auto g : ids) {
    if (g < 0 || std::uint64_t(g) >= global_size) throw std::invalid_argument(fmt::format("row_starts: id {} of {}", g, global_size));
    ++send_count[std::size_t(block_of(g))];
  }
  if (n > 1) backend().alltoall_int(send_count.data(), recv_count.data());
  else recv_count = send_count;
  std::vector<int> send_at(std::size_t(n) + 1, 0), recv_at(std::size_t(n) + 1, 0);
  for (std::size_t r = 0; r < std::size_t(n); ++r) {
    send_at[r + 1] = send_at[r] + send_count[r];
    recv_at[r + 1] = recv_at[r] + recv_count[r];
  }
  // ids ascend, so the pairs are already grouped by block: (id, length) after one another.
  std::vector<std::int64_t> pairs(2 * ids.size()), asked(2 * std::size_t(recv_at.back()));
  for (std::size_t k = 0; k < ids.size(); ++k) pairs[2 * k] = ids[k], pairs[2 * k + 1] = std::int64_t(lengths[k]);
  const auto m = static_cast<std::size_t>(n);
  std::vector<int> send2(m), recv2(m), send2_at(m), recv2_at(m);
  for (std::size_t r = 0; r < std::size_t(n); ++r)
    send2[r] = 2 * send_count[r], recv2[r] = 2 * recv_count[r], send2_at[r] = 2 * send_at[r], recv2_at[r] = 2 * recv_at[r];
  if (n > 1)
    backend().alltoallv(pairs.data(), send2.data(), send2_at.data(), asked.data(), recv2.data(), recv2_at.data(), peridot_i64);
  else asked = pairs;
  // This rank's block: every id's length, then their prefix sums, offset by the blocks below.
  const int me = rank();
  const std::uint64_t lo = block_start(me), hi = block_start(me + 1);
  std::vector<std::uint64_t> within(hi - lo + 1, 0);
  for (std::size_t k = 0; k < asked.size(); k += 2) within[std::size_t(std::uint64_t(asked[k]) - lo) + 1] = std::uint64_t(asked[k + 1]);
  for (std::size_t k = 1; k < within.size(); ++k) within[k] += within[k - 1];
  std::uint64_t below = 0, total = within.back();
  if (n > 1) backend().exscan_sum_u64(&total, &below);
  if (me == 0) below = 0;  // MPI_Exscan leaves rank 0's result undefined
  std::vector<std::int64_t> answers(asked.size() / 2), starts(ids.size());
  for (std::size_t k = 0; k < answers.size(); ++k) answers[k] = std::int64_t(below + within[std::size_t(std::uint64_t(asked[2 * k]) - lo)]);
  if (n > 1)
    backend().alltoallv(answers.data(), recv_count.data(), recv_at.data(), starts.data(), send_count.data(), send_at.data(), peridot_i64);
  else starts = answers;
  return {starts.begin(), starts.end()};
}

std::vector<std::int64_t> index_on_owners(std::span<const std::int64_t> ids, std::span<const int> owner,
                                          std::span<const std::int64_t> held) {
  if (ids.size() != owner.size()) throw std::invalid_argument("index_on_owners: ids and owners differ in length");
  const auto find = [&](std::int64_t g) -> std::int64_t {
    const auto it = std::lower_bound(held.begin(), held.end(), g);
    return it != held.end() && *it == g ? std::int64_t(it - held.begin()) : -1;
  };
  const int n = ranks();
  std::vector<std::int64_t> out(ids.size(), -1);
  if (n == 1) {
    for (std::size_t k = 0; k < ids.size(); ++k) out[k] = find(ids[k]);
    return out;
  }
  // Questions grouped by owner (stable, so answers come back in the same order).
  std::vector<int> send_count(std::size_t(n), 0), recv_count(std::size_t(n), 0);
  for (int r : owner) {
    if (r < 0 || r >= n) throw std::invalid_argument(fmt::format("index_on_owners: owner rank {} of {}", r, n));
    ++send_count[std::size_t(r)];
  }
  backend().alltoall_int(send_count.data(), recv_count.data());
  std::vector<int> send_at(std::size_t(n) + 1, 0), recv_at(std::size_t(n) + 1, 0);
  for (std::size_t r = 0; r < std::size_t(n); ++r) {
    send_at[r + 1] = send_at[r] + send_count[r];
    recv_at[r + 1] = recv_at[r] + recv_count[r];
  }
  std::vector<std::int64_t> questions(ids.size()), asked(std::size_t(recv_at.back()));
  std::vector<std::size_t> slot(ids.size());
  {
    std::vector<int> next(send_at.begin(), send_at.end() - 1);
    for (std::size_t k = 0; k < ids.size(); ++k) {
      slot[k] = std::size_t(next[std::size_t(owner[k])]++);
      questions[slot[k]] = ids[k];
    }
  }
  backend().alltoallv(questions.data(), send_count.data(), send_at.data(), asked.data(), recv_count.data(), recv_at.data(), peridot_i64);
  for (auto& g : asked) g = find(g);
  backend().alltoallv(asked.data(), recv_count.data(), recv_at.data(), questions.data(), send_count.data(), send_at.data(), peridot_i64);
  for (std::size_t k = 0; k < ids.size(); ++k) out[k] = questions[slot[k]];
  return out;
}

void abort_all(int code) {
  if (ranks() > 1) backend().abort(code);
}

Failure failure_of(const std::exception& e, InputErrorTest is_input) {
  const bool input = is_input ? is_input(e) : dynamic_cast<const std::invalid_argument*>(&e) != nullptr;
  return input ? Failure::input : Failure::runtime;
}

void rethrow_together(std::string_view phase, Failure mine, std::exception_ptr error) {
  if (ranks() == 1) {
    if (error) std::rethrow_exception(error);
    return;
  }
  // The worst failure, then (only when there is one) the lowest rank that had it.
  const int me = rank();
  const auto kind = Failure(max_over_ranks(int(mine)));
  if (kind == Failure::none) return;
  const int failed = int(min_over_ranks(mine == kind ? double(me) : double(ranks())));
  if (error) {
    // The failed rank's own message, with its rank and phase, as the message of its kind.
    std::string what;
    try {
      std::rethrow_exception(error);
    } catch (const std::exception& e) {
      what = fmt::format("rank {}, {}: {}", me, phase, e.what());
    }
    if (mine == Failure::input) throw std::invalid_argument(what);
    throw std::runtime_error(what);
  }
  const auto message = fmt::format("rank {} failed in {} (its message is above); rank {} stops too", failed, phase, me);
  if (kind == Failure::input) throw std::invalid_argument(message);
  throw std::runtime_error(message);
}

void abort_from(std::string_view phase, const std::exception& e) {
  std::fprintf(stderr, "error: rank %d, %.*s: %s\n", rank(), int(phase.size()), phase.data(), e.what());
  std::fflush(stderr);
  if (started()) backend().abort(1);
  std::abort();  // MPI_Abort does not return
}

void inject_failure(std::string_view phase) {
  static const std::string wanted = [] {
    const char* v = std::getenv("PERIDOT_INJECT_FAILURE");
    return std::string(v ? v : "");
  }();
  if (wanted.empty()) return;
  if (wanted == fmt::format("{}@{}", phase, rank()))
    throw std::runtime_error(fmt::format("injected failure (PERIDOT_INJECT_FAILURE={})", wanted));
}

void set_command_line_options(std::string options) { cli_options() = std::move(options); }
const std::string& command_line_options() { return cli_options(); }

SplitArguments split_petsc_arguments(int argc, char** argv) {
  SplitArguments out;
  for (int k = 0; k < argc; ++k) {
    const std::string_view t = argv[k];
    if (k == 0 || !is_petsc_option(t)) {
      out.peridot.push_back(argv[k]);
      continue;
    }
    if (!out.petsc.empty()) out.petsc += ' ';
    out.petsc += t;
    if (k + 1 < argc && !is_petsc_option(argv[k + 1]) && std::string_view(argv[k + 1]).substr(0, 2) != "--") {
      out.petsc += ' ';
      out.petsc += argv[++k];
    }
  }
  return out;
}

}  // namespace peridot::parallel
