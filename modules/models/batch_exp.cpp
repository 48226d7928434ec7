// A plain translation unit, not a module unit, so it alone is built with -fveclib=libmvec and
// -fno-math-errno (see CMakeLists.txt): the loop then becomes calls to glibc's vector exp, 2-4
// values at a time, which is what keeps RNP's force pass close to PMB's. The BMIs of the modules
// keep the project's default floating-point options.
#include <cmath>
#include <cstddef>

// Built for AVX-512, AVX2 and the baseline and picked at load time, so a portable build calls
// libmvec's 8-, 4- or 2-lane exp as the CPU allows.
extern "C" [[gnu::target_clones("avx512f", "avx2", "default")]] void peridot_batch_exp(double* x, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) x[i] = std::exp(x[i]);
}
