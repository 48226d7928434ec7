// The PETSc linear solve's own contract: the iterative default (GMRES + BoomerAMG) gives way to
// LU when it fails, unless options were given or the matrix is too large to factorise.
#include <catch2/catch.hpp>

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>
import peridot.parallel;

using namespace peridot::parallel;

namespace {

// The 1D Laplacian tridiag(-1, 2, -1) of n rows on one rank, with b = A x for x_k = sin(k).
RowBlock laplacian(std::int64_t n) {
  RowBlock b;
  b.global_rows = n;
  for (std::int64_t i = 0; i < n; ++i) {
    double rhs = 0;
    for (std::int64_t j = i - 1; j <= i + 1; ++j) {
      if (j < 0 || j >= n) continue;
      const double a = j == i ? 2.0 : -1.0;
      b.column.push_back(j);
      b.value.push_back(a);
      rhs += a * std::sin(double(j));
    }
    b.offset.push_back(std::int64_t(b.column.size()));
    b.rhs.push_back(rhs);
  }
  return b;
}

}  // namespace

TEST_CASE("when GMRES + BoomerAMG fails the same matrix is solved by LU, and the report says why") {
  KspOptions o;
  o.direct_below = 0;     // the iterative default at any size
  o.max_iterations = 1;   // and one iteration cannot reach 1e-12
  KspReport report;
  const auto x = ksp_solve(laplacian(400), o, &report);
  REQUIRE(x.size() == 400);
  double worst = 0;
  for (std::size_t k = 0; k < x.size(); ++k) worst = std::max(worst, std::abs(x[k] - std::sin(double(k))));
  CHECK(worst < 1e-9);
  CHECK(report.residual < 1e-12);
  CHECK(report.pc == "lu");
  CHECK(report.fallback.find("GMRES + BoomerAMG DIVERGED_ITS after 1 iterations") != std::string::npos);
}

TEST_CASE("a failed iterative solve is an error, not a silent LU, when options chose the solver or the matrix is too large to factorise") {
  using Catch::Matchers::Contains;
  KspOptions chosen;
  chosen.direct_below = 0;
  chosen.max_iterations = 1;
  chosen.options = "-ksp_gmres_restart 30";
  REQUIRE_THROWS_WITH(ksp_solve(laplacian(400), chosen), Contains("did not converge") && Contains("DIVERGED_ITS"));
  KspOptions large = chosen;
  large.options.clear();
  large.fallback_nonzeros = 100;  // the Laplacian has 1198
  REQUIRE_THROWS_WITH(ksp_solve(laplacian(400), large), Contains("did not converge") && Contains("DIVERGED_ITS"));
}
