/* SPDX-License-Identifier: BSD-3-Clause */
// The problem's sizes and its visibility index, in the forms the LM core, the solvers and the
// callbacks need, and how they are built and checked against the int-sized 1.6 API.
#ifndef SBA_SRC_LAYOUT_H
#define SBA_SRC_LAYOUT_H

#include <string>
#include <vector>

#include "camera_map.h"
#include "sba_export.h"
#include "types.h"

namespace sba {

// What p holds: motion+structure, cameras only (sba_mot_*), or points only (sba_str_*).
enum class Mode { MotStr, Mot, Str };

// Sizes and the visibility index in the forms the core and the callbacks need.
struct Layout {
  Mode mode = Mode::MotStr;
  int n = 0, m = 0;       // points, cameras
  int cnp = 0, pnp = 0;   // parameters per camera / point held in p (0 when not in p)
  int mnp = 0;            // coordinates per projection
  int mcon = 0, ncon = 0; // leading fixed cameras / points
  i64 nvis = 0;           // visible projections

  // Row-compressed by point (cameras ascending); val[k] == k is the measurement ordinal.
  std::vector<int> rowptr, colidx, val;
  // Where each camera's projections start in the camera-major order (see by_camera()).
  std::vector<int> colptr;
  sba_crsm idx{};  // views rowptr/colidx/val for the callbacks
  // How the free cameras' parameters map to the unknowns of the camera side (camera_map.h):
  // build_layout makes the plain one, sba 1.6's one unknown per parameter; the drivers refine
  // it from the held and shared parameters (make_camera_map).
  CameraMap cams;

  i64 nvars() const { return i64(m) * cnp + i64(n) * pnp; }
  i64 a_off(int j) const { return i64(j) * cnp; }
  i64 b_off(int i) const { return i64(m) * cnp + i64(i) * pnp; }
  // Doubles per projection in the Jacobian; build_layout refuses sizes where it exceeds an
  // int, so the narrowing is exact for every layout that exists.
  int jblk() const { return int(i64(mnp) * (i64(cnp) + pnp)); }
  bool cam_free(int j) const { return cnp > 0 && j >= mcon; }
  bool pt_free(int i) const { return pnp > 0 && i >= ncon; }
  int free_cams() const { return cnp > 0 ? m - mcon : 0; }
  int free_pts() const { return pnp > 0 ? n - ncon : 0; }
  i64 free_vars() const { return i64(free_cams()) * cnp + i64(free_pts()) * pnp; }
  // The order of the reduced camera system: the camera side's unknowns.
  i64 camera_unknowns() const { return cams.order(); }
};

// The index column-compressed by camera (points ascending): for slot s of camera j's range
// [colptr[j], colptr[j+1]), the point (row) and the measurement ordinal (k, unless null).
// Built on demand by the solvers that need it, so that the others do not keep 8 bytes per
// projection alive through the solve.
void by_camera(const Layout &lay, std::vector<int> *row, std::vector<int> *k);

// Builds the index from vmask. Returns false (with msg, naming the product) on a problem too
// big for the int API: any block (mnp*(cnp+pnp), cnp*cnp, pnp*pnp, cnp*pnp, and mnp*mnp when
// with_covx) or any
// vector the callbacks index (p, x, the Jacobian, and covx when with_covx) beyond INT_MAX
// entries. Nothing is allocated before these checks.
bool build_layout(Layout &lay, Mode mode, int n, int m, int mcon, int ncon, int cnp, int pnp,
                  int mnp, const char *vmask, std::string *msg, bool with_covx = false);
// The same from a list of (point, camera) pairs sorted by point then camera (sba_ext.h's
// sba_visibility); only nvis and the single blocks must fit an int: the callbacks of this API
// index hx and the Jacobian with 64-bit offsets.
bool build_layout(Layout &lay, Mode mode, int n, int m, int mcon, int ncon, int cnp, int pnp,
                  int mnp, const sba_visibility &vis, std::string *msg, bool with_covx = false);

}  // namespace sba

#endif
