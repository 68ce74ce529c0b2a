// SPDX-License-Identifier: BSD-3-Clause
// The visibility index: built from vmask or from (point, camera) pairs, and checked against
// the int-sized 1.6 API before anything of the problem's size is allocated.
#include "layout.h"

#include <climits>
#include <string>
#include <vector>

namespace sba {

namespace {

void set_sizes(Layout &lay, Mode mode, int n, int m, int mcon, int ncon, int cnp, int pnp,
               int mnp) {
  lay.mode = mode;
  lay.n = n;
  lay.m = m;
  lay.mcon = mcon;
  lay.ncon = ncon;
  lay.cnp = cnp;
  lay.pnp = pnp;
  lay.mnp = mnp;
}

// The camera counts and the callbacks' view, once rowptr/colidx/val are filled.
void finish_layout(Layout &lay) {
  const int n = lay.n, m = lay.m;
  lay.colptr.assign(size_t(m) + 1, 0);
  for (i64 k = 0; k < lay.nvis; ++k) ++lay.colptr[size_t(lay.colidx[size_t(k)]) + 1];
  for (int j = 0; j < m; ++j) lay.colptr[size_t(j) + 1] += lay.colptr[size_t(j)];
  lay.idx.nr = n;
  lay.idx.nc = m;
  lay.idx.nnz = int(lay.nvis);
  lay.idx.val = lay.val.data();
  lay.idx.colidx = lay.colidx.data();
  lay.idx.rowptr = lay.rowptr.data();
  lay.cams = CameraMap(m, lay.mcon, lay.cnp);
}

}  // namespace

void by_camera(const Layout &lay, std::vector<int> *row, std::vector<int> *k) {
  row->resize(size_t(lay.nvis));
  if (k) k->resize(size_t(lay.nvis));
  std::vector<int> fill(lay.colptr.begin(), lay.colptr.end() - 1);
  for (int i = 0; i < lay.n; ++i)
    for (int kk = lay.rowptr[i]; kk < lay.rowptr[i + 1]; ++kk) {
      const int slot = fill[size_t(lay.colidx[size_t(kk)])]++;
      (*row)[size_t(slot)] = i;
      if (k) (*k)[size_t(slot)] = kk;
    }
}

namespace {

// a * b for non-negative sizes, saturating instead of wrapping: a count of visible cells can
// approach 2^62, so even 64-bit products of three sizes could wrap.
i64 mul(i64 a, i64 b) {
  i64 r;
  return __builtin_mul_overflow(a, b, &r) ? INT64_MAX : r;
}
i64 add(i64 a, i64 b) {
  i64 r;
  return __builtin_add_overflow(a, b, &r) ? INT64_MAX : r;
}

// One product of sizes and what it sizes, for the message.
struct Extent {
  const char *what;  // e.g. "the Jacobian"
  const char *expr;  // e.g. "nvis*mnp*(cnp+pnp)"
  i64 value;
};

std::string too_large(const Extent &e, const char *advice) {
  return std::string("problem too large for the int-sized sba 1.6 API: ") + e.what + " (" +
         e.expr + " = " + std::to_string(e.value) + ") exceeds INT_MAX = " +
         std::to_string(INT_MAX) + advice;
}

// Sizes of single blocks: the library and every callback API index within a block (and
// form block strides such as mnp*cnp) with int arithmetic, whichever entry point is used.
// Checked from the arguments alone, before the index is built or anything is allocated.
std::string check_block_sizes(const Layout &lay, bool covx) {
  const i64 cnp = lay.cnp, pnp = lay.pnp, mnp = lay.mnp;
  const Extent blocks[] = {
      {"a projection's Jacobian block", "mnp*(cnp+pnp)", mul(mnp, cnp + pnp)},
      {"a camera block U_j", "cnp*cnp", mul(cnp, cnp)},
      {"a point block V_i", "pnp*pnp", mul(pnp, pnp)},
      {"a block W_ij", "cnp*pnp", mul(cnp, pnp)},
      {"a measurement covariance block", "mnp*mnp", covx ? mul(mnp, mnp) : 0},
  };
  for (const Extent &e : blocks)
    if (e.value > INT_MAX) return too_large(e, "");
  return {};
}

// Whole-vector sizes for the vmask entry points: 1.6-style callbacks index p, x, hx, covx
// and the Jacobian with int offsets, so each of them must have at most INT_MAX entries.
std::string check_vector_sizes(const Layout &lay, i64 nvis, bool covx) {
  const i64 n = lay.n, m = lay.m, cnp = lay.cnp, pnp = lay.pnp, mnp = lay.mnp;
  const Extent vectors[] = {
      {"the camera parameters", "m*cnp", mul(m, cnp)},
      {"the point parameters", "n*pnp", mul(n, pnp)},
      {"p", "m*cnp+n*pnp", add(mul(m, cnp), mul(n, pnp))},
      {"the visible projections", "nvis", nvis},
      {"the measurements x", "nvis*mnp", mul(nvis, mnp)},
      {"the Jacobian", "nvis*mnp*(cnp+pnp)", mul(mul(nvis, mnp), cnp + pnp)},
      {"covx", "nvis*mnp*mnp", covx ? mul(mul(nvis, mnp), mnp) : 0},
  };
  for (const Extent &e : vectors)
    if (e.value > INT_MAX) return too_large(e, ": use the sba_*_vis entry points of sba_ext.h");
  return {};
}

}  // namespace

bool build_layout(Layout &lay, Mode mode, int n, int m, int mcon, int ncon, int cnp, int pnp,
                  int mnp, const char *vmask, std::string *msg, bool covx) {
  set_sizes(lay, mode, n, m, mcon, ncon, cnp, pnp, mnp);
  // Refuse what would overflow an int offset (in the callbacks or in our own block
  // arithmetic) before anything of that size is read, allocated or handed to a callback.
  *msg = check_block_sizes(lay, covx);
  if (!msg->empty()) return false;
  const i64 cells = i64(n) * m;
  i64 nvis = 0;
  for (i64 c = 0; c < cells; ++c) nvis += vmask[c] != 0;
  lay.nvis = nvis;
  if (nvis == 0) {
    *msg = "vmask has no visible projection (nvis == 0)";
    return false;
  }
  *msg = check_vector_sizes(lay, nvis, covx);
  if (!msg->empty()) return false;
  lay.rowptr.assign(size_t(n) + 1, 0);
  lay.colidx.resize(size_t(nvis));
  lay.val.resize(size_t(nvis));
  int k = 0;
  for (int i = 0; i < n; ++i) {
    lay.rowptr[size_t(i)] = k;
    const char *row = vmask + i64(i) * m;
    for (int j = 0; j < m; ++j) {
      if (!row[j]) continue;
      lay.colidx[size_t(k)] = j;
      lay.val[size_t(k)] = k;
      ++k;
    }
  }
  lay.rowptr[size_t(n)] = k;
  finish_layout(lay);
  return true;
}

bool build_layout(Layout &lay, Mode mode, int n, int m, int mcon, int ncon, int cnp, int pnp,
                  int mnp, const sba_visibility &vis, std::string *msg, bool covx) {
  set_sizes(lay, mode, n, m, mcon, ncon, cnp, pnp, mnp);
  *msg = check_block_sizes(lay, covx);
  if (!msg->empty()) return false;
  if (vis.nvis <= 0 || vis.nvis > INT_MAX || !vis.point || !vis.camera) {
    *msg = "vis must list between 1 and INT_MAX pairs (got " + std::to_string(vis.nvis) +
           ") with non-NULL point and camera arrays";
    return false;
  }
  const i64 nvis = vis.nvis;
  lay.nvis = nvis;
  lay.rowptr.assign(size_t(n) + 1, 0);
  lay.colidx.resize(size_t(nvis));
  lay.val.resize(size_t(nvis));
  for (i64 k = 0; k < nvis; ++k) {
    const int i = vis.point[k], j = vis.camera[k];
    if (i < 0 || i >= n || j < 0 || j >= m) {
      *msg = "vis pair " + std::to_string(k) + " (point " + std::to_string(i) + ", camera " +
             std::to_string(j) + ") is out of range";
      return false;
    }
    if (k > 0 && (i < vis.point[k - 1] || (i == vis.point[k - 1] && j <= vis.camera[k - 1]))) {
      *msg = "vis pair " + std::to_string(k) +
             " is out of order: pairs must be sorted by point, then camera, each once";
      return false;
    }
    ++lay.rowptr[size_t(i) + 1];
    lay.colidx[size_t(k)] = j;
    lay.val[size_t(k)] = int(k);
  }
  for (int i = 0; i < n; ++i) lay.rowptr[size_t(i) + 1] += lay.rowptr[size_t(i)];
  finish_layout(lay);
  return true;
}

}  // namespace sba
