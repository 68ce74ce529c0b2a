/* SPDX-License-Identifier: BSD-3-Clause */
/*
 * sba_chkjac.h: sba 1.6's Jacobian checks for the expert drivers' callbacks (installed beside
 * sba.h; programs written for 1.6 include it unchanged).
 *
 * Each function compares the analytic Jacobian jacf(p) with central differences of func
 * around p, as the drivers do when called with itmax == 0, and prints on stderr one line per
 * suspicious gradient (one coordinate of one projection whose derivative with respect to some
 * free parameter disagrees), followed by a one-line verdict:
 *   gradient G (element r of the projection of point i on camera j) is probably wrong:
 *     d/d(camera|point k parameter c) analytic A, finite differences F
 *   sba: Jacobian check: all R gradients agree with finite differences
 *   sba: Jacobian check: B of R gradients look wrong
 * (the first on one line). G counts the coordinates in idxij's element order, point by point;
 * it is the position in hx when idxij->val[k] == k, as in every index the drivers build.
 *
 * Only free parameters are checked: cameras 0..mcon-1 and points 0..ncon-1 are held fixed and
 * their blocks of the Jacobian are not looked at. The layout follows sba.h: idxij has one row
 * per point (n = idxij->nr) and one column per camera (m = idxij->nc), and idxij->val[k] is
 * the ordinal of element k's projection in hx; p holds m*cnp camera parameters then n*pnp
 * point parameters (sba_mot_chkjac_x: the cameras only; sba_str_chkjac_x: the points only),
 * and jacf writes per projection A_ij then B_ij (only A_ij, only B_ij).
 *
 * func is called with func_adata and jacf with jac_adata; both get the caller's idxij, rcidxs
 * and rcsubs (scratch arrays of max(n, m) ints). p is the same, bitwise, on return; the
 * callbacks are given a copy of it. On a bad argument (a NULL pointer, a non-positive size,
 * mcon or ncon outside 0..m or 0..n, an idxij that contradicts itself) one line naming the
 * problem is printed and nothing is called.
 */
#ifndef _SBA_CHKJAC_H_
#define _SBA_CHKJAC_H_

#include "sba.h"

#ifdef __cplusplus
extern "C" {
#endif

extern void sba_motstr_chkjac_x(
    void (*func)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *hx, void *adata),
    void (*jacf)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *jac, void *adata),
    double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, int ncon, int mcon, int cnp,
    int pnp, int mnp, void *func_adata, void *jac_adata);

extern void sba_mot_chkjac_x(
    void (*func)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *hx, void *adata),
    void (*jacf)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *jac, void *adata),
    double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, int mcon, int cnp, int mnp,
    void *func_adata, void *jac_adata);

extern void sba_str_chkjac_x(
    void (*func)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *hx, void *adata),
    void (*jacf)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *jac, void *adata),
    double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, int ncon, int pnp, int mnp,
    void *func_adata, void *jac_adata);

#ifdef __cplusplus
}
#endif

#endif /* _SBA_CHKJAC_H_ */
