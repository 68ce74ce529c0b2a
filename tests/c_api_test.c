/* SPDX-License-Identifier: BSD-3-Clause */
/* Compiled as C (C99, -pedantic): sba.h and sba_ext.h must be valid C headers, and every
 * exported function must be callable from C. A tiny two-camera problem with a linear "projection" keeps the
 * arithmetic checkable by hand. Exit status 0 on success. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "sba.h"
#include "sba_ext.h"

static int failures = 0;
#define CHECK(cond)                                                  \
  do {                                                               \
    if (!(cond)) {                                                   \
      fprintf(stderr, "%s:%d: check failed: %s\n", __FILE__, __LINE__, #cond); \
      ++failures;                                                    \
    }                                                                \
  } while (0)

/* x_ij = a_j + b_i (1-D cameras and points, mnp = 1): linear, so LM converges at once. */
static void proj(int j, int i, double *aj, double *bi, double *xij, void *adata) {
  (void)j; (void)i; (void)adata;
  xij[0] = aj[0] + bi[0];
}
static void projac(int j, int i, double *aj, double *bi, double *A, double *B, void *adata) {
  (void)j; (void)i; (void)aj; (void)bi; (void)adata;
  A[0] = 1.0;
  B[0] = 1.0;
}
static void mproj(int j, int i, double *aj, double *xij, void *adata) {
  const double *pts = (const double *)adata;
  xij[0] = aj[0] + pts[i];
  (void)j;
}
static void sproj(int j, int i, double *bi, double *xij, void *adata) {
  const double *cams = (const double *)adata;
  xij[0] = cams[j] + bi[0];
  (void)i;
}
static void func(double *p, struct sba_crsm *idx, int *rcidxs, int *rcsubs, double *hx, void *adata) {
  int i, k, nnz;
  (void)adata;
  for (i = 0; i < idx->nr; ++i) {
    nnz = sba_crsm_row_elmidxs(idx, i, rcidxs, rcsubs);
    for (k = 0; k < nnz; ++k) hx[idx->val[rcidxs[k]]] = p[rcsubs[k]] + p[idx->nc + i];
  }
}
static void fjac(double *p, struct sba_crsm *idx, int *rcidxs, int *rcsubs, double *jac, void *adata) {
  int k;
  (void)p; (void)rcidxs; (void)rcsubs; (void)adata;
  for (k = 0; k < idx->nnz; ++k) jac[2 * k] = jac[2 * k + 1] = 1.0;
}
static void mfunc(double *p, struct sba_crsm *idx, int *r, int *s, double *hx, void *adata) {
  const double *pts = (const double *)adata;
  int i, k;
  (void)r; (void)s;
  for (i = 0; i < idx->nr; ++i)
    for (k = idx->rowptr[i]; k < idx->rowptr[i + 1]; ++k) hx[idx->val[k]] = p[idx->colidx[k]] + pts[i];
}
static void sfunc(double *p, struct sba_crsm *idx, int *r, int *s, double *hx, void *adata) {
  const double *cams = (const double *)adata;
  int i, k;
  (void)r; (void)s;
  for (i = 0; i < idx->nr; ++i)
    for (k = idx->rowptr[i]; k < idx->rowptr[i + 1]; ++k) hx[idx->val[k]] = cams[idx->colidx[k]] + p[i];
}

/* A camera prior by callback: r = a_j - 2 (dim 1), its Jacobian 1. */
static void cam_prior(int j, const double *aj, double *r, void *data) {
  (void)j; (void)data;
  r[0] = aj[0] - 2.0;
}
static void cam_prior_jac(int j, const double *aj, double *jac, void *data) {
  (void)j; (void)aj; (void)data;
  jac[0] = 1.0;
}

int main(void) {
  /* 3 points, 2 cameras, all visible; camera 0 fixed (mcon = 1) removes the gauge. */
  char vmask[6] = {1, 1, 1, 1, 1, 1};
  const double truth[5] = {0.0, 2.0, 1.0, -1.0, 3.0};
  double x[6], p[5], info[SBA_INFOSZ], cams[2] = {0.0, 2.0}, pts[3] = {1.0, -1.0, 3.0};
  int i, j, k = 0, ret;
  for (i = 0; i < 3; ++i)
    for (j = 0; j < 2; ++j) x[k++] = truth[j] + truth[2 + i];

  memcpy(p, truth, sizeof p);
  p[1] = 2.5; p[2] = 0.5; p[3] = -0.7; p[4] = 3.2;
  ret = sba_motstr_levmar(3, 0, 2, 1, vmask, p, 1, 1, x, NULL, 1, proj, projac, NULL, 50, 0, NULL, info);
  CHECK(ret > 0);
  CHECK(info[1] < 1e-20);
  CHECK(fabs(p[1] - 2.0) < 1e-9 && fabs(p[3] + 1.0) < 1e-9);

  p[1] = 2.5; p[2] = 0.5; p[3] = -0.7; p[4] = 3.2;
  ret = sba_motstr_levmar_x(3, 0, 2, 1, vmask, p, 1, 1, x, NULL, 1, func, fjac, NULL, 50, 0, NULL, info);
  CHECK(ret > 0 && info[1] < 1e-20);

  { double a[2] = {0.3, 2.4};
    ret = sba_mot_levmar(3, 2, 0, vmask, a, 1, x, NULL, 1, mproj, NULL, pts, 50, 0, NULL, info);
    CHECK(ret > 0 && fabs(a[1] - 2.0) < 1e-6);
    a[0] = 0.3; a[1] = 2.4;
    ret = sba_mot_levmar_x(3, 2, 0, vmask, a, 1, x, NULL, 1, mfunc, NULL, pts, 50, 0, NULL, info);
    CHECK(ret > 0 && fabs(a[0]) < 1e-6); }
  { double b[3] = {0.0, 0.0, 0.0};
    ret = sba_str_levmar(3, 0, 2, vmask, b, 1, x, NULL, 1, sproj, NULL, cams, 50, 0, NULL, info);
    CHECK(ret > 0 && fabs(b[2] - 3.0) < 1e-6);
    b[0] = b[1] = b[2] = 0.0;
    ret = sba_str_levmar_x(3, 0, 2, vmask, b, 1, x, NULL, 1, sfunc, NULL, cams, 50, 0, NULL, info);
    CHECK(ret > 0 && fabs(b[1] + 1.0) < 1e-6); }

  /* Dense helpers: A = [4 1; 1 3], b = [1 2] -> x = [1/11, 7/11]. */
  { double A[4] = {4, 1, 1, 3}, b[2] = {1, 2}, s[2], inv[4], U[4];
    const double x0 = 1.0 / 11.0, x1 = 7.0 / 11.0;
#define SOLVES(call) (s[0] = s[1] = 0.0, (call) == 1 && fabs(s[0] - x0) < 1e-12 && fabs(s[1] - x1) < 1e-12)
    CHECK(SOLVES(sba_Axb_QR(A, b, s, 2, 0)));
    CHECK(SOLVES(sba_Axb_QRnoQ(A, b, s, 2, 1)));
    CHECK(SOLVES(sba_Axb_Chol(A, b, s, 2, 0)));
    CHECK(SOLVES(sba_Axb_LDLt(A, b, s, 2, 0)));
    CHECK(SOLVES(sba_Axb_LU(A, b, s, 2, 1)));
    CHECK(SOLVES(sba_Axb_SVD(A, b, s, 2, 0)));
    CHECK(SOLVES(sba_Axb_BK(A, b, s, 2, 0)));
    s[0] = s[1] = 0.0;
    CHECK(sba_Axb_CG(A, b, s, 2, 10, 1e-14, SBA_CG_JACOBI, 0) > 0 && fabs(s[1] - x1) < 1e-10);
    CHECK(sba_Axb_Chol(NULL, NULL, NULL, 0, 0) == 1); /* the 1.6 buffer-release call */
    memcpy(inv, A, sizeof inv);
    CHECK(sba_symat_invert_LU(inv, 2) == 1 && fabs(inv[0] - 3.0 / 11.0) < 1e-12);
    memcpy(inv, A, sizeof inv);
    /* 1.6's layout: the inverse in the lower triangle, the strictly upper one kept */
    CHECK(sba_symat_invert_Chol(inv, 2) == 1 && fabs(inv[2] + 1.0 / 11.0) < 1e-12 && inv[1] == A[1]);
    memcpy(inv, A, sizeof inv);
    CHECK(sba_symat_invert_BK(inv, 2) == 1 && fabs(inv[3] - 4.0 / 11.0) < 1e-12);
    CHECK(sba_mat_cholinv(A, U, 2) == 1 && U[2] == 0.0);
    /* U^T U = A^-1: (0,0) entry is U00^2 = 3/11 */
    CHECK(fabs(U[0] * U[0] - 3.0 / 11.0) < 1e-12); }

  /* crsm helpers on the paper's 4 x 3 example. */
  { struct sba_crsm sm;
    const int colidx[8] = {0, 1, 1, 2, 1, 2, 1, 2}, rowptr[5] = {0, 2, 4, 6, 8};
    int v[4], c[4];
    sba_crsm_alloc(&sm, 4, 3, 8);
    for (k = 0; k < 8; ++k) { sm.val[k] = k; sm.colidx[k] = colidx[k]; }
    for (k = 0; k < 5; ++k) sm.rowptr[k] = rowptr[k];
    CHECK(sba_crsm_elmidx(&sm, 1, 2) == 3);
    CHECK(sba_crsm_elmidx(&sm, 0, 2) == -1);
    CHECK(sba_crsm_elmidxp(&sm, 2, 2, 1, 4) == 5);
    CHECK(sba_crsm_row_elmidxs(&sm, 2, v, c) == 2 && v[0] == 4 && c[1] == 2);
    CHECK(sba_crsm_col_elmidxs(&sm, 1, v, c) == 4 && v[3] == 6 && c[3] == 3);
    sba_crsm_free(&sm); }

  /* The stop reasons: info[6] as sba 1.6 documents it (1..7) and this library's, each in words. */
  CHECK(SBA_STOP_GRADIENT == 1 && SBA_STOP_STEP == 2 && SBA_STOP_ITMAX == 3 && SBA_STOP_REDUCTION == 4 &&
        SBA_STOP_ERROR == 5 && SBA_STOP_DAMPING == 6 && SBA_STOP_NONFINITE == 7);
  CHECK(SBA_STOP_NONE == 0 && SBA_STOP_SINGULAR == 8 && SBA_STOP_USER == 9);
  for (k = SBA_STOP_NONE; k <= SBA_STOP_USER; ++k)
    CHECK(sba_stop_reason_text(k) != NULL && strcmp(sba_stop_reason_text(k), "unknown") != 0);
  CHECK(strcmp(sba_stop_reason_text(SBA_STOP_USER + 1), "unknown") == 0);

  /* "auto" is a solver name; an extension call that names none is auto, and the result names
   * the solver it chose (chol for a problem this small), never "auto". */
  CHECK(sba_linsolver_valid("auto") == 1 && strstr(sba_linsolver_names(), " auto") != NULL);
  { struct sba_ext_options ext;
    struct sba_ext_result res;
    sba_ext_options_init(&ext);
    sba_ext_result_init(&res);
    ext.result = &res;
    p[1] = 2.5; p[2] = 0.5; p[3] = -0.7; p[4] = 3.2;
    ret = sba_motstr_levmar_x_ext(3, 0, 2, 1, vmask, p, 1, 1, x, NULL, 1, func, fjac, NULL, 50, 0, NULL, info, &ext);
    CHECK(ret > 0 && res.linsolver != NULL && strcmp(res.linsolver, "chol") == 0);
    ext.linsolver = "automatic";
    ext.quiet = 1;
    ret = sba_motstr_levmar_x_ext(3, 0, 2, 1, vmask, p, 1, 1, x, NULL, 1, func, fjac, NULL, 50, 0, NULL, info, &ext);
    CHECK(ret == SBA_ERROR); }

  /* Priors: a point pulled to 1.5 (sigma 1e-3) against its projections' 1, a camera held near
   * its value by a callback prior and by a linear one. */
  { struct sba_ext_options ext;
    struct sba_ext_result res;
    struct sba_point_prior pp;
    struct sba_camera_prior cp;
    struct sba_camera_linear_prior lp;
    const double mean = 1.5, sigma = 1e-3, lmean = 2.0, lsigma = 0.5;
    const int param = 0;
    sba_ext_options_init(&ext);
    sba_ext_result_init(&res);
    memset(&pp, 0, sizeof pp);
    memset(&cp, 0, sizeof cp);
    memset(&lp, 0, sizeof lp);
    pp.point = 0;
    pp.mean = &mean;
    pp.weight.sigma = &sigma;
    cp.camera = 1;
    cp.dim = 1;
    cp.func = cam_prior;
    cp.jacf = cam_prior_jac;
    cp.loss = "huber";
    lp.camera = 1;
    lp.k = 1;
    lp.params = &param;
    lp.mean = &lmean;
    lp.weight.sigma = &lsigma;
    ext.result = &res;
    ext.npoint_priors = 1;
    ext.point_priors = &pp;
    ext.ncamera_priors = 1;
    ext.camera_priors = &cp;
    ext.ncamera_linear_priors = 1;
    ext.camera_linear_priors = &lp;
    p[1] = 2.5; p[2] = 0.5; p[3] = -0.7; p[4] = 3.2;
    ret = sba_motstr_levmar_x_ext(3, 0, 2, 1, vmask, p, 1, 1, x, NULL, 1, func, fjac, NULL, 50, 0, NULL, info, &ext);
    CHECK(ret > 0 && fabs(p[2] - 1.5) < 1e-3);
    CHECK(res.prior_cost_final > 0.0 && res.projection_cost_final > 0.0);
    CHECK(info[1] == res.projection_cost_final + res.prior_cost_final);
    pp.point = 3; /* no such point */
    ext.quiet = 1;
    ret = sba_motstr_levmar_x_ext(3, 0, 2, 1, vmask, p, 1, 1, x, NULL, 1, func, fjac, NULL, 50, 0, NULL, info, &ext);
    CHECK(ret == SBA_ERROR && info[6] == SBA_STOP_NONE); }

  CHECK(strstr(SBA_VERSION, "1.6") != NULL);
  if (failures) fprintf(stderr, "%d check(s) failed\n", failures);
  else printf("C API: all checks passed\n");
  return failures != 0;
}
