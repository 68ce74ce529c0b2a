/* SPDX-License-Identifier: BSD-3-Clause */
// What the COLMAP text format (colmap_text.cpp), the binary format (colmap_binary.cpp) and the
// model's files (colmap_io.cpp) share beyond colmap_io.h: the messages about a model, and the
// formatting of a model in each encoding. COLMAP's camera models are colmap_camera.h's.
#ifndef SBA_LIB_FORMATS_COLMAP_IO_IMPL_H
#define SBA_LIB_FORMATS_COLMAP_IO_IMPL_H

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "cameras/colmap_camera.h"
#include "formats/colmap_io.h"

namespace sbaformats::colmap {

using sbacameras::colmap_camera::kModels;
using sbacameras::colmap_camera::kNumModels;
using sbacameras::colmap_camera::ModelInfo;

// What separates values in the text format: a carriage return too, so that a CRLF file or a
// stray '\r' does not end up inside a value (or as an image name that a rewrite would lose).
// The binary reader refuses a name the text format could not hold.
inline bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\r'; }

// The text format's name of a sensor type.
inline const char *sensor_type_name(SensorType type) { return type == SensorType::Camera ? "CAMERA" : "IMU"; }
// A sensor as the messages name it: "CAMERA 2".
inline std::string sensor_name(const SensorId &s) {
  return sensor_type_name(s.type) + (" " + std::to_string(s.id));
}

// A sensor as one number, its type above its id: the key by which sensors are sorted and found.
inline std::uint64_t sensor_key(const SensorId &s) {
  return std::uint64_t{static_cast<std::uint32_t>(s.type)} << 32 | s.id;
}

// s as a message quotes it: at most 40 characters, then "...", any byte outside printable
// ASCII as '?'.
std::string printable(const std::string &s);

// *error = msg (when error is not null); false. Inline, so that the compiler sees the false,
// and with it that a value a reader failed to read is never used.
inline bool fail(std::string *error, const std::string &msg) {
  if (error) *error = msg;
  return false;
}

// The position of each id in a list of records (cameras, images, points), the first one's
// when an id repeats. A model holds hundreds of thousands of points and millions of
// observations that name them: open addressing in one array, without std::unordered_map's
// allocation per id and pointer chase per look-up.
class IdIndex {
 public:
  static constexpr std::size_t kNone = ~std::size_t{0};

  // Room for n ids before the table grows.
  explicit IdIndex(std::size_t n = 0) { rehash(n); }

  // Records id at index; false, and nothing changed, when id is already there.
  bool insert(std::uint64_t id, std::size_t index) {
    if (2 * (size_ + 1) > slots_.size()) rehash(2 * (size_ + 1));
    Slot *s = &slots_[home(id)];
    for (; s->index != kNone; s = next(s))
      if (s->id == id) return false;
    *s = {id, index};
    ++size_;
    return true;
  }
  // The index recorded for id, kNone when there is none.
  std::size_t find(std::uint64_t id) const {
    for (const Slot *s = &slots_[home(id)]; s->index != kNone; s = next(s))
      if (s->id == id) return s->index;
    return kNone;
  }

 private:
  struct Slot {
    std::uint64_t id;
    std::size_t index;
  };

  // Fibonacci hashing: the top bits of id times 2^64 / phi, spread well even for the
  // consecutive ids that models usually hold.
  std::size_t home(std::uint64_t id) const {
    return static_cast<std::size_t>((id * 0x9E3779B97F4A7C15ull) >> shift_);
  }
  // Linear probing, wrapping at the end of the table.
  Slot *next(Slot *s) { return ++s == slots_.data() + slots_.size() ? slots_.data() : s; }
  const Slot *next(const Slot *s) const { return ++s == slots_.data() + slots_.size() ? slots_.data() : s; }

  // A table of at least 2n slots (a power of two), holding the ids recorded so far.
  void rehash(std::size_t n) {
    int bits = 4;
    while ((std::size_t{1} << bits) < 2 * n) ++bits;
    std::vector<Slot> old(std::size_t{1} << bits, Slot{0, kNone});
    old.swap(slots_);
    shift_ = 64 - bits;
    size_ = 0;
    for (const Slot &s : old)
      if (s.index != kNone) insert(s.id, s.index);
  }

  std::vector<Slot> slots_;
  int shift_ = 60;
  std::size_t size_ = 0;
};

// format_model for each encoding.
Files format_text(const Model &model, const std::vector<Pose> &poses);
Files format_binary(const Model &model, const std::vector<Pose> &poses);

}  // namespace sbaformats::colmap

#endif  // SBA_LIB_FORMATS_COLMAP_IO_IMPL_H
