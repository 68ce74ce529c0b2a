// SPDX-License-Identifier: BSD-3-Clause
// The dense helpers of the C API: sba.h's sba_Axb_* solvers, symmetric inverses and
// sba_mat_cholinv, exported under their C names. What they do and what they promise is told
// in dense.cpp; none of them throws.
#include "dense.h"
#include "sba_export.h"

using sba::dense::Inverse;
using sba::dense::Method;

extern "C" {

int sba_Axb_QR(double *A, double *B, double *x, int m, int iscolmaj) {
  return sba::dense::axb(Method::QR, A, B, x, m, iscolmaj);
}

int sba_Axb_QRnoQ(double *A, double *B, double *x, int m, int iscolmaj) {
  return sba::dense::axb(Method::QRnoQ, A, B, x, m, iscolmaj);
}

int sba_Axb_Chol(double *A, double *B, double *x, int m, int iscolmaj) {
  return sba::dense::axb(Method::Chol, A, B, x, m, iscolmaj);
}

int sba_Axb_LDLt(double *A, double *B, double *x, int m, int iscolmaj) {
  return sba::dense::axb(Method::LDLt, A, B, x, m, iscolmaj);
}

int sba_Axb_LU(double *A, double *B, double *x, int m, int iscolmaj) {
  return sba::dense::axb(Method::LU, A, B, x, m, iscolmaj);
}

int sba_Axb_SVD(double *A, double *B, double *x, int m, int iscolmaj) {
  return sba::dense::axb(Method::SVD, A, B, x, m, iscolmaj);
}

int sba_Axb_BK(double *A, double *B, double *x, int m, int iscolmaj) {
  return sba::dense::axb(Method::BK, A, B, x, m, iscolmaj);
}

int sba_Axb_CG(double *A, double *B, double *x, int m, int niter, double eps, int prec,
               int iscolmaj) {
  return sba::dense::axb_cg(A, B, x, m, niter, eps, prec, iscolmaj);
}

int sba_symat_invert_LU(double *A, int m) { return sba::dense::symat_invert(Inverse::LU, A, m); }

int sba_symat_invert_Chol(double *A, int m) { return sba::dense::symat_invert(Inverse::Chol, A, m); }

int sba_symat_invert_BK(double *A, int m) { return sba::dense::symat_invert(Inverse::BK, A, m); }

int sba_mat_cholinv(double *A, double *B, int m) { return sba::dense::mat_cholinv(A, B, m); }

}  // extern "C"
