// The dense solvers of the sba_Axb_* helpers, for the library's own use: the helpers turn every
// failure into a return value of 0, including running out of memory, which the LM loop would
// take for a failed factorization and answer with more damping. Here std::bad_alloc passes
// through, so that a solve out of memory ends in SBA_ERROR.
#ifndef SBA_SRC_DENSE_H
#define SBA_SRC_DENSE_H

namespace sba::dense {

enum class Method { LDLt, BK, LU, QR, SVD };

// Solves A x = b for the row-major m x m A as the matching sba_Axb_* helper does; false when
// it fails (singular, not finite). May throw std::bad_alloc.
bool solve(Method method, const double *A, const double *B, double *x, int m);

}  // namespace sba::dense

#endif
