/* SPDX-License-Identifier: BSD-3-Clause */
// The rules a COLMAP record holds to on its own, beyond the syntax of its file: one function
// per kind of record, which the text reader, the binary reader and check_records (a model made
// in memory, pysba's) all call, so that a rule has one message wherever it is broken. The
// readers put their place before it ("cameras.txt:4: ", "cameras.bin: byte 8: "),
// check_records the model's name. How the records agree with each other is check_model's
// (colmap_io.h).
#ifndef SBA_LIB_FORMATS_COLMAP_CHECK_H
#define SBA_LIB_FORMATS_COLMAP_CHECK_H

#include <cstdint>
#include <string>

#include "formats/colmap_io.h"

namespace sbaformats::colmap {

// Each returns why the record cannot be in a model, empty when it can; the record is named by
// its id ("camera 3: PINHOLE's fx must be positive, got -1").
//
// A camera: COLMAP's invalid id 2^32 - 1 as its id, a model id outside COLMAP's eighteen, a
// parameter count that is not the model's, a focal length that is not positive or an aspect
// ratio fy / fx that is infinite or zero (EQUIRECTANGULAR: a w or h that is not positive).
std::string camera_problem(const Camera &c);
// Of camera_problem's, those before the parameters (the id, the model id), in its order: what
// a binary reader checks before the model's parameter count tells it what follows.
std::string camera_head_problem(const Camera &c);
// An image: the invalid id as its id or its camera's, a zero quaternion, a name the text format
// cannot hold (empty, a line break, a NUL byte, a blank at either end).
std::string image_problem(const Image &im);
// A point: POINT3D_ID -1 as its id, the invalid id as an image of its track.
std::string point_problem(const Point3D &p);
// A rig: the invalid id, a pose for its reference sensor (the files hold none: it is the rig's
// origin), a zero quaternion of a sensor, a sensor listed twice.
std::string rig_problem(const Rig &rig);
// A frame: the invalid id as its id or its rig's, a zero quaternion, a measurement listed twice
// (COLMAP keeps them as a set, and would write one back).
std::string frame_problem(const Frame &f);

// An id given to two records of a kind (what: "camera", "image", "point", "rig", "frame"):
// "camera 3 appears twice".
std::string appears_twice(const char *what, std::uint64_t id);

// Every record of a model made in memory, as the readers check each file: so that what
// write_model makes of it, read_model reads back, and colmap::Problem gets a model it can take.
// The numbers must be finite (the caller checks them where it can name them better). False with
// "NAME: " and the first problem, the records' own before the repeated ids, cameras, images,
// points, rigs, frames in turn.
bool check_records(const Model &model, const std::string &name, std::string *error);

}  // namespace sbaformats::colmap

#endif  // SBA_LIB_FORMATS_COLMAP_CHECK_H
