export module peridot.parallel:row_block;
import peridot.std;

export namespace peridot::parallel {

// This rank's rows [first_row, first_row + rows()) of a square global matrix, as CSR with
// global column indices and sorted, merged columns: what MatCreateMPIAIJWithArrays takes.
struct RowBlock {
  std::int64_t global_rows = 0, first_row = 0;
  std::vector<std::int64_t> offset{0};
  std::vector<std::int64_t> column;
  std::vector<double> value;
  std::vector<double> rhs;  // one per local row
  std::int64_t rows() const { return std::int64_t(offset.size()) - 1; }
};

// An entry (global row, global column, value); duplicates are summed.
struct Entry {
  std::int64_t row, col;
  double value;
};

// Builds a block from rows assembled a few at a time, in any order, on many threads. Each
// thread merges a point's rows as soon as they are complete and keeps them in its own arrays;
// finish() lays them out in row order. Peak memory is twice the merged matrix, not the
// unmerged entries plus a sorted copy.
class RowAssembly {
 public:
  RowAssembly(std::int64_t global_rows, std::int64_t first_row, std::int64_t rows, int threads);
  // Thread `thread` hands over every entry of rows [row, row + count) (unsorted, duplicates
  // summed); `entries` is left empty for reuse. It runs inside OpenMP regions, so it never
  // throws: an inconsistency is recorded and finish() reports it.
  void add_rows(int thread, std::int64_t row, int count, std::vector<Entry>& entries);
  // Every row must have been added once. Throws std::logic_error on an inconsistency.
  RowBlock finish(std::vector<double> rhs);

 private:
  struct Chunk {
    std::vector<std::int64_t> column;
    std::vector<double> value;
  };
  struct Where {
    std::int64_t at = -1;   // first entry in its thread's chunk
    std::int32_t length = 0;
    std::int32_t thread = 0;
  };
  std::int64_t global_rows_, first_row_;
  std::vector<Chunk> chunks_;
  std::vector<Where> where_;
  std::string error_;  // the first inconsistency add_rows met
  void fail(std::string what);
};

// Contiguous ownership of `items` among `ranks`: the first items % ranks ranks get one more.
struct Range {
  std::int64_t begin, end;
};
Range owned_range(std::int64_t items, int ranks, int rank);

}  // namespace peridot::parallel

namespace peridot::parallel {

RowAssembly::RowAssembly(std::int64_t global_rows, std::int64_t first_row, std::int64_t rows, int threads)
    : global_rows_(global_rows), first_row_(first_row), chunks_(std::size_t(threads)), where_(std::size_t(rows)) {}

void RowAssembly::fail(std::string what) {
#pragma omp critical(peridot_row_assembly)
  if (error_.empty()) error_ = std::move(what);
}

void RowAssembly::add_rows(int thread, std::int64_t row, int count, std::vector<Entry>& entries) {
  const std::int64_t end = first_row_ + std::int64_t(where_.size());
  if (row < first_row_ || row + count > end) {
    fail(fmt::format("row assembly: rows [{}, {}) outside [{}, {})", row, row + count, first_row_, end));
    entries.clear();
    return;
  }
  std::sort(entries.begin(), entries.end(), [](const Entry& a, const Entry& b) { return a.row != b.row ? a.row < b.row : a.col < b.col; });
  auto& ch = chunks_[std::size_t(thread)];
  std::size_t k = 0;
  for (std::int64_t r = row; r < row + count; ++r) {
    auto& w = where_[std::size_t(r - first_row_)];
    w.at = std::int64_t(ch.column.size());
    w.thread = thread;
    for (; k < entries.size() && entries[k].row == r; ++k) {
      const auto& e = entries[k];
      if (e.col < 0 || e.col >= global_rows_) {
        fail(fmt::format("row assembly: column {} outside [0, {})", e.col, global_rows_));
        continue;
      }
      if (std::int64_t(ch.column.size()) > w.at && ch.column.back() == e.col) ch.value.back() += e.value;
      else ch.column.push_back(e.col), ch.value.push_back(e.value);
    }
    w.length = std::int32_t(std::int64_t(ch.column.size()) - w.at);
  }
  if (k != entries.size()) fail(fmt::format("row assembly: entries outside rows [{}, {})", row, row + count));
  entries.clear();
}

RowBlock RowAssembly::finish(std::vector<double> rhs) {
  if (!error_.empty()) throw std::logic_error(error_);
  if (rhs.size() != where_.size())
    throw std::invalid_argument(fmt::format("row assembly: {} right-hand sides for {} rows", rhs.size(), where_.size()));
  RowBlock b;
  b.global_rows = global_rows_;
  b.first_row = first_row_;
  b.rhs = std::move(rhs);
  b.offset.assign(where_.size() + 1, 0);
  for (std::size_t r = 0; r < where_.size(); ++r) {
    if (where_[r].at < 0) throw std::logic_error(fmt::format("row assembly: row {} was never added", first_row_ + std::int64_t(r)));
    b.offset[r + 1] = b.offset[r] + where_[r].length;
  }
  b.column.resize(std::size_t(b.offset.back()));
  b.value.resize(std::size_t(b.offset.back()));
  for (std::size_t r = 0; r < where_.size(); ++r) {
    const auto& w = where_[r];
    const auto& ch = chunks_[std::size_t(w.thread)];
    std::copy_n(ch.column.begin() + w.at, w.length, b.column.begin() + b.offset[r]);
    std::copy_n(ch.value.begin() + w.at, w.length, b.value.begin() + b.offset[r]);
  }
  std::vector<Chunk>().swap(chunks_);
  std::vector<Where>().swap(where_);
  return b;
}

Range owned_range(std::int64_t items, int ranks, int rank) {
  const std::int64_t q = items / ranks, r = items % ranks;
  const std::int64_t begin = rank * q + std::min<std::int64_t>(rank, r);
  return {begin, begin + q + (rank < r ? 1 : 0)};
}

}  // namespace peridot::parallel
