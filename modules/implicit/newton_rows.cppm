module;
#include <Eigen/Core>
#include <Eigen/SVD>

export module peridot.implicit:newton_rows;
import peridot.std;
import peridot.models;
import peridot.parallel;
import :replicated_solve;

export namespace peridot {

// The 2-norm condition number of a dense matrix, by its singular values (small systems only).
double dense_condition_number(const Eigen::MatrixXd& A);

// A rank's rows of a Newton system on PETSc, for one part of a distributed body: the free
// components of its owned points, numbered rank after rank (owned points in their order,
// components in theirs), with the columns of the points' own blocks and of their partners,
// ghosts included, by their global unknown numbers. The pattern is built once; each assembly
// refills the values. No rank holds another's rows.
class NewtonRows {
 public:
  // unknown[d * i + k]: the global unknown of local point i's component k, or -1 where it is
  // fixed, for owned points and ghosts alike (a ghost's comes from its owner). `global`: the
  // unknowns of the whole body; `first`: this rank's first row.
  NewtonRows(const Body& body, std::span<const std::int64_t> owned, const std::vector<std::int64_t>& unknown, std::int64_t global,
             std::int64_t first);
  // Writes -K (the model's blocks for the owned rows) into the rows.
  void assemble(const TangentBlocks& K);
  // Solves (-K) dx = rhs (this rank's rows) on PETSc; returns this rank's rows of dx, or
  // nullopt on every rank when the solve fails or any rank's part of dx is not finite.
  // Collective. `used` names what ran.
  std::optional<Eigen::VectorXd> solve(const Eigen::VectorXd& rhs, const parallel::KspOptions& options, std::string& used);
  // The 2-norm condition number of the assembled -K of all ranks: the rows go to rank 0 for a
  // dense SVD (8 n^2 bytes there; the caller bounds n). Collective; the same value on every rank.
  double condition_number() const;
  // The local degree of freedom d * i + k of each row, in row order.
  const std::vector<std::int64_t>& row_dofs() const { return dofs_; }
  std::int64_t global_rows() const { return pattern_.global_rows; }

 private:
  int dim_;
  parallel::RowBlock pattern_;  // columns sorted within each row; values refilled by assemble()
  // Where each block entry goes among the values, -1 for a fixed row or column: the diagonal
  // blocks of local points [i * d * d + r * d + c] and the bond blocks [b * d * d + r * d + c].
  std::vector<std::int64_t> diag_slot_, bond_slot_;
  std::vector<std::int64_t> dofs_;
};

}  // namespace peridot

namespace peridot {

NewtonRows::NewtonRows(const Body& body, std::span<const std::int64_t> owned, const std::vector<std::int64_t>& unknown, std::int64_t global,
                       std::int64_t first)
    : dim_(body.dim()) {
  const auto d = std::size_t(dim_), bs = d * d;
  const auto& bl = body.bonds;
  diag_slot_.assign(body.size() * bs, -1);
  bond_slot_.assign(bl.size() * bs, -1);
  pattern_.global_rows = global;
  pattern_.first_row = first;
  // One row at a time: its (column, slot) pairs sorted by column; slots name block entries.
  struct Cell {
    std::int64_t column;
    std::int64_t* slot;
  };
  std::vector<Cell> row;
  for (const auto p : owned) {
    const auto i = std::size_t(p);
    for (std::size_t r = 0; r < d; ++r) {
      const auto own = unknown[i * d + r];
      if (own < 0) continue;
      if (own != first + std::int64_t(dofs_.size()))
        throw std::logic_error(fmt::format("NewtonRows: point {} component {} is unknown {}, not row {}", i, r, own, first + std::int64_t(dofs_.size())));
      dofs_.push_back(std::int64_t(i * d + r));
      row.clear();
      for (std::size_t c = 0; c < d; ++c)
        if (const auto col = unknown[i * d + c]; col >= 0) row.push_back({col, &diag_slot_[i * bs + r * d + c]});
      for (auto b = bl.offset[i]; b < bl.offset[i + 1]; ++b) {
        const auto j = std::size_t(bl.neighbor[b]);
        for (std::size_t c = 0; c < d; ++c)
          if (const auto col = unknown[j * d + c]; col >= 0) row.push_back({col, &bond_slot_[std::size_t(b) * bs + r * d + c]});
      }
      std::sort(row.begin(), row.end(), [](const Cell& a, const Cell& b) { return a.column < b.column; });
      for (std::size_t q = 0; q < row.size(); ++q) {
        // A partner listed twice would add into one entry.
        if (q == 0 || row[q].column != row[q - 1].column) pattern_.column.push_back(row[q].column);
        *row[q].slot = std::int64_t(pattern_.column.size()) - 1;
      }
      pattern_.offset.push_back(std::int64_t(pattern_.column.size()));
    }
  }
  pattern_.value.assign(pattern_.column.size(), 0.0);
}

double dense_condition_number(const Eigen::MatrixXd& A) {
  const Eigen::BDCSVD<Eigen::MatrixXd> svd(A);
  const auto& sv = svd.singularValues();
  return sv(sv.size() - 1) > 0 ? sv(0) / sv(sv.size() - 1) : INFINITY;
}

double NewtonRows::condition_number() const {
  // Each nonzero as (row, column, value), every rank's after the one before.
  std::vector<double> mine;
  mine.reserve(3 * pattern_.value.size());
  for (std::int64_t r = 0; r < pattern_.rows(); ++r)
    for (auto k = pattern_.offset[std::size_t(r)]; k < pattern_.offset[std::size_t(r) + 1]; ++k)
      mine.insert(mine.end(), {double(pattern_.first_row + r), double(pattern_.column[std::size_t(k)]), pattern_.value[std::size_t(k)]});
  const auto sizes = parallel::all_gather(std::uint64_t(mine.size()));
  std::vector<std::size_t> starts{0};
  for (auto n : sizes) starts.push_back(starts.back() + std::size_t(n));
  const bool root = parallel::rank() == 0;
  std::vector<double> all(root ? starts.back() : 0);
  parallel::gather_to_root(mine, all, starts);
  double cond = 0;
  if (root) {
    Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(pattern_.global_rows, pattern_.global_rows);
    for (std::size_t k = 0; k < all.size(); k += 3) dense(Eigen::Index(all[k]), Eigen::Index(all[k + 1])) = all[k + 2];
    cond = dense_condition_number(dense);
  }
  // The others add zeros: rank 0's value, exactly (an infinite one too).
  return parallel::sum_over_ranks(cond);
}

void NewtonRows::assemble(const TangentBlocks& K) {
  std::fill(pattern_.value.begin(), pattern_.value.end(), 0.0);
  double* v = pattern_.value.data();
  for (std::size_t k = 0; k < diag_slot_.size(); ++k)
    if (diag_slot_[k] >= 0) v[diag_slot_[k]] -= K.diagonal[k];
  for (std::size_t k = 0; k < bond_slot_.size(); ++k)
    if (bond_slot_[k] >= 0) v[bond_slot_[k]] -= K.bond[k];
}

std::optional<Eigen::VectorXd> NewtonRows::solve(const Eigen::VectorXd& rhs, const parallel::KspOptions& options, std::string& used) {
  parallel::RowBlock block = pattern_;
  block.rhs.assign(rhs.data(), rhs.data() + rhs.size());
  parallel::KspReport report;
  std::vector<double> x;
  try {
    x = parallel::ksp_solve(std::move(block), options, &report, parallel::SolutionRows::own);
  } catch (const std::runtime_error& e) {
    // PETSc's verdict is collective: every rank fails alike, and the increment is cut on all.
    used = fmt::format("petsc failed: {}", e.what());
    return std::nullopt;
  }
  used = describe_petsc_solve(report);
  Eigen::VectorXd out = Eigen::Map<const Eigen::VectorXd>(x.data(), Eigen::Index(x.size()));
  if (parallel::max_over_ranks(out.allFinite() ? 0 : 1) != 0) return std::nullopt;
  return out;
}

}  // namespace peridot
