// SPDX-License-Identifier: BSD-3-Clause
// A COLMAP model as a whole: its camera models, the agreement of its three files, and the
// files themselves, read and written in either encoding (colmap_text.cpp, colmap_binary.cpp).
#include "formats/colmap_io.h"

#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iterator>
#include <vector>

#include "formats/colmap_io_impl.h"
#include "formats/output_file.h"
#include "formats/text_tokens.h"

namespace sbaformats::colmap {

std::string bad_intrinsics(const Camera &c) {
  const ModelInfo &m = kModels[c.model];
  const std::string camera = "camera " + std::to_string(c.id) + ": " + m.name + "'s ";
  static const char *const kFocal[2][2] = {{"f", ""}, {"fx", "fy"}};
  for (int k = 0; k < m.focals; ++k) {
    const double f = c.params[static_cast<std::size_t>(k)];
    if (!(f > 0)) return camera + kFocal[m.focals - 1][k] + " must be positive, got " + g17(f);
  }
  if (m.focals == 2) {
    const double ar = c.params[1] / c.params[0];
    if (!std::isfinite(ar) || ar == 0) return camera + "aspect ratio fy / fx overflows or underflows";
  }
  return {};
}

std::string printable(const std::string &s) {
  std::string out;
  for (char c : s) {
    if (out.size() >= 40) return out + "...";
    out += (c >= 32 && c < 127) ? c : '?';
  }
  return out;
}

const char *camera_model_name(int model) {
  return model >= 0 && model < kNumModels ? kModels[model].name : nullptr;
}

int camera_model_params(int model) { return model >= 0 && model < kNumModels ? kModels[model].params : 0; }

bool check_model(const Model &model, const std::string &name, std::string *error) {
  const std::string where = name + ": ";
  constexpr std::size_t kNone = IdIndex::kNone;
  IdIndex cameras(model.cameras.size()), images(model.images.size()), points(model.points.size());
  for (std::size_t k = 0; k < model.cameras.size(); ++k) cameras.insert(model.cameras[k].id, k);
  for (std::size_t k = 0; k < model.points.size(); ++k) points.insert(model.points[k].id, k);
  for (std::size_t i = 0; i < model.images.size(); ++i) {
    const Image &im = model.images[i];
    images.insert(im.id, i);
    if (cameras.find(im.camera_id) == kNone)
      return fail(error, where + "image " + std::to_string(im.id) + " uses camera " + std::to_string(im.camera_id) +
                             ", which cameras does not hold");
  }
  // Each observation that names a point is claimed by exactly one track element. The marks
  // below stand for per-image and per-track sets, without an allocation for each:
  // seen_by[p] is 1 + the last image that saw point p, listed_by[i] 1 + the last point whose
  // track listed image i.
  std::size_t observations = 0;
  std::vector<std::size_t> seen_by(model.points.size(), 0);
  for (std::size_t i = 0; i < model.images.size(); ++i) {
    const Image &im = model.images[i];
    for (std::size_t k = 0; k < im.points.size(); ++k) {
      const std::uint64_t pid = im.points[k].point3d_id;
      if (pid == kNoPoint) continue;
      ++observations;
      const std::size_t p = points.find(pid);
      if (p == kNone)
        return fail(error, where + "image " + std::to_string(im.id) + " POINTS2D " + std::to_string(k) +
                               " names point " + std::to_string(pid) + ", which points3D does not hold");
      if (seen_by[p] == i + 1)
        return fail(error, where + "image " + std::to_string(im.id) + " sees point " + std::to_string(pid) +
                               " twice: sba takes one observation per point and image");
      seen_by[p] = i + 1;
    }
  }
  std::size_t elements = 0;
  std::vector<std::size_t> listed_by(model.images.size(), 0);
  for (std::size_t j = 0; j < model.points.size(); ++j) {
    const Point3D &p = model.points[j];
    if (p.track.empty()) return fail(error, where + "point " + std::to_string(p.id) + " has an empty track");
    for (const TrackElement &e : p.track) {
      const std::size_t i = images.find(e.image_id);
      if (i == kNone)
        return fail(error, where + "point " + std::to_string(p.id) + " is seen in image " +
                               std::to_string(e.image_id) + ", which images does not hold");
      const Image &im = model.images[i];
      if (e.point2d_idx >= im.points.size())
        return fail(error, where + "point " + std::to_string(p.id) + ": POINT2D_IDX " +
                               std::to_string(e.point2d_idx) + " is out of range for image " +
                               std::to_string(im.id) + " (" + std::to_string(im.points.size()) + " POINTS2D)");
      if (im.points[e.point2d_idx].point3d_id != p.id)
        return fail(error, where + "point " + std::to_string(p.id) + " lists POINTS2D " +
                               std::to_string(e.point2d_idx) + " of image " + std::to_string(im.id) +
                               ", which does not name it");
      // No image sees a point twice (checked above), so an image listed twice in a track is
      // the same observation listed twice.
      if (listed_by[i] == j + 1)
        return fail(error, where + "point " + std::to_string(p.id) + " lists POINTS2D " +
                               std::to_string(e.point2d_idx) + " of image " + std::to_string(im.id) + " twice");
      listed_by[i] = j + 1;
      ++elements;
    }
  }
  // Every element points back (checked above) and none repeats, so equal counts mean every
  // observation is listed.
  if (elements != observations)
    return fail(error, where + "the tracks of points3D list " + std::to_string(elements) +
                           " observations, the images name points in " + std::to_string(observations));
  return true;
}

// ---- files ----

bool read_rest(std::FILE *f, const std::string &path, bool text, std::string *out, std::string *error) {
  // Straight into *out, in what its capacity leaves (read_whole_file reserves the file's size),
  // or 64 KiB at a time past it.
  for (;;) {
    const std::size_t old = out->size();
    const std::size_t room = std::max<std::size_t>(out->capacity() - old, std::size_t{1} << 16);
    out->resize(old + room);
    const std::size_t got = std::fread(&(*out)[old], 1, room, f);
    out->resize(old + got);
    if (text && std::memchr(out->data() + old, '\0', got)) return fail(error, path + ": a NUL byte: not a text file");
    if (got < room) break;
  }
  if (std::ferror(f)) return fail(error, path + ": read error");
  return true;
}

bool read_whole_file(const std::string &path, bool text, std::string *out, std::string *error) {
  std::FILE *f = std::fopen(path.c_str(), "rb");
  if (!f) return fail(error, path + ": cannot open: " + std::strerror(errno));
  // fopen opens a directory for reading, whose reading then fails without saying why.
  struct stat st {};
  if (::fstat(fileno(f), &st) == 0 && S_ISDIR(st.st_mode)) {
    std::fclose(f);
    return fail(error, path + ": is a directory");
  }
  std::string data;
  // One byte more than the size, so that the end of the file is seen without growing data.
  if (S_ISREG(st.st_mode) && st.st_size > 0) data.reserve(static_cast<std::size_t>(st.st_size) + 1);
  const bool read = read_rest(f, path, text, &data, error);
  std::fclose(f);
  if (!read) return false;
  *out = std::move(data);
  return true;
}

namespace {

// A model's files, in the order they are written and renamed onto their names: the cameras
// file last. A reader takes a directory's model by its cameras file (binary first): while a
// rewrite renames its files, the directory is read as the model it held until the new cameras
// file is in place, and a rename that fails before leaves that model readable (when the new
// model has the other encoding, whole; otherwise with the files already renamed refined, as
// the old ones held the same ids).
struct ModelFile {
  const char *name;
  std::string Files::*content;
};
constexpr ModelFile kModelFiles[] = {
    {"images", &Files::images}, {"points3D", &Files::points}, {"cameras", &Files::cameras}};

const char *extension(Encoding encoding) { return encoding == Encoding::Text ? ".txt" : ".bin"; }

std::string slashed(const std::string &dir) { return dir.empty() || dir.back() == '/' ? dir : dir + "/"; }

// A model's file: a regular file, or its reading would never end (/dev/zero) or fail
// without saying why (a directory).
bool read_model_file(const std::string &path, bool text, std::string *out, std::string *error) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return fail(error, path + ": cannot open: " + std::strerror(errno));
  if (S_ISDIR(st.st_mode)) return fail(error, path + ": is a directory");
  if (!S_ISREG(st.st_mode)) return fail(error, path + ": not a regular file");
  return read_whole_file(path, text, out, error);
}

}  // namespace

bool has_model(const std::string &dir, Encoding encoding) {
  struct stat st {};
  return ::stat((slashed(dir) + "cameras" + extension(encoding)).c_str(), &st) == 0;
}

bool model_encoding(const std::string &dir, Encoding *out, std::string *error) {
  for (Encoding e : {Encoding::Binary, Encoding::Text}) {
    const std::string path = slashed(dir) + "cameras" + extension(e);
    struct stat st {};
    if (::stat(path.c_str(), &st) == 0) {
      *out = e;
      return true;
    }
    // A symbolic link loop or a directory that cannot be searched is said as it is.
    if (errno != ENOENT && errno != ENOTDIR) return fail(error, path + ": cannot open: " + std::strerror(errno));
  }
  return fail(error, dir + ": no COLMAP model (cameras.txt or cameras.bin)");
}

bool read_model(const std::string &dir, Model *out, Encoding *encoding, std::string *error) {
  Encoding enc;
  if (!model_encoding(dir, &enc, error)) return false;
  const bool text = enc == Encoding::Text;
  const std::string pc = slashed(dir) + "cameras" + extension(enc), pi = slashed(dir) + "images" + extension(enc),
                    pp = slashed(dir) + "points3D" + extension(enc);
  Model m;
  std::string content;
  if (!read_model_file(pc, text, &content, error)) return false;
  if (!(text ? parse_cameras_text : parse_cameras_binary)(content, pc, &m.cameras, error)) return false;
  if (!read_model_file(pi, text, &content, error)) return false;
  if (!(text ? parse_images_text : parse_images_binary)(content, pi, &m.images, error)) return false;
  if (!read_model_file(pp, text, &content, error)) return false;
  if (!(text ? parse_points_text : parse_points_binary)(content, pp, &m.points, error)) return false;
  if (!check_model(m, dir, error)) return false;
  *out = std::move(m);
  if (encoding) *encoding = enc;
  return true;
}

Files format_model(const Model &model, Encoding encoding) {
  return encoding == Encoding::Binary ? format_binary(model) : format_text(model);
}
bool model_writable(const std::string &dir, Encoding encoding, std::string *error) {
  // A directory made here goes with `probe`: the write makes it.
  OutputSet probe;
  if (!probe.make_directory(dir, error)) return false;
  std::string why;
  for (const ModelFile &file : kModelFiles) {
    const std::string path = slashed(dir) + file.name + extension(encoding);
    if (!probe_writable(path, &why)) return fail(error, path + ": " + why);
  }
  return true;
}

bool write_model(const std::string &dir, const Model &model, Encoding encoding, std::string *error,
                 OutputSet *outputs) {
  OutputSet own;
  OutputSet *set = outputs ? outputs : &own;
  if (!set->make_directory(dir, error)) return false;
  const Files files = format_model(model, encoding);
  for (const ModelFile &file : kModelFiles)
    if (!write_whole_file(slashed(dir) + file.name + extension(encoding), files.*file.content, error, set))
      return false;
  // The other encoding's model goes, or a reader could take it for this one; its cameras file
  // first, without which no reader takes the others for a model.
  const Encoding other = encoding == Encoding::Text ? Encoding::Binary : Encoding::Text;
  for (auto file = std::rbegin(kModelFiles); file != std::rend(kModelFiles); ++file)
    set->remove_on_commit(slashed(dir) + file->name + extension(other), "the model of the other format");
  return outputs || own.commit(error);
}

}  // namespace sbaformats::colmap
