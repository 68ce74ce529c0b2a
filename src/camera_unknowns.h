/* SPDX-License-Identifier: BSD-3-Clause */
// The held and shared camera parameters of a call (sba_ext_options' cam_fixed,
// cam_param_group, cam_group, cam_shared): checked once, then turned into the Layout's
// CameraMap (camera_map.h), which is all the rest of the library sees of them.
#ifndef SBA_SRC_CAMERA_UNKNOWNS_H
#define SBA_SRC_CAMERA_UNKNOWNS_H

#include <string>

#include "layout.h"

namespace sba {

// The caller's arrays, valid for the call, as the Options carry them (options.h).
struct CameraParamOptions {
  const char *fixed = nullptr;  // cnp flags, or m * cnp with fixed_per_camera
  bool fixed_per_camera = false;
  const int *param_group = nullptr;  // m * cnp group numbers, -1 for none
  const int *group = nullptr;        // m group numbers, -1 for none
  const char *shared = nullptr;      // cnp flags
  bool any() const { return fixed || param_group || group || shared; }
};

// What is wrong with o for this problem and the initial estimate p (empty: nothing). Only
// problems with cameras are checked; the structure-only drivers ignore the options.
std::string check_camera_params(const CameraParamOptions &o, const Layout &lay, const double *p);

// The map of o (checked by check_camera_params) for lay's cameras.
CameraMap make_camera_map(const CameraParamOptions &o, const Layout &lay);

}  // namespace sba

#endif
