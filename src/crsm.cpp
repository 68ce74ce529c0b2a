// SPDX-License-Identifier: BSD-3-Clause
// The sba_crsm visibility index helpers of the 1.6 API. Column indices within a row are
// ascending (the drivers build them so, and 1.6 callers rely on it), which is what makes the
// binary searches below valid.
#include <cstdlib>

#include "sba_export.h"

namespace {

// Position of column j within colidx[lo, hi), or -1.
int find_in_row(const int *colidx, int lo, int hi, int j) {
  while (lo < hi) {
    const int mid = lo + (hi - lo) / 2;
    if (colidx[mid] < j)
      lo = mid + 1;
    else if (colidx[mid] > j)
      hi = mid;
    else
      return mid;
  }
  return -1;
}

bool valid_row(const sba_crsm *sm, int i) {
  return sm && sm->rowptr && sm->colidx && i >= 0 && i < sm->nr;
}

}  // namespace

extern "C" {

void sba_crsm_alloc(struct sba_crsm *sm, int nr, int nc, int nnz) {
  if (!sm) return;
  sm->nr = sm->nc = sm->nnz = 0;
  sm->val = sm->colidx = sm->rowptr = nullptr;
  if (nr < 0 || nc < 0 || nnz < 0) return;
  // calloc so that a caller who forgets to fill a field reads zeros, not garbage; +1 keeps
  // zero-sized requests from returning NULL, which would look like an allocation failure.
  int *val = static_cast<int *>(std::calloc(static_cast<size_t>(nnz) + 1, sizeof(int)));
  int *colidx = static_cast<int *>(std::calloc(static_cast<size_t>(nnz) + 1, sizeof(int)));
  int *rowptr = static_cast<int *>(std::calloc(static_cast<size_t>(nr) + 1, sizeof(int)));
  if (!val || !colidx || !rowptr) {
    std::free(val);
    std::free(colidx);
    std::free(rowptr);
    return;  // the caller sees NULL arrays and zero sizes
  }
  sm->nr = nr;
  sm->nc = nc;
  sm->nnz = nnz;
  sm->val = val;
  sm->colidx = colidx;
  sm->rowptr = rowptr;
}

void sba_crsm_free(struct sba_crsm *sm) {
  if (!sm) return;
  std::free(sm->val);
  std::free(sm->colidx);
  std::free(sm->rowptr);
  sm->val = sm->colidx = sm->rowptr = nullptr;
  sm->nr = sm->nc = sm->nnz = 0;
}

int sba_crsm_elmidx(struct sba_crsm *sm, int i, int j) {
  if (!valid_row(sm, i)) return -1;
  return find_in_row(sm->colidx, sm->rowptr[i], sm->rowptr[i + 1], j);
}

int sba_crsm_elmidxp(struct sba_crsm *sm, int i, int j, int jp, int jpidx) {
  if (!valid_row(sm, i)) return -1;
  int lo = sm->rowptr[i], hi = sm->rowptr[i + 1];
  // The hint narrows the search to the side of jp where j must lie; a hint that does not
  // describe the index is ignored rather than trusted.
  if (jpidx >= lo && jpidx < hi && sm->colidx[jpidx] == jp) {
    if (j == jp) return jpidx;
    if (j > jp)
      lo = jpidx + 1;
    else
      hi = jpidx;
  }
  return find_in_row(sm->colidx, lo, hi, j);
}

int sba_crsm_row_elmidxs(struct sba_crsm *sm, int i, int *vidxs, int *jidxs) {
  if (!valid_row(sm, i)) return 0;
  int cnt = 0;
  for (int k = sm->rowptr[i]; k < sm->rowptr[i + 1]; ++k, ++cnt) {
    if (vidxs) vidxs[cnt] = k;
    if (jidxs) jidxs[cnt] = sm->colidx[k];
  }
  return cnt;
}

int sba_crsm_col_elmidxs(struct sba_crsm *sm, int j, int *vidxs, int *iidxs) {
  if (!sm || !sm->rowptr || !sm->colidx) return 0;
  int cnt = 0;
  for (int i = 0; i < sm->nr; ++i) {
    const int k = find_in_row(sm->colidx, sm->rowptr[i], sm->rowptr[i + 1], j);
    if (k < 0) continue;
    if (vidxs) vidxs[cnt] = k;
    if (iidxs) iidxs[cnt] = i;
    ++cnt;
  }
  return cnt;
}

}  // extern "C"
