/* SPDX-License-Identifier: BSD-3-Clause */
// COLMAP sparse models (docs/formats.md, "COLMAP sparse models"): the three files
// cameras, images and points3D, and the two that COLMAP writes from 3.12 on, rigs and frames,
// as text (.txt) or binary (.bin), read strictly and written back with every field as it came.
//
// COLMAP's eighteen camera models, ids 0..17, are accepted (cameras/colmap_camera.h).
// Errors are one line: "<file>:<line>: <message>" for text, "<file>: byte N: <message>" for
// binary, "<file>: <message>" for what concerns a whole file or the model.
#ifndef SBA_LIB_FORMATS_COLMAP_IO_H
#define SBA_LIB_FORMATS_COLMAP_IO_H

#include <array>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "cameras/colmap_camera.h"
#include "cameras/rigid_pose.h"

namespace sbaformats {
class OutputSet;  // output_file.h
}  // namespace sbaformats

namespace sbaformats::colmap {

// COLMAP's model ids of its camera models: colmap_camera.h's, whose comment gives each one's
// parameters.
using CameraModelId = sbacameras::colmap_camera::ModelId;
using sbacameras::colmap_camera::kSimplePinhole;
using sbacameras::colmap_camera::kPinhole;
using sbacameras::colmap_camera::kSimpleRadial;
using sbacameras::colmap_camera::kRadial;
using sbacameras::colmap_camera::kOpenCV;
using sbacameras::colmap_camera::kOpenCVFisheye;
using sbacameras::colmap_camera::kFullOpenCV;
using sbacameras::colmap_camera::kFov;
using sbacameras::colmap_camera::kSimpleRadialFisheye;
using sbacameras::colmap_camera::kRadialFisheye;
using sbacameras::colmap_camera::kThinPrismFisheye;
using sbacameras::colmap_camera::kRadTanThinPrismFisheye;
using sbacameras::colmap_camera::kSimpleDivision;
using sbacameras::colmap_camera::kDivision;
using sbacameras::colmap_camera::kSimpleFisheye;
using sbacameras::colmap_camera::kFisheye;
using sbacameras::colmap_camera::kEucm;
using sbacameras::colmap_camera::kEquirectangular;

// The model's name, or nullptr for an id outside the accepted ones.
const char *camera_model_name(int model);
// The number of parameters of an accepted model id.
int camera_model_params(int model);

struct Camera {
  std::uint32_t id = 0;
  int model = kSimplePinhole;
  std::uint64_t width = 0, height = 0;
  std::vector<double> params;
};

constexpr std::uint64_t kNoPoint = ~std::uint64_t{0};  // POINT3D_ID -1

struct Point2D {
  double x = 0, y = 0;
  std::uint64_t point3d_id = kNoPoint;
};

// An image. Its pose, world to camera (X_cam = R(q) X + t, qw qx qy qz), is q and t in a model
// without rigs and frames. In a model with them it is derived (image_poses): q and t are only
// what the images file held, COLMAP's rendering of that derived pose, which the writer writes
// again where it still is that pose but for rounding.
struct Image {
  std::uint32_t id = 0;
  std::array<double, 4> q{1, 0, 0, 0};
  std::array<double, 3> t{};
  std::uint32_t camera_id = 0;
  std::string name;
  std::vector<Point2D> points;
};

struct TrackElement {
  std::uint32_t image_id = 0;
  std::uint32_t point2d_idx = 0;
};

struct Point3D {
  std::uint64_t id = 0;
  std::array<double, 3> xyz{};
  std::array<std::uint8_t, 3> rgb{};
  double error = 0;
  std::vector<TrackElement> track;
};

// A pose X_out = R(q) X_in + t, the quaternion Hamilton's, qw first (as an image's).
using Pose = sbacameras::RigidPose;

// COLMAP's sensor types, by the values of the binary files (the text names them).
enum class SensorType : std::int32_t { Camera = 0, Imu = 1 };

struct SensorId {
  SensorType type = SensorType::Camera;
  std::uint32_t id = 0;  // a camera's CAMERA_ID for a camera
};
inline bool operator==(const SensorId &a, const SensorId &b) { return a.type == b.type && a.id == b.id; }

struct RigSensor {
  SensorId sensor;
  bool has_pose = false;  // its pose in the rig is known
  Pose sensor_from_rig;   // when has_pose
};

// A rig: its sensors, the reference sensor (whose pose in the rig is the identity) first, the
// others in file order. A rig may have no sensor.
struct Rig {
  std::uint32_t id = 0;
  std::vector<RigSensor> sensors;
};

struct DataId {
  SensorId sensor;
  std::uint64_t id = 0;  // a camera's data: the IMAGE_ID of its image
};

// A frame: one pose of a rig, and what its sensors measured there, in file order.
struct Frame {
  std::uint32_t id = 0;
  std::uint32_t rig_id = 0;
  Pose rig_from_world;
  std::vector<DataId> data;
};

// A model in file order. With rigs and frames an image's pose is derived, as COLMAP 4 derives
// it: the pose of its camera in the frame's rig times the frame's rig_from_world (image_poses);
// without them it is the image's own.
struct Model {
  std::vector<Camera> cameras;
  std::vector<Image> images;
  std::vector<Point3D> points;
  bool has_rigs = false;  // the model has rigs and frames (both files, or neither)
  std::vector<Rig> rigs;
  std::vector<Frame> frames;
};

// Which files a directory holds: binary if cameras.bin exists, else text if cameras.txt does.
// Binary first, as COLMAP reads a folder that holds both.
enum class Encoding { Text, Binary };

// Whether dir holds a cameras file of the encoding (anything by that name).
bool has_model(const std::string &dir, Encoding encoding);

// The encoding of the model in dir, without reading it: false with "PATH: cannot open: REASON"
// when its cameras file cannot be looked at (a symbolic link loop, say), "DIR: no COLMAP
// model (cameras.txt or cameras.bin)" when there is none.
bool model_encoding(const std::string &dir, Encoding *out, std::string *error);

// Parsers of one file's content; name stands for the file in the messages. They check each
// file on its own (syntax, finite numbers, accepted camera models, unique ids, nonzero
// quaternions, a sensor listed once in its rig and a measurement once in its frame);
// check_model checks how the files agree.
bool parse_cameras_text(const std::string &text, const std::string &name, std::vector<Camera> *out,
                        std::string *error);
bool parse_images_text(const std::string &text, const std::string &name, std::vector<Image> *out,
                       std::string *error);
bool parse_points_text(const std::string &text, const std::string &name, std::vector<Point3D> *out,
                       std::string *error);
bool parse_cameras_binary(const std::string &bytes, const std::string &name, std::vector<Camera> *out,
                          std::string *error);
bool parse_images_binary(const std::string &bytes, const std::string &name, std::vector<Image> *out,
                         std::string *error);
bool parse_points_binary(const std::string &bytes, const std::string &name, std::vector<Point3D> *out,
                         std::string *error);
bool parse_rigs_text(const std::string &text, const std::string &name, std::vector<Rig> *out,
                     std::string *error);
bool parse_frames_text(const std::string &text, const std::string &name, std::vector<Frame> *out,
                       std::string *error);
bool parse_rigs_binary(const std::string &bytes, const std::string &name, std::vector<Rig> *out,
                       std::string *error);
bool parse_frames_binary(const std::string &bytes, const std::string &name, std::vector<Frame> *out,
                         std::string *error);

// The files agree: every image's camera exists; every observation's point exists and lists
// that observation in its track; every track element names an existing image and one of its
// observations that points back; no image sees a point twice; every point is seen at least
// once. With rigs and frames, as COLMAP 4 reads them: a rig's cameras exist, and a camera is a
// sensor of one rig; a frame's rig exists and holds the sensor of each of its measurements; a
// camera's measurement is an existing image of that camera; every image is in exactly one
// frame, and its pose can be composed there: its camera is the rig's reference sensor, or has
// a pose in the rig whose quaternion has norm 1 (COLMAP composes with it as written, and a
// quaternion of another norm is not a rotation there) and the composed pose does not
// overflow. name prefixes the message (the model's directory).
bool check_model(const Model &model, const std::string &name, std::string *error);

// The pose of each image of a checked model (one per Model::images). Without rigs and frames,
// the image's q and t. With them, the image's frame's rig_from_world itself for the rig's
// reference sensor (the same bits), compose(sensor_from_rig, rig_from_world) for another
// sensor; but the image's q and t where they are that pose but for the rounding of another
// program's arithmetic (COLMAP writes the poses it composed into the images file), so that a
// model nothing changed is written back as it was read. Of a model check_model refuses, the
// images' own poses where its frames do not place every image.
std::vector<Pose> image_poses(const Model &model);

// COLMAP's filter of the observations of points that are not in front of their image's camera
// (its FilterObservationsWithNegativeDepth, which COLMAP's bundle_adjuster and
// pycolmap.bundle_adjustment run before the solve): an observation whose point's depth in the
// camera (the third coordinate of the point in the camera's frame, by image_poses) is below
// the epsilon of doubles leaves its point's track and its keypoint, and a point left with
// fewer than two observations is deleted, its keypoints freed. A checked model stays one.
struct DepthFilter {
  std::vector<TrackElement> observations;  // the observations removed for their depth
  std::size_t points = 0;                  // the points deleted with them
};
DepthFilter filter_negative_depth(Model *model);

// The reverse: the rig_from_world of a frame at which a camera whose pose in the rig is
// *sensor_from_rig has the pose `pose`: `pose` itself (the same bits) for the rig's reference
// sensor (sensor_from_rig null), between(*sensor_from_rig, pose) for another.
Pose frame_pose(const Pose &pose, const Pose *sensor_from_rig);

// Where an image of a checked model with rigs and frames is: its frame (an index into
// Model::frames), its frame's rig (into Model::rigs) and its camera among the rig's sensors
// (0: the reference sensor).
struct ImagePlace {
  std::size_t frame = 0, rig = 0, sensor = 0;
};
// Each image's (one per Model::images): an index of the model's ids, which check_model does not
// keep. A caller that needs it more than once builds it once and passes it on.
std::vector<ImagePlace> image_places(const Model &model);
// image_poses of a checked model with the places image_places gave of it.
std::vector<Pose> image_poses(const Model &model, const std::vector<ImagePlace> &places);

// Reads DIR/{cameras,images,points3D}.{txt,bin} (encoding from the files found, see above),
// and DIR/{rigs,frames} of the same encoding when they are there: both or neither, as COLMAP 4
// refuses a model with one of the two. The images keep the poses their file holds (see Image).
// Each must be a regular file: a directory or a device there (/dev/zero)
// is refused by name.
bool read_model(const std::string &dir, Model *out, Encoding *encoding, std::string *error);
// Writes the model's files into dir (created if missing), all or none of them: the rigs and
// frames files with the other three when the model has them. They are renamed onto their
// names (the cameras file last) once all are written, and a failure before leaves every file
// of dir as it was, and no dir that was not there. Then the other encoding's files, if dir
// holds any, are removed, and so are the rigs and frames of this encoding when the model has
// none, so that dir holds one model and COLMAP composes no pose from another's frames. Text numbers have 17
// significant digits, so that they read back to the same doubles. With `outputs`, the files
// and the directory are part of that set of a run's outputs (output_file.h), renamed and
// removed when it is committed. The images file holds image_poses(model).
bool write_model(const std::string &dir, const Model &model, Encoding encoding, std::string *error,
                 OutputSet *outputs = nullptr);

// Whether write_model could write into dir, asked before a long computation: dir is a
// directory whose model files (all five, as the model to write is not known yet) can be
// written, or can be made (it is not left behind). False with the message write_model would
// give.
bool model_writable(const std::string &dir, Encoding encoding, std::string *error);

// The same in memory: the files' contents (rigs and frames formatted whether or not the model
// has them).
struct Files {
  std::string cameras, images, points, rigs, frames;
};
Files format_model(const Model &model, Encoding encoding);

// The whole file into *out. A text file must hold no NUL byte (a binary file, /dev/zero):
// the reading stops at the first. False with "<path>: <message>" on failure ("is a
// directory" for one).
bool read_whole_file(const std::string &path, bool text, std::string *out, std::string *error);
// The same for what is left of an open stream (a pipe whose first bytes were read), appended
// to *out; path names it in messages.
bool read_rest(std::FILE *f, const std::string &path, bool text, std::string *out, std::string *error);

}  // namespace sbaformats::colmap

#endif  // SBA_LIB_FORMATS_COLMAP_IO_H
