module;
#include <algorithm>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <vector>
#include <fmt/core.h>
export module peridot.parallel:row_block;

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

// Builds the block from unsorted entries whose rows all lie in [first_row, first_row + rows).
RowBlock make_row_block(std::int64_t global_rows, std::int64_t first_row, std::int64_t rows, std::span<const std::vector<Entry>> entries,
                        std::vector<double> rhs);

// Contiguous ownership of `items` among `ranks`: the first items % ranks ranks get one more.
struct Range {
  std::int64_t begin, end;
};
Range owned_range(std::int64_t items, int ranks, int rank);

}  // namespace peridot::parallel

namespace peridot::parallel {

RowBlock make_row_block(std::int64_t global_rows, std::int64_t first_row, std::int64_t rows, std::span<const std::vector<Entry>> entries,
                        std::vector<double> rhs) {
  if (std::int64_t(rhs.size()) != rows) throw std::invalid_argument(fmt::format("row block: {} right-hand sides for {} rows", rhs.size(), rows));
  RowBlock b;
  b.global_rows = global_rows;
  b.first_row = first_row;
  b.rhs = std::move(rhs);
  // Counting sort by row, then sort and merge each row's columns.
  std::vector<std::int64_t> count(std::size_t(rows) + 1, 0);
  for (const auto& list : entries)
    for (const auto& e : list) {
      if (e.row < first_row || e.row >= first_row + rows || e.col < 0 || e.col >= global_rows)
        throw std::logic_error(fmt::format("row block: entry ({}, {}) outside rows [{}, {}) of {}", e.row, e.col, first_row, first_row + rows, global_rows));
      ++count[std::size_t(e.row - first_row) + 1];
    }
  for (std::size_t r = 0; r < std::size_t(rows); ++r) count[r + 1] += count[r];
  std::vector<std::pair<std::int64_t, double>> slot(std::size_t(count.back()));
  auto fill = count;
  for (const auto& list : entries)
    for (const auto& e : list) slot[std::size_t(fill[std::size_t(e.row - first_row)]++)] = {e.col, e.value};
  b.offset.assign(std::size_t(rows) + 1, 0);
  b.column.reserve(slot.size());
  b.value.reserve(slot.size());
  for (std::size_t r = 0; r < std::size_t(rows); ++r) {
    auto first = slot.begin() + count[r], last = slot.begin() + count[r + 1];
    std::sort(first, last, [](const auto& a, const auto& c) { return a.first < c.first; });
    for (auto it = first; it != last; ++it) {
      if (!b.column.empty() && std::int64_t(b.column.size()) > b.offset[r] && b.column.back() == it->first) b.value.back() += it->second;
      else b.column.push_back(it->first), b.value.push_back(it->second);
    }
    b.offset[r + 1] = std::int64_t(b.column.size());
  }
  return b;
}

Range owned_range(std::int64_t items, int ranks, int rank) {
  const std::int64_t q = items / ranks, r = items % ranks;
  const std::int64_t begin = rank * q + std::min<std::int64_t>(rank, r);
  return {begin, begin + q + (rank < r ? 1 : 0)};
}

}  // namespace peridot::parallel
