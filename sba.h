/* SPDX-License-Identifier: BSD-3-Clause */
/*
 * sba: generic sparse bundle adjustment, a C++ reimplementation with the C API
 * of M. Lourakis' sba 1.6 (sba 1.6 programs compile and link against it unchanged).
 *
 * Problem layout (see README.md and the sba paper, ACM TOMS 36(1), 2009):
 *   n points, m cameras; camera j has cnp parameters a_j, point i has pnp parameters b_i,
 *   a projection x_ij has mnp coordinates.
 *   p      = (a_1..a_m, b_1..b_n), updated in place (only the a's for sba_mot_*,
 *            only the b's for sba_str_*).
 *   vmask  = n*m chars, vmask[i*m+j] != 0 iff point i is seen in image j.
 *   x      = the measured x_ij of the visible (i,j), point by point, cameras ascending.
 *   covx   = NULL or one mnp x mnp covariance (row-major) per measurement, in x's order.
 *   mcon   = cameras 0..mcon-1 are held fixed; ncon = points 0..ncon-1 are held fixed.
 *   opts   = (tau, eps1, eps2, eps3, eps4) or NULL for the defaults.
 *   info   = NULL or SBA_INFOSZ doubles:
 *            [0] ||e(p0)||^2, [1] ||e(p_final)||^2, [2] ||J^T e||_inf, [3] ||dp||^2,
 *            [4] mu / max diag(J^T J), [5] iterations, [6] stop reason (SBA_STOP_* of sba_ext.h),
 *            [7] function evaluations, [8] Jacobian evaluations, [9] linear systems solved,
 *            counted as sba 1.6 counts them: [7] the LM loop's calls of func (not those
 *            that build a finite-difference Jacobian); the simple drivers count proj and
 *            projac calls (nvis per func/fjac call); the motion-only and structure-only
 *            drivers count one system per free camera (point) block.
 *   verbose = what sba 1.6 prints on stdout: > 0 its "initial ...-SBA error" line (and which
 *            projection is NaN or Inf, if one is), > 1 its lines for every trial point.
 * The drivers return the number of iterations, or SBA_ERROR.
 *
 * Compile with -DSBA_API_1_5 to get the sba 1.5 driver signatures (no ncon).
 */
#ifndef SBA_H
#define SBA_H
/* sba 1.6's include guard, defined as well because 1.6 programs test it to see whether sba.h
 * has been included (a reserved name: it is 1.6's, and programs spell it so). */
#ifndef _SBA_H_
#define _SBA_H_
#endif

/* In 1.6 this selected LAPACK routine names with a trailing underscore (to be undefined for
 * AIX). It configures nothing here: the build finds out how the installed LAPACK names its
 * routines. It is defined only for programs that test it (and left alone when a program's
 * build already defines it, e.g. with -D). */
#ifndef SBA_APPEND_UNDERSCORE_SUFFIX
#define SBA_APPEND_UNDERSCORE_SUFFIX
#endif

#ifdef __cplusplus
extern "C" {
#endif

#define SBA_MIN_DELTA 1E-06   /* smallest finite-difference step */
#define SBA_DELTA_SCALE 1E-04 /* relative finite-difference step */

#define SBA_OPTSSZ 5
#define SBA_INFOSZ 10
#define SBA_ERROR -1
#define SBA_INIT_MU 1E-03
#define SBA_STOP_THRESH 1E-12

#define SBA_CG_NOPREC 0
#define SBA_CG_JACOBI 1
#define SBA_CG_SSOR 2

#define SBA_VERSION "1.6-compatible (sba-cpp 0.1.0)"

/* Compressed row storage of the visibility index: row i is point i, column j camera j,
 * val[k] is the ordinal of x_ij in the measurement vector. Field order is ABI. */
struct sba_crsm {
  int nr, nc;  /* rows, columns */
  int nnz;     /* number of nonzeros */
  int *val;    /* nnz values */
  int *colidx; /* nnz column indices */
  int *rowptr; /* nr+1 row starts; rowptr[nr] == nnz */
};

/* ---- simple drivers: callbacks per projection x_ij ---- */

/* Every callback (proj, projac, func, fjac) must return normally. Do not longjmp out of
 * one: the solve's memory leaks, and with more than one thread it crashes the process. A
 * C++ exception thrown by a callback is caught at the library's boundary: the call returns
 * SBA_ERROR with everything freed and p the last accepted estimate. To stop a solve from a
 * callback, write a NaN into its output (the solve stops with SBA_ERROR and info[6] = 7,
 * p the last accepted estimate), or, with sba_ext.h, return nonzero from the progress
 * callback (info[6] = SBA_STOP_USER, a normal return). */

/* Motion and structure. proj writes x_ij (mnp values) from a_j and b_i; projac writes
 * A_ij = dx_ij/da_j (mnp x cnp) and B_ij = dx_ij/db_i (mnp x pnp), row-major;
 * projac == NULL means forward-difference Jacobians. */
extern int sba_motstr_levmar(const int n, const int ncon, const int m, const int mcon, char *vmask,
                             double *p, const int cnp, const int pnp, double *x, double *covx,
                             const int mnp,
                             void (*proj)(int j, int i, double *aj, double *bi, double *xij, void *adata),
                             void (*projac)(int j, int i, double *aj, double *bi, double *Aij,
                                            double *Bij, void *adata),
                             void *adata, const int itmax, const int verbose,
                             const double opts[SBA_OPTSSZ], double info[SBA_INFOSZ]);

/* Motion only: p holds the m*cnp camera parameters. */
extern int sba_mot_levmar(const int n, const int m, const int mcon, char *vmask, double *p,
                          const int cnp, double *x, double *covx, const int mnp,
                          void (*proj)(int j, int i, double *aj, double *xij, void *adata),
                          void (*projac)(int j, int i, double *aj, double *Aij, void *adata),
                          void *adata, const int itmax, const int verbose,
                          const double opts[SBA_OPTSSZ], double info[SBA_INFOSZ]);

/* Structure only: p holds the n*pnp point parameters. */
extern int sba_str_levmar(const int n, const int ncon, const int m, char *vmask, double *p,
                          const int pnp, double *x, double *covx, const int mnp,
                          void (*proj)(int j, int i, double *bi, double *xij, void *adata),
                          void (*projac)(int j, int i, double *bi, double *Bij, void *adata),
                          void *adata, const int itmax, const int verbose,
                          const double opts[SBA_OPTSSZ], double info[SBA_INFOSZ]);

/* ---- expert drivers: callbacks over the whole parameter vector ----
 * func writes every predicted x_ij into hx in x's order. fjac writes, for every visible
 * (i,j) in x's order, A_ij then B_ij (row-major, back to back; only A_ij for sba_mot_*,
 * only B_ij for sba_str_*). rcidxs and rcsubs are scratch arrays of max(n,m) ints for use
 * with sba_crsm_row_elmidxs / sba_crsm_col_elmidxs. fjac == NULL means forward differences. */
extern int sba_motstr_levmar_x(
    const int n, const int ncon, const int m, const int mcon, char *vmask, double *p, const int cnp,
    const int pnp, double *x, double *covx, const int mnp,
    void (*func)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *hx, void *adata),
    void (*fjac)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *jac, void *adata),
    void *adata, const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
    double info[SBA_INFOSZ]);

extern int sba_mot_levmar_x(
    const int n, const int m, const int mcon, char *vmask, double *p, const int cnp, double *x,
    double *covx, const int mnp,
    void (*func)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *hx, void *adata),
    void (*fjac)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *jac, void *adata),
    void *adata, const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
    double info[SBA_INFOSZ]);

extern int sba_str_levmar_x(
    const int n, const int ncon, const int m, char *vmask, double *p, const int pnp, double *x,
    double *covx, const int mnp,
    void (*func)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *hx, void *adata),
    void (*fjac)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *jac, void *adata),
    void *adata, const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
    double info[SBA_INFOSZ]);

/* ---- dense linear algebra: solve A x = B for an m x m A (column-major if iscolmaj,
 * else row-major). Return 1 on success, 0 on failure; A and B are left unchanged.
 * A call with A == NULL is accepted and does nothing (1.6 used it to free buffers). ---- */
extern int sba_Axb_QR(double *A, double *B, double *x, int m, int iscolmaj);
extern int sba_Axb_QRnoQ(double *A, double *B, double *x, int m, int iscolmaj);
extern int sba_Axb_Chol(double *A, double *B, double *x, int m, int iscolmaj);
extern int sba_Axb_LDLt(double *A, double *B, double *x, int m, int iscolmaj);
extern int sba_Axb_LU(double *A, double *B, double *x, int m, int iscolmaj);
extern int sba_Axb_SVD(double *A, double *B, double *x, int m, int iscolmaj);
extern int sba_Axb_BK(double *A, double *B, double *x, int m, int iscolmaj);
/* Conjugate gradients on SPD A with relative residual tolerance eps (||B - A x|| <= eps ||B||,
 * eps <= 0: 1e-12) and preconditioner prec (SBA_CG_*). niter > 0: from x = 0, at most niter
 * iterations; niter < 0: from the starting point in x, at most -niter; niter == 0: from 0, at
 * most m. Returns the iterations performed as sba 1.6 counts them (k updates of x and the
 * test that sees convergence: k + 1); when the budget runs out first, the budget, with x the
 * last iterate. 0 on failure (not SPD, bad arguments, NaN). */
extern int sba_Axb_CG(double *A, double *B, double *x, int m, int niter, double eps, int prec,
                      int iscolmaj);

/* Invert the symmetric m x m A (row-major) in place, as sba 1.6 does: only the upper triangle
 * (A[i*m+j], j >= i) is read, the inverse is written to the lower triangle with the diagonal
 * (A[i*m+j], j <= i), and the strictly upper triangle keeps its input. 1 on success, 0 on
 * failure (singular; not positive definite for _Chol), with A left as it was. */
extern int sba_symat_invert_LU(double *A, int m);
extern int sba_symat_invert_Chol(double *A, int m);
extern int sba_symat_invert_BK(double *A, int m);
/* B (upper triangular, row-major, m x m) such that B^T B = A^-1 for SPD A; 1 ok, 0 fail. */
extern int sba_mat_cholinv(double *A, double *B, int m);

/* ---- the sparse visibility index ---- */
extern void sba_crsm_alloc(struct sba_crsm *sm, int nr, int nc, int nnz);
extern void sba_crsm_free(struct sba_crsm *sm);
/* index k in val of element (i,j), -1 if (i,j) is not stored */
extern int sba_crsm_elmidx(struct sba_crsm *sm, int i, int j);
/* same, given that (i,jp) is stored at index jpidx: a hint that shortens the search */
extern int sba_crsm_elmidxp(struct sba_crsm *sm, int i, int j, int jp, int jpidx);
/* the val indices and column numbers of row i's elements; returns their count */
extern int sba_crsm_row_elmidxs(struct sba_crsm *sm, int i, int *vidxs, int *jidxs);
/* the val indices and row numbers of column j's elements; returns their count */
extern int sba_crsm_col_elmidxs(struct sba_crsm *sm, int j, int *vidxs, int *iidxs);

#ifdef SBA_API_1_5
/* sba 1.5 had no ncon: map its driver calls onto 1.6 with no fixed points. A macro does
 * not re-expand its own name, so the 1.6 function is what gets called. */
#define sba_motstr_levmar(n, m, mcon, vmask, p, cnp, pnp, x, covx, mnp, proj, projac, adata, itmax, \
                          verbose, opts, info)                                                        \
  sba_motstr_levmar((n), 0, (m), (mcon), (vmask), (p), (cnp), (pnp), (x), (covx), (mnp), (proj),     \
                    (projac), (adata), (itmax), (verbose), (opts), (info))
#define sba_str_levmar(n, m, vmask, p, pnp, x, covx, mnp, proj, projac, adata, itmax, verbose, opts, \
                       info)                                                                          \
  sba_str_levmar((n), 0, (m), (vmask), (p), (pnp), (x), (covx), (mnp), (proj), (projac), (adata),    \
                 (itmax), (verbose), (opts), (info))
#define sba_motstr_levmar_x(n, m, mcon, vmask, p, cnp, pnp, x, covx, mnp, func, fjac, adata, itmax, \
                            verbose, opts, info)                                                      \
  sba_motstr_levmar_x((n), 0, (m), (mcon), (vmask), (p), (cnp), (pnp), (x), (covx), (mnp), (func),   \
                      (fjac), (adata), (itmax), (verbose), (opts), (info))
#define sba_str_levmar_x(n, m, vmask, p, pnp, x, covx, mnp, func, fjac, adata, itmax, verbose, opts, \
                         info)                                                                        \
  sba_str_levmar_x((n), 0, (m), (vmask), (p), (pnp), (x), (covx), (mnp), (func), (fjac), (adata),    \
                   (itmax), (verbose), (opts), (info))
#endif /* SBA_API_1_5 */

#ifdef __cplusplus
}
#endif

#endif /* SBA_H */
