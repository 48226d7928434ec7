module;
#include <Eigen/SparseCore>

export module peridot.implicit:replicated_solve;
import peridot.std;
import peridot.parallel;

export namespace peridot {

// Solves A x = b on PETSc where every rank built the same A and b (a replicated set-up): each
// rank hands PETSc its contiguous block of rows and gets the whole x back, so the ranks go on in
// step. The factorisation or the Krylov solve is spread over the ranks; the assembly is not.
// Collective; throws as parallel::ksp_solve does (std::invalid_argument for refused options,
// std::runtime_error when the solve fails).
template <class Matrix>
std::vector<double> solve_on_ranks(const Matrix& A, const Eigen::VectorXd& b, const parallel::KspOptions& options,
                                   parallel::KspReport* report = nullptr) {
  parallel::start();
  const std::int64_t n = A.rows();
  if (A.cols() != n || b.size() != n) throw std::invalid_argument("solve_on_ranks: a square matrix and a right side of its size");
  const auto own = parallel::owned_range(n, parallel::ranks(), parallel::rank());
  // Row-major: each owned row's columns come out sorted and merged, as PETSc takes them.
  Eigen::SparseMatrix<double, Eigen::RowMajor, std::int64_t> rows;
  {
    const Eigen::SparseMatrix<double, Eigen::RowMajor, std::int64_t> all = A;
    rows = all.middleRows(own.begin, own.end - own.begin);
  }
  rows.makeCompressed();
  parallel::RowBlock block;
  block.global_rows = n;
  block.first_row = own.begin;
  block.offset.assign(rows.outerIndexPtr(), rows.outerIndexPtr() + rows.rows() + 1);
  block.column.assign(rows.innerIndexPtr(), rows.innerIndexPtr() + rows.nonZeros());
  block.value.assign(rows.valuePtr(), rows.valuePtr() + rows.nonZeros());
  block.rhs.assign(b.data() + own.begin, b.data() + own.end);
  rows = {};
  return parallel::ksp_solve(std::move(block), options, report);
}

// What a replicated solve ran, for a log column: "petsc preonly/lu (mumps)", "petsc gmres/hypre, 14 iterations".
inline std::string describe_petsc_solve(const parallel::KspReport& r) {
  return fmt::format("petsc {}/{}{}{}", r.ksp, r.pc, r.factor_package.empty() ? "" : " (" + r.factor_package + ")",
                     r.ksp == "preonly" ? "" : fmt::format(", {} iterations", r.iterations));
}

}  // namespace peridot
