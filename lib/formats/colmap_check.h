/* SPDX-License-Identifier: BSD-3-Clause */
// A COLMAP model made in memory (pysba's, from Python objects) rather than read from files,
// checked record by record as the readers check each file (colmap_io.h): so that what
// write_model makes of it, read_model reads back, and colmap::Problem gets a model it can take.
#ifndef SBA_LIB_FORMATS_COLMAP_CHECK_H
#define SBA_LIB_FORMATS_COLMAP_CHECK_H

#include <string>

#include "formats/colmap_io.h"

namespace sbaformats::colmap {

// What the parsers refuse in a record beyond the syntax of its file: a camera model outside
// COLMAP's eighteen or a parameter count that is not the model's, a focal length that is not
// positive (bad intrinsics), an id given twice (cameras, images, points, rigs, frames), a zero
// quaternion (an image's, a frame's, a sensor's pose in its rig), a pose for a rig's reference
// sensor (the files hold none: it is the rig's origin), an image name the text format cannot
// hold (empty, a line break, a NUL byte, a blank at either end), POINT3D_ID -1 as a point's id,
// COLMAP's invalid id 2^32 - 1 as the id of a camera, an image, a rig or a frame or where one
// is named (an image's camera, a track's image, a frame's rig), a sensor listed twice in its rig
// or a measurement twice in its frame. The numbers must be
// finite (the caller checks them where it can name them better), and how the records agree is
// check_model's. False with "NAME: " and the record named by its id, as the readers name it
// ("camera 3: PINHOLE's fx must be positive, got -1").
bool check_records(const Model &model, const std::string &name, std::string *error);

}  // namespace sbaformats::colmap

#endif  // SBA_LIB_FORMATS_COLMAP_CHECK_H
