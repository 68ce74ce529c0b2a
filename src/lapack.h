/* SPDX-License-Identifier: BSD-3-Clause */
// Private prototypes of the Fortran LAPACK/BLAS routines the library calls. The symbol
// naming (trailing underscore or not) comes from the build's probe in sba_lapack_config.h.
// Character arguments carry gfortran's hidden length arguments so that the calls are correct
// for LAPACK builds compiled with gfortran >= 8, which may rely on them.
#ifndef SBA_SRC_LAPACK_H
#define SBA_SRC_LAPACK_H

#include <cstddef>

#include "sba_lapack_config.h"

namespace sba::lapack {
using flen = std::size_t;
}

extern "C" {
// Cholesky
void SBA_F77(dpotrf, DPOTRF)(const char *uplo, const int *n, double *a, const int *lda, int *info,
                             sba::lapack::flen);
void SBA_F77(dpotrs, DPOTRS)(const char *uplo, const int *n, const int *nrhs, const double *a,
                             const int *lda, double *b, const int *ldb, int *info, sba::lapack::flen);
void SBA_F77(dpotri, DPOTRI)(const char *uplo, const int *n, double *a, const int *lda, int *info,
                             sba::lapack::flen);
// LU
void SBA_F77(dgetrf, DGETRF)(const int *m, const int *n, double *a, const int *lda, int *ipiv,
                             int *info);
void SBA_F77(dgetrs, DGETRS)(const char *trans, const int *n, const int *nrhs, const double *a,
                             const int *lda, const int *ipiv, double *b, const int *ldb, int *info,
                             sba::lapack::flen);
void SBA_F77(dgetri, DGETRI)(const int *n, double *a, const int *lda, const int *ipiv, double *work,
                             const int *lwork, int *info);
// QR
void SBA_F77(dgeqrf, DGEQRF)(const int *m, const int *n, double *a, const int *lda, double *tau,
                             double *work, const int *lwork, int *info);
void SBA_F77(dorgqr, DORGQR)(const int *m, const int *n, const int *k, double *a, const int *lda,
                             const double *tau, double *work, const int *lwork, int *info);
void SBA_F77(dtrtrs, DTRTRS)(const char *uplo, const char *trans, const char *diag, const int *n,
                             const int *nrhs, const double *a, const int *lda, double *b,
                             const int *ldb, int *info, sba::lapack::flen, sba::lapack::flen,
                             sba::lapack::flen);
// SVD
void SBA_F77(dgesdd, DGESDD)(const char *jobz, const int *m, const int *n, double *a, const int *lda,
                             double *s, double *u, const int *ldu, double *vt, const int *ldvt,
                             double *work, const int *lwork, int *iwork, int *info,
                             sba::lapack::flen);
// Symmetric indefinite (Bunch-Kaufman)
void SBA_F77(dsytrf, DSYTRF)(const char *uplo, const int *n, double *a, const int *lda, int *ipiv,
                             double *work, const int *lwork, int *info, sba::lapack::flen);
void SBA_F77(dsytrs, DSYTRS)(const char *uplo, const int *n, const int *nrhs, const double *a,
                             const int *lda, const int *ipiv, double *b, const int *ldb, int *info,
                             sba::lapack::flen);
void SBA_F77(dsytri, DSYTRI)(const char *uplo, const int *n, double *a, const int *lda,
                             const int *ipiv, double *work, int *info, sba::lapack::flen);
// Symmetric eigendecomposition (the pseudo-inverse of a gauge-deficient S)
void SBA_F77(dsyev, DSYEV)(const char *jobz, const char *uplo, const int *n, double *a,
                           const int *lda, double *w, double *work, const int *lwork, int *info,
                           sba::lapack::flen, sba::lapack::flen);
}

#endif
