/* SPDX-License-Identifier: BSD-3-Clause */
/* The files of sba 1.6 that programs include beside sba.h: compiler.h (inline, SBA_FINITE) and
 * sba_chkjac.h (the expert drivers' Jacobian checks), and the 1.6 macros of sba.h. Written in
 * C90 so that the same file is built as C99 and as C90, both with -pedantic -Werror: compiler.h
 * must work for a strict C90 compiler too, where inline is not a keyword. It is also built
 * against the installed library by tests/install_consumer.
 *
 * The checks print their findings on stderr, so stderr is reopened onto the file named by
 * argv[1] around each call and read back; this program reports on stdout. Exit status 0 when
 * every check passed. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "sba.h"
#include "compiler.h"
#include "sba_chkjac.h"

#ifndef _SBA_H_
#error "sba.h does not define sba 1.6's include guard _SBA_H_"
#endif
#ifndef SBA_APPEND_UNDERSCORE_SUFFIX
#error "sba.h does not define SBA_APPEND_UNDERSCORE_SUFFIX"
#endif
#ifndef _COMPILER_H_
#error "compiler.h does not define its include guard _COMPILER_H_"
#endif
#ifndef _SBA_CHKJAC_H_
#error "sba_chkjac.h does not define its include guard _SBA_CHKJAC_H_"
#endif

static int failures = 0;
static char captured[16384];

#define CHECK(cond)                                                              \
  do {                                                                           \
    if (!(cond)) {                                                               \
      printf("%s:%d: check failed: %s\n", __FILE__, __LINE__, #cond);            \
      printf("---- what the last call printed on stderr:\n%s----\n", captured);  \
      ++failures;                                                                \
    }                                                                            \
  } while (0)

/* ---- stderr capture ---- */
static const char *errpath = "c_api_chkjac.stderr";

static int capture_begin(void) {
  fflush(stderr);
  captured[0] = '\0';
  return freopen(errpath, "w", stderr) != NULL;
}

static void capture_end(void) {
  FILE *f;
  size_t len = 0;
  fflush(stderr);
  f = fopen(errpath, "r");
  if (f) {
    len = fread(captured, 1, sizeof captured - 1, f);
    fclose(f);
  }
  captured[len] = '\0';
}

static int count(const char *text, const char *what) {
  int c = 0;
  const char *s = text;
  while ((s = strstr(s, what)) != NULL) {
    ++c;
    s += strlen(what);
  }
  return c;
}

/* ---- the problem: 3 cameras a_j = (tx, s), 4 points b_i = (X, Y, Z), projection
 * u = s X / Z + tx, v = s Y / Z (mnp = 2). Camera 0 and point 0 are held fixed. ---- */
#define M 3
#define N 4
#define NVIS 9
#define CNP 2
#define PNP 3
#define MNP 2

static const char vmask[N * M] = {1, 1, 1, /* point 0 */
                                  1, 0, 1, /* point 1 */
                                  0, 1, 1, /* point 2 */
                                  1, 1, 0 /* point 3 */};
static const double cams0[M * CNP] = {0.1, 1.0, -0.3, 1.2, 0.5, 0.9};
static const double pts0[N * PNP] = {0.2, 0.3, 4.0, -0.5, 0.1, 5.0, 0.4, -0.6, 3.0, 1.0, 0.7, 6.0};

enum { FUNC = 1, JAC = 2 };

/* What the callbacks share with the test through adata: func and jacf get different ones. */
struct cbdata {
  int role;                   /* FUNC or JAC: which callback this adata is meant for */
  int cams_in_p, pts_in_p;    /* which parameters p holds (motstr, mot or str) */
  const double *cams, *pts;   /* the parameters p does not hold */
  int mcon, ncon;             /* jacf writes garbage into fixed blocks: it must not be reported */
  int wrong_i, wrong_j;       /* jacf gets one entry of this projection's free block wrong */
  struct sba_crsm *idx;       /* the pointers the callbacks must receive */
  int *rcidxs, *rcsubs;
  int calls, misdirected;
};

static inline double ratio(double a, double b) { return a / b; }

static void params(const struct cbdata *d, double *p, int j, int i, const double **a,
                   const double **b) {
  *a = d->cams_in_p ? p + CNP * j : d->cams + CNP * j;
  *b = d->pts_in_p ? p + (d->cams_in_p ? M * CNP : 0) + PNP * i : d->pts + PNP * i;
}

static void note_call(struct cbdata *d, int role, struct sba_crsm *idx, int *rcidxs, int *rcsubs) {
  ++d->calls;
  if (d->role != role || idx != d->idx || rcidxs != d->rcidxs || rcsubs != d->rcsubs)
    ++d->misdirected;
}

static void func(double *p, struct sba_crsm *idx, int *rcidxs, int *rcsubs, double *hx,
                 void *adata) {
  struct cbdata *d = (struct cbdata *)adata;
  const double *a, *b;
  int i, q, nq, k;
  note_call(d, FUNC, idx, rcidxs, rcsubs);
  for (i = 0; i < idx->nr; ++i) {
    nq = sba_crsm_row_elmidxs(idx, i, rcidxs, rcsubs);
    for (q = 0; q < nq; ++q) {
      k = idx->val[rcidxs[q]];
      params(d, p, rcsubs[q], i, &a, &b);
      hx[MNP * k] = a[1] * ratio(b[0], b[2]) + a[0];
      hx[MNP * k + 1] = a[1] * ratio(b[1], b[2]);
    }
  }
}

static void jacf(double *p, struct sba_crsm *idx, int *rcidxs, int *rcsubs, double *jac,
                 void *adata) {
  struct cbdata *d = (struct cbdata *)adata;
  const int ca = d->cams_in_p ? CNP : 0, cb = d->pts_in_p ? PNP : 0;
  const double *a, *b;
  double *A, *B;
  int i, j, q, nq;
  note_call(d, JAC, idx, rcidxs, rcsubs);
  for (i = 0; i < idx->nr; ++i) {
    nq = sba_crsm_row_elmidxs(idx, i, rcidxs, rcsubs);
    for (q = 0; q < nq; ++q) {
      j = rcsubs[q];
      params(d, p, j, i, &a, &b);
      A = jac + MNP * (ca + cb) * idx->val[rcidxs[q]];
      B = A + MNP * ca;
      if (ca) {
        A[0] = 1.0;
        A[1] = b[0] / b[2];
        A[2] = 0.0;
        A[3] = b[1] / b[2];
        if (j < d->mcon) A[1] = A[3] = 1e3;
        if (i == d->wrong_i && j == d->wrong_j && !cb) A[1] *= 1.5;
      }
      if (cb) {
        B[0] = a[1] / b[2];
        B[1] = 0.0;
        B[2] = -a[1] * b[0] / (b[2] * b[2]);
        B[3] = 0.0;
        B[4] = a[1] / b[2];
        B[5] = -a[1] * b[1] / (b[2] * b[2]);
        if (i < d->ncon) B[0] = B[5] = -1e3;
        if (i == d->wrong_i && j == d->wrong_j) B[2] *= 1.5;
      }
    }
  }
}

/* The index of vmask; bycam != 0 numbers the measurements camera by camera instead of point by
 * point, so that val is a permutation other than the identity. */
static void make_index(struct sba_crsm *idx, int *val, int *colidx, int *rowptr, int bycam) {
  int i, j, k = 0, v = 0;
  for (i = 0; i < N; ++i) {
    rowptr[i] = k;
    for (j = 0; j < M; ++j)
      if (vmask[i * M + j]) colidx[k++] = j;
  }
  rowptr[N] = k;
  for (k = 0; k < NVIS; ++k) val[k] = k;
  if (bycam)
    for (j = 0; j < M; ++j)
      for (i = 0; i < N; ++i)
        for (k = rowptr[i]; k < rowptr[i + 1]; ++k)
          if (colidx[k] == j) val[k] = v++;
  idx->nr = N;
  idx->nc = M;
  idx->nnz = NVIS;
  idx->val = val;
  idx->colidx = colidx;
  idx->rowptr = rowptr;
}

enum { MOTSTR, MOT, STR };

/* One check run: returns nothing, leaves its stderr in captured and the callback counts in
 * fd/jd. wrong: whether jacf gets the entry of (point 2, camera 1) wrong. */
static void run(int which, int wrong, int bycam, struct cbdata *fd, struct cbdata *jd) {
  struct sba_crsm idx;
  int val[NVIS], colidx[NVIS], rowptr[N + 1], rcidxs[N], rcsubs[N];
  double p[M * CNP + N * PNP], p0[M * CNP + N * PNP];
  size_t np = 0;
  memset(p, 0, sizeof p);
  make_index(&idx, val, colidx, rowptr, bycam);
  memset(fd, 0, sizeof *fd);
  fd->cams_in_p = which != STR;
  fd->pts_in_p = which != MOT;
  fd->cams = cams0;
  fd->pts = pts0;
  fd->mcon = fd->cams_in_p ? 1 : 0;
  fd->ncon = fd->pts_in_p ? 1 : 0;
  fd->wrong_i = wrong ? 2 : -1;
  fd->wrong_j = wrong ? 1 : -1;
  fd->idx = &idx;
  fd->rcidxs = rcidxs;
  fd->rcsubs = rcsubs;
  *jd = *fd;
  fd->role = FUNC;
  jd->role = JAC;
  if (fd->cams_in_p) {
    memcpy(p, cams0, sizeof cams0);
    np += M * CNP;
  }
  if (fd->pts_in_p) {
    memcpy(p + np, pts0, sizeof pts0);
    np += N * PNP;
  }
  memcpy(p0, p, sizeof p);
  if (!capture_begin()) {
    printf("cannot reopen stderr onto %s\n", errpath);
    ++failures;
    return;
  }
  if (which == MOTSTR)
    sba_motstr_chkjac_x(func, jacf, p, &idx, rcidxs, rcsubs, 1, 1, CNP, PNP, MNP, fd, jd);
  else if (which == MOT)
    sba_mot_chkjac_x(func, jacf, p, &idx, rcidxs, rcsubs, 1, CNP, MNP, fd, jd);
  else
    sba_str_chkjac_x(func, jacf, p, &idx, rcidxs, rcsubs, 1, PNP, MNP, fd, jd);
  capture_end();
  CHECK(memcmp(p, p0, np * sizeof *p) == 0);
  CHECK(fd->calls > 0 && jd->calls == 1);
  CHECK(fd->misdirected == 0 && jd->misdirected == 0);
}

static void check_all(void) {
  static const char *const names[3] = {"motstr", "mot", "str"};
  static const char *const culprit[3] = {"d/d(point 2 parameter 2)", "d/d(camera 1 parameter 1)",
                                         "d/d(point 2 parameter 2)"};
  struct cbdata fd, jd;
  int which, bycam;
  for (which = MOTSTR; which <= STR; ++which)
    for (bycam = 0; bycam <= (which == MOTSTR); ++bycam) {
      printf("%s%s: correct Jacobian, then one wrong entry\n", names[which],
             bycam ? " (val numbered by camera)" : "");
      run(which, 0, bycam, &fd, &jd);
      CHECK(count(captured, "probably wrong") == 0);
      CHECK(count(captured, "agree with finite differences") == 1);
      CHECK(count(captured, "\n") == 1);
      run(which, 1, bycam, &fd, &jd);
      printf("%s", captured);
      CHECK(count(captured, "probably wrong") == 1);
      CHECK(count(captured, "of the projection of point 2 on camera 1") == 1);
      CHECK(count(captured, culprit[which]) == 1);
      CHECK(count(captured, "sba: Jacobian check: 1 of ") == 1);
      CHECK(count(captured, "\n") == 2);
    }
}

/* Bad arguments: one line on stderr that names the function and the problem, no callback. */
static void check_bad_arguments(void) {
  struct sba_crsm idx;
  int val[NVIS], colidx[NVIS], rowptr[N + 1], rcidxs[N], rcsubs[N];
  double p[M * CNP + N * PNP];
  struct cbdata fd, jd;
  int t;
  memset(&fd, 0, sizeof fd);
  jd = fd;
  memcpy(p, cams0, sizeof cams0);
  memcpy(p + M * CNP, pts0, sizeof pts0);
  for (t = 0; t < 9; ++t) {
    const char *name = t == 7 ? "sba_mot_chkjac_x" : t == 8 ? "sba_str_chkjac_x" : "sba_motstr_chkjac_x";
    const char *what = "";
    make_index(&idx, val, colidx, rowptr, 0);
    CHECK(capture_begin());
    switch (t) {
      case 0:
        what = "idxij";
        sba_motstr_chkjac_x(func, jacf, p, NULL, rcidxs, rcsubs, 0, 0, CNP, PNP, MNP, &fd, &jd);
        break;
      case 1:
        what = "rowptr";
        rowptr[2] = rowptr[3] + 1;
        sba_motstr_chkjac_x(func, jacf, p, &idx, rcidxs, rcsubs, 0, 0, CNP, PNP, MNP, &fd, &jd);
        break;
      case 2:
        what = "colidx";
        colidx[4] = M;
        sba_motstr_chkjac_x(func, jacf, p, &idx, rcidxs, rcsubs, 0, 0, CNP, PNP, MNP, &fd, &jd);
        break;
      case 3:
        what = "val";
        val[5] = val[6];
        sba_motstr_chkjac_x(func, jacf, p, &idx, rcidxs, rcsubs, 0, 0, CNP, PNP, MNP, &fd, &jd);
        break;
      case 4:
        what = "mcon";
        sba_motstr_chkjac_x(func, jacf, p, &idx, rcidxs, rcsubs, 0, M + 1, CNP, PNP, MNP, &fd, &jd);
        break;
      case 5:
        what = "cnp";
        sba_motstr_chkjac_x(func, jacf, p, &idx, rcidxs, rcsubs, 0, 0, 0, PNP, MNP, &fd, &jd);
        break;
      case 6:
        what = "jacf";
        sba_motstr_chkjac_x(func, NULL, p, &idx, rcidxs, rcsubs, 0, 0, CNP, PNP, MNP, &fd, &jd);
        break;
      case 7:
        what = "p";
        sba_mot_chkjac_x(func, jacf, NULL, &idx, rcidxs, rcsubs, 0, CNP, MNP, &fd, &jd);
        break;
      default:
        what = "ncon";
        sba_str_chkjac_x(func, jacf, p, &idx, rcidxs, rcsubs, -1, PNP, MNP, &fd, &jd);
        break;
    }
    capture_end();
    printf("bad argument %d (%s): %s", t, what, captured);
    CHECK(count(captured, "\n") == 1);
    CHECK(strncmp(captured, name, strlen(name)) == 0 && captured[strlen(name)] == ':');
    CHECK(strstr(captured, what) != NULL);
    CHECK(fd.calls == 0 && jd.calls == 0);
  }
}

int main(int argc, char **argv) {
  volatile double one = 1.0;
  if (argc > 1) errpath = argv[1];
  CHECK(SBA_FINITE(one) && !SBA_FINITE(one / 0.0) && !SBA_FINITE(HUGE_VAL));
  check_all();
  check_bad_arguments();
  remove(errpath);
  if (failures)
    printf("%d check(s) failed\n", failures);
  else
    printf("sba_chkjac.h, compiler.h: all checks passed\n");
  return failures != 0;
}
