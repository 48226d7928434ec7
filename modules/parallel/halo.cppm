module;
#include "parallel_backend.h"

export module peridot.parallel:halo;
import peridot.std;
import :runtime;

export namespace peridot::parallel {

// Ghost copies of off-rank points, refreshed through a PetscSF (held by the backend): every rank's local points are
// the roots, and a ghost is a leaf that reads one root on its owner. Empty (no exchange) on one
// rank.
class Halo {
 public:
  Halo() = default;
  // local_size points on this rank; ghost g (local index ghost_local[g]) copies point
  // owner_index[g] (the owner's local index) of rank owner_rank[g]. Collective.
  Halo(std::size_t local_size, std::span<const std::int64_t> ghost_local, std::span<const int> owner_rank,
       std::span<const std::int64_t> owner_index);
  Halo(Halo&& o) noexcept : sf_(std::exchange(o.sf_, nullptr)), ghosts_(o.ghosts_) {}
  Halo& operator=(Halo&& o) noexcept {
    std::swap(sf_, o.sf_);
    ghosts_ = o.ghosts_;
    return *this;
  }
  ~Halo();

  bool empty() const { return sf_ == nullptr; }
  std::size_t ghosts() const { return ghosts_; }
  // Copies each owner's values into its ghosts, for the arrays of one field (each indexed by
  // local point). Collective.
  void exchange(std::span<double* const> arrays) const;
  // The same for fixed-width records of bytes: point i's record is rows[i * width, (i + 1) * width).
  // Every rank passes the same width. Collective.
  void exchange_records(std::span<std::uint8_t> rows, std::size_t width) const;

 private:
  void* sf_ = nullptr;  // the backend's PetscSF
  std::size_t ghosts_ = 0;
};

// Contiguous pieces, one per rank, of an array of global length starts.back(): rank r holds
// [starts[r], starts[r + 1]). gather_to_root fills `whole` on rank 0 (untouched elsewhere);
// scatter_from_root is its inverse. Collective.
void gather_to_root(std::span<const double> piece, std::span<double> whole, std::span<const std::size_t> starts);
void gather_to_root(std::span<const std::uint8_t> piece, std::span<std::uint8_t> whole, std::span<const std::size_t> starts);
void scatter_from_root(std::span<const double> whole, std::span<double> piece, std::span<const std::size_t> starts);
void scatter_from_root(std::span<const std::uint8_t> whole, std::span<std::uint8_t> piece, std::span<const std::size_t> starts);

}  // namespace peridot::parallel

namespace peridot::parallel {

Halo::Halo(std::size_t local_size, std::span<const std::int64_t> ghost_local, std::span<const int> owner_rank,
           std::span<const std::int64_t> owner_index) {
  if (ghost_local.size() != owner_rank.size() || ghost_local.size() != owner_index.size())
    throw std::invalid_argument("Halo: ghost, owner rank and owner index lists differ in length");
  if (ranks() < 2) return;
  PeridotError error{};
  sf_ = backend().halo_create(std::int64_t(local_size), ghost_local.data(), owner_rank.data(), owner_index.data(), std::int64_t(ghost_local.size()),
                              &error);
  if (!sf_) rethrow(error);
  ghosts_ = ghost_local.size();
}

Halo::~Halo() {
  if (sf_) backend().halo_destroy(sf_);
}

void Halo::exchange(std::span<double* const> arrays) const {
  if (!sf_) return;
  PeridotError error{};
  if (backend().halo_exchange(sf_, arrays.data(), arrays.size(), &error)) rethrow(error);
}

void Halo::exchange_records(std::span<std::uint8_t> rows, std::size_t width) const {
  if (!sf_ || width == 0) return;
  if (width > std::size_t(INT32_MAX)) throw std::length_error("Halo: records too wide for one MPI type");
  PeridotError error{};
  if (backend().halo_exchange_records(sf_, rows.data(), width, &error)) rethrow(error);
}

namespace {

template <class T>
void gatherv(const T* piece, T* whole, std::span<const std::size_t> starts, int type, bool scatter) {
  const int n = ranks();
  if (std::size_t(n) + 1 != starts.size()) throw std::invalid_argument("gather: one start per rank and the end are needed");
  std::vector<int> counts(static_cast<std::size_t>(n)), displs(static_cast<std::size_t>(n));
  for (int r = 0; r < n; ++r) {
    if (starts[std::size_t(r) + 1] - starts[std::size_t(r)] > std::size_t(INT32_MAX) || starts[std::size_t(r)] > std::size_t(INT32_MAX))
      throw std::length_error("gather: a piece is too large for one MPI message");
    counts[std::size_t(r)] = int(starts[std::size_t(r) + 1] - starts[std::size_t(r)]);
    displs[std::size_t(r)] = int(starts[std::size_t(r)]);
  }
  const int mine = counts[std::size_t(rank())];
  // One process that never started MPI holds the whole array itself.
  if (!started()) {
    if (scatter) std::copy(whole, whole + mine, const_cast<T*>(piece));
    else std::copy(piece, piece + mine, whole);
    return;
  }
  if (backend().gatherv(piece, mine, whole, counts.data(), displs.data(), type, scatter ? 1 : 0) != 0)
    throw std::runtime_error("MPI gather/scatter failed");
}

}  // namespace

void gather_to_root(std::span<const double> piece, std::span<double> whole, std::span<const std::size_t> starts) {
  gatherv(piece.data(), whole.data(), starts, peridot_f64, false);
}
void gather_to_root(std::span<const std::uint8_t> piece, std::span<std::uint8_t> whole, std::span<const std::size_t> starts) {
  gatherv(piece.data(), whole.data(), starts, peridot_u8, false);
}
void scatter_from_root(std::span<const double> whole, std::span<double> piece, std::span<const std::size_t> starts) {
  gatherv(piece.data(), const_cast<double*>(whole.data()), starts, peridot_f64, true);
}
void scatter_from_root(std::span<const std::uint8_t> whole, std::span<std::uint8_t> piece, std::span<const std::size_t> starts) {
  gatherv(piece.data(), const_cast<std::uint8_t*>(whole.data()), starts, peridot_u8, true);
}

}  // namespace peridot::parallel
