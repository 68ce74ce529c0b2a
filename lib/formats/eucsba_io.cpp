// SPDX-License-Identifier: BSD-3-Clause
#include "formats/eucsba_io.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <memory>
#include <sys/stat.h>
#include <utility>

#include "formats/bzip2_stream.h"
#include "formats/output_file.h"
#include "formats/text_tokens.h"

namespace sbaformats::eucsba {

int camera_file_values(euclidean::CameraKind kind) { return euclidean::camera_params(kind) + 1; }

namespace {

// Success, or the first error found in a file, already as the text the public functions
// below give in *error.
class Status {
 public:
  Status() = default;  // success
  // "<file>:<line>: <message>", or "<file>: <message>" when line is 0 (open, write).
  static Status error(const std::string &file, int line, const std::string &message) {
    Status s;
    s.text_ = line > 0 ? file + ":" + std::to_string(line) + ": " + message : file + ": " + message;
    return s;
  }

  bool ok() const { return text_.empty(); }
  explicit operator bool() const { return ok(); }
  const std::string &text() const { return text_; }

 private:
  std::string text_;  // never empty for an error: it starts with the file and ": "
};

// The public functions' form of a Status: false, with its text in *error, for a failure.
bool reported(const Status &s, std::string *error) {
  if (!s) *error = s.text();
  return s.ok();
}

// The longest line a reader takes. Lines are read whole before being split, so a file
// without line breaks (/dev/zero, a binary file) would otherwise be read into memory entire.
// Camera and calibration lines hold at most 17 values: 1 MiB is far beyond any of them.
constexpr std::size_t kMaxLineBytes = std::size_t(1) << 20;
// A points file line grows with the cameras that see its point: 4 values and at most 7 per
// camera (frame, x, y and a full covariance). Its limit allows a point seen by every camera
// with 64 bytes per value (%.17e takes 24), and never less than kMaxLineBytes.
std::size_t points_line_limit(int ncameras) {
  constexpr std::size_t kBytesPerValue = 64;
  return std::max(kMaxLineBytes, (4 + 7 * static_cast<std::size_t>(std::max(ncameras, 0))) * kBytesPerValue);
}

// The data lines of a text file: blank and '#' lines skipped, the rest split into tokens.
class DataLines {
 public:
  DataLines(std::string path, std::size_t max_line = kMaxLineBytes)
      : path_(std::move(path)), max_line_(max_line) {}

  // "-" reads standard input (plain text); a file that starts as bzip2 data does (by its
  // magic, as balsba decides) is read through the decompressor.
  Status open() {
    if (path_ == "-") {
      in_.reset(stdin);
      owned_ = false;
      return {};
    }
    // fopen opens a directory for reading without complaint and then fails to read: ask first.
    struct stat st {};
    if (::stat(path_.c_str(), &st) == 0 && S_ISDIR(st.st_mode)) return error_at(0, "is a directory");
    errno = 0;
    in_.reset(std::fopen(path_.c_str(), "rb"));
    if (!in_) return error_at(0, errno != 0 ? std::string("cannot open: ") + std::strerror(errno) : "cannot open");
    if (S_ISREG(st.st_mode) && is_bzip2(in_.get())) {
      std::FILE *z = open_bzip2_stream(in_.release(), &bzip2_error_);
      if (!z) return error_at(0, "cannot read bzip2 data: out of memory");
      in_.reset(z);
    }
    return {};
  }
  ~DataLines() {
    if (!owned_) (void)in_.release();
  }
  DataLines(const DataLines &) = delete;
  DataLines &operator=(const DataLines &) = delete;

  // Advances to the next data line; false at the end of the file, on a read error, on a line
  // longer than the limit or after INT_MAX lines (finish() tells which).
  bool next() {
    std::string &text = text_;
    for (;;) {
      if (line_ == std::numeric_limits<int>::max()) {
        too_many_lines_ = true;
        return false;
      }
      if (!read_line(&text)) return false;
      ++line_;
      tokens_.clear();
      std::size_t pos = 0;
      const char *ws = " \t\r\n\v\f";
      pos = text.find_first_not_of(ws);
      if (pos == std::string::npos || text[pos] == '#') continue;
      while (pos != std::string::npos) {
        const std::size_t end = text.find_first_of(ws, pos);
        tokens_.push_back(text.substr(pos, end == std::string::npos ? end : end - pos));
        pos = text.find_first_not_of(ws, end);
      }
      return true;
    }
  }

  // After next() returned false: an error if the file could not be read to its end.
  Status finish() const {
    if (too_long_)
      return error_at(line_ + 1, "line longer than " + std::to_string(max_line_) + " bytes");
    if (too_many_lines_) return error("more than " + std::to_string(line_) + " lines");
    if (!bzip2_error_.empty()) return error_at(line_ + 1, bzip2_error_);
    if (read_errno_ != 0) return error_at(line_ + 1, std::string("read error: ") + std::strerror(read_errno_));
    return {};
  }

  const std::vector<std::string> &tokens() const { return tokens_; }
  std::size_t size() const { return tokens_.size(); }
  const std::string &operator[](std::size_t k) const { return tokens_[k]; }
  int line() const { return line_; }
  // For errors about the file as a whole, found at its end: an empty file has no line, so
  // say line 1.
  int last_line() const { return std::max(line_, 1); }

  Status error(const std::string &message) const { return error_at(line_, message); }
  Status error_at(int line, const std::string &message) const {
    return Status::error(path_, line, message);
  }

 private:
  // The next line without its '\n' into *text; false at the end of the file, on a read error
  // or when the line has more than max_line_ bytes (the rest is not read).
  bool read_line(std::string *text) {
    text->clear();
    std::FILE *f = in_.get();
    int c;
    while ((c = getc_unlocked(f)) != EOF) {
      if (c == '\n') return true;
      if (text->size() == max_line_) {
        too_long_ = true;
        return false;
      }
      text->push_back(static_cast<char>(c));
    }
    if (std::ferror(f)) {
      read_errno_ = errno != 0 ? errno : EIO;
      return false;
    }
    return !text->empty();  // a last line without '\n'
  }

  struct FileCloser {
    void operator()(std::FILE *f) const { std::fclose(f); }
  };

  std::string path_;
  std::size_t max_line_;
  std::unique_ptr<std::FILE, FileCloser> in_;
  bool owned_ = true;        // false for standard input, which is not closed
  std::string bzip2_error_;  // why the decompressor failed, if it did
  int line_ = 0;
  std::string text_;
  std::vector<std::string> tokens_;
  bool too_long_ = false, too_many_lines_ = false;
  int read_errno_ = 0;
};

// A token as an error message may show it: unprintable bytes (a NUL would cut the line short,
// an escape sequence would reach the terminal) become '?', and a long token is shortened.
std::string quoted(const std::string &tok) {
  constexpr std::size_t kMax = 40;
  std::string q = "'";
  for (std::size_t k = 0; k < tok.size() && k < kMax; ++k) {
    const unsigned char c = static_cast<unsigned char>(tok[k]);
    q += (c >= 32 && c < 127) ? static_cast<char>(c) : '?';
  }
  if (tok.size() > kMax) q += "...";
  return q + "'";
}

// A finite decimal number, or why the token is not one. The whole token must be read: strtod
// stops at a NUL inside it, which must not pass for the end of the token.
bool parse_real(const std::string &tok, double *value, std::string *why) {
  double v;
  if (!decimal_number(tok, &v)) {
    *why = quoted(tok) + " is not a number";
    return false;
  }
  if (!std::isfinite(v)) {
    // strtod saturates overflow to inf with ERANGE; underflow to 0 or a denormal is fine.
    *why = quoted(tok) + " is not a finite number";
    return false;
  }
  *value = v;
  return true;
}

// An integer written as one, or why the token is not one.
bool parse_integer(const std::string &tok, long long *value, std::string *why) {
  const char *s = tok.c_str();
  char *end = nullptr;
  errno = 0;
  const long long v = std::strtoll(s, &end, 10);
  if (end == s || end != s + tok.size()) {
    double ignored;
    std::string unused;
    *why = quoted(tok) + (parse_real(tok, &ignored, &unused) ? " is not an integer" : " is not a number");
    return false;
  }
  if (errno == ERANGE) {
    *why = quoted(tok) + " is out of range";
    return false;
  }
  *value = v;
  return true;
}

// Parses tokens [first, first + count) of the current line as finite doubles.
Status parse_reals(const DataLines &in, std::size_t first, std::size_t count, double *out,
                   const char *what) {
  std::string why;
  for (std::size_t k = 0; k < count; ++k)
    if (!parse_real(in[first + k], &out[k], &why))
      return in.error(std::string(what) + " " + std::to_string(first + k + 1) + ": " + why);
  return {};
}

const char *form_name(CovarianceForm form) {
  switch (form) {
    case CovarianceForm::None: return "no covariances (f x y)";
    case CovarianceForm::UpperTriangular: return "upper-triangular covariances (f x y cxx cxy cyy)";
    case CovarianceForm::Full: return "full covariances (f x y cxx cxy cyx cyy)";
  }
  return "";
}

int form_width(CovarianceForm form) {
  switch (form) {
    case CovarianceForm::None: return 3;
    case CovarianceForm::UpperTriangular: return 6;
    case CovarianceForm::Full: return 7;
  }
  return 0;
}

// The form whose per-projection width times nframes gives count, if any.
bool form_for(std::size_t count, long long nframes, CovarianceForm *form) {
  for (CovarianceForm f : {CovarianceForm::None, CovarianceForm::UpperTriangular, CovarianceForm::Full}) {
    if (count == static_cast<std::size_t>(nframes) * form_width(f)) {
      *form = f;
      return true;
    }
  }
  return false;
}

// The writers go through an OutputFile (output_file.h): the result appears whole under its name
// or not at all, at once or with the set of outputs it belongs to.
Status open_for_writing(const std::string &path, SetFile *file) {
  std::string why;
  if (!file->open(path, &why)) return Status::error(path, 0, why);
  return {};
}

// Closes the file (and moves it to its name when it is on its own), reporting what a full
// disk or a failed write did.
Status close_written(const std::string &path, SetFile *file) {
  std::string why;
  if (!file->close(&why)) return Status::error(path, 0, why);
  return {};
}

Status read_cameras_status(const std::string &path, CameraFile *out) {
  DataLines in(path);
  if (Status s = in.open(); !s) return s;
  CameraFile result;
  std::size_t nvalues = 0;
  while (in.next()) {
    const std::size_t count = in.size();
    if (nvalues == 0) {
      if (count == 7) result.kind = euclidean::CameraKind::FixedIntrinsics;
      else if (count == 12) result.kind = euclidean::CameraKind::VaryingIntrinsics;
      else if (count == 17) result.kind = euclidean::CameraKind::VaryingIntrinsicsDistortion;
      else
        return in.error("expected 7, 12 or 17 values per camera line (fixed intrinsics, varying "
                        "intrinsics, varying intrinsics and distortion), found " +
                        std::to_string(count));
      nvalues = count;
      result.first_line = in.line();
    } else if (count != nvalues) {
      return in.error("expected " + std::to_string(nvalues) + " values as on line " +
                      std::to_string(result.first_line) + ", found " + std::to_string(count));
    }
    double v[17];
    if (Status s = parse_reals(in, 0, count, v, "value"); !s) return s;

    euclidean::Camera cam;
    const double *p = v;
    if (result.kind != euclidean::CameraKind::FixedIntrinsics) {
      cam.k = {p[0], p[1], p[2], p[3], p[4]};
      p += euclidean::kIntrinsicParams;
    }
    if (result.kind == euclidean::CameraKind::VaryingIntrinsicsDistortion) {
      std::copy(p, p + euclidean::kDistortionParams, cam.kc.begin());
      p += euclidean::kDistortionParams;
    }
    cam.q = {p[0], p[1], p[2], p[3]};
    if (p[0] == 0 && p[1] == 0 && p[2] == 0 && p[3] == 0)
      return in.error("the quaternion is zero and gives no rotation");
    std::copy(p + 4, p + 7, cam.t.begin());
    result.cameras.push_back(cam);
  }
  if (Status s = in.finish(); !s) return s;
  if (result.cameras.empty())
    return in.error_at(in.last_line(), "no cameras (empty or comment-only file)");
  *out = std::move(result);
  return {};
}

Status read_calibration_status(const std::string &path, euclidean::Intrinsics *out) {
  DataLines in(path);
  if (Status s = in.open(); !s) return s;
  double K[3][3];
  int row_line[3] = {0, 0, 0};
  int rows = 0;
  while (in.next()) {
    if (rows == 3) return in.error("a 4th row: the calibration file holds the 3x3 matrix K only");
    if (in.size() != 3)
      return in.error("expected 3 values in row " + std::to_string(rows + 1) + " of K, found " +
                      std::to_string(in.size()));
    if (Status s = parse_reals(in, 0, 3, K[rows], "value"); !s) return s;
    row_line[rows++] = in.line();
  }
  if (Status s = in.finish(); !s) return s;
  if (rows < 3)
    return in.error_at(in.last_line(), "K has " + std::to_string(rows) + " row" +
                                           (rows == 1 ? "" : "s") + ", expected 3");
  if (K[1][0] != 0) return in.error_at(row_line[1], "K[1][0] must be 0 (K = [fu s u0; 0 fv v0; 0 0 1])");
  if (K[2][0] != 0 || K[2][1] != 0 || K[2][2] != 1)
    return in.error_at(row_line[2], "the last row of K must be 0 0 1");
  if (K[0][0] == 0) return in.error_at(row_line[0], "fu (K[0][0]) must be nonzero");
  if (K[1][1] == 0) return in.error_at(row_line[1], "fv (K[1][1]) must be nonzero");
  // The model keeps fv as fu*ar: a ratio that overflows or underflows (a subnormal fu or fv)
  // would turn a valid-looking K into an infinite or zero focal length.
  const double ar = K[1][1] / K[0][0];
  if (!std::isfinite(ar) || ar == 0)
    return in.error_at(row_line[1], "the aspect ratio fv/fu (K[1][1]/K[0][0]) overflows or underflows");
  out->fu = K[0][0];
  out->s = K[0][1];
  out->u0 = K[0][2];
  out->v0 = K[1][2];
  out->ar = ar;
  return {};
}

struct Projection {
  int frame;
  double x, y;
  double cov[4];
};

// The covariance form of a point line with nframes projections in its values after the 4th:
// the first point's fixes it for the file (*form_line, its line, 0 before), every later one
// must hold the same.
Status check_form(const DataLines &in, long long nframes, int *form_line, CovarianceForm *file_form) {
  const std::size_t rest = in.size() - 4;
  CovarianceForm form;
  if (*form_line == 0) {
    if (!form_for(rest, nframes, &form))
      return in.error("nframes is " + std::to_string(nframes) + " but " + std::to_string(rest) +
                      " values follow it: expected " + std::to_string(3 * nframes) + " (f x y per frame), " +
                      std::to_string(6 * nframes) + " or " + std::to_string(7 * nframes) + " (with covariances)");
    *file_form = form;
    *form_line = in.line();
  } else if (rest != static_cast<std::size_t>(nframes) * form_width(*file_form)) {
    if (form_for(rest, nframes, &form))
      return in.error(std::string("inconsistent covariance form: ") + form_name(form) + " here, " +
                      form_name(*file_form) + " on line " + std::to_string(*form_line));
    return in.error("nframes is " + std::to_string(nframes) + " but " + std::to_string(rest) +
                    " values follow it: expected " + std::to_string(nframes * form_width(*file_form)) + " (" +
                    form_name(*file_form) + " as on line " + std::to_string(*form_line) + ")");
  }
  return {};
}

// The projection whose frame index is value `first` of the line.
Status parse_projection(const DataLines &in, std::size_t first, CovarianceForm form, int ncameras, Projection *out) {
  long long frame = 0;
  std::string why;
  if (!parse_integer(in[first], &frame, &why)) return in.error("frame index: " + why);
  if (frame < 0 || frame >= ncameras)
    return in.error("frame index " + std::to_string(frame) + " out of range [0, " + std::to_string(ncameras) + ")");
  Projection p{static_cast<int>(frame), 0, 0, {0, 0, 0, 0}};
  double v[6];
  if (Status s = parse_reals(in, first + 1, form_width(form) - 1, v, "value"); !s) return s;
  p.x = v[0];
  p.y = v[1];
  if (form == CovarianceForm::UpperTriangular) {
    p.cov[0] = v[2];
    p.cov[1] = p.cov[2] = v[3];
    p.cov[3] = v[4];
  } else if (form == CovarianceForm::Full) {
    // The file repeats cxy; two different numbers there mean the matrix is not a
    // covariance, which is worth saying rather than silently averaging away.
    const double tol = 1e-9 * (std::fabs(v[2]) + std::fabs(v[5]));
    if (std::fabs(v[3] - v[4]) > tol)
      return in.error("covariance of frame " + std::to_string(frame) + " is not symmetric");
    p.cov[0] = v[2];
    p.cov[1] = p.cov[2] = 0.5 * (v[3] + v[4]);
    p.cov[3] = v[5];
  }
  if (form != CovarianceForm::None && !(p.cov[0] > 0 && p.cov[0] * p.cov[3] - p.cov[1] * p.cov[1] > 0))
    return in.error("covariance of frame " + std::to_string(frame) + " is not positive definite");
  *out = p;
  return {};
}

// The line's nframes projections, by ascending frame (sba wants each point's measurements so;
// files need not be sorted), each frame once.
Status parse_track(const DataLines &in, long long nframes, CovarianceForm form, int ncameras,
                   std::vector<Projection> *track) {
  track->clear();
  for (long long f = 0; f < nframes; ++f) {
    Projection p;
    if (Status s = parse_projection(in, 4 + static_cast<std::size_t>(f) * form_width(form), form, ncameras, &p); !s)
      return s;
    track->push_back(p);
  }
  std::stable_sort(track->begin(), track->end(),
                   [](const Projection &a, const Projection &b) { return a.frame < b.frame; });
  for (std::size_t k = 1; k < track->size(); ++k)
    if ((*track)[k].frame == (*track)[k - 1].frame)
      return in.error("frame " + std::to_string((*track)[k].frame) + " appears twice in this track");
  return {};
}

Status read_points_status(const std::string &path, int ncameras, PointSet *out) {
  DataLines in(path, points_line_limit(ncameras));
  if (Status s = in.open(); !s) return s;

  PointSet result;
  result.ncameras = ncameras;
  int form_line = 0;  // the line that fixed the covariance form; 0 before the first point
  // Each point's visible cameras, to build vmask once the number of points is known.
  std::vector<int> frames_of;     // concatenated, ascending per point
  std::vector<int> frames_begin{0};
  std::vector<Projection> track;
  while (in.next()) {
    if (in.size() < 4)
      return in.error("expected X Y Z nframes and the projections, found " + std::to_string(in.size()) +
                      (in.size() == 1 ? " value" : " values"));
    double X[3];
    if (Status s = parse_reals(in, 0, 3, X, "value"); !s) return s;
    long long nframes = 0;
    std::string why;
    if (!parse_integer(in[3], &nframes, &why)) return in.error("nframes: " + why);
    if (nframes < 1) return in.error("nframes is " + std::to_string(nframes) + ", must be at least 1");
    if (nframes > ncameras)
      return in.error("nframes is " + std::to_string(nframes) + ", more than the " + std::to_string(ncameras) +
                      " cameras");
    if (Status s = check_form(in, nframes, &form_line, &result.form); !s) return s;
    if (Status s = parse_track(in, nframes, result.form, ncameras, &track); !s) return s;

    if (result.x.size() / 2 + track.size() > static_cast<std::size_t>(std::numeric_limits<int>::max() / 2))
      return in.error("too many projections for sba's int sizes");
    result.xyz.insert(result.xyz.end(), X, X + 3);
    for (const Projection &p : track) {
      frames_of.push_back(p.frame);
      result.x.push_back(p.x);
      result.x.push_back(p.y);
      if (result.form != CovarianceForm::None) result.covx.insert(result.covx.end(), p.cov, p.cov + 4);
    }
    frames_begin.push_back(static_cast<int>(frames_of.size()));
  }
  if (Status s = in.finish(); !s) return s;
  if (result.xyz.empty()) return in.error_at(in.last_line(), "no points (empty or comment-only file)");

  const std::size_t n = result.xyz.size() / 3;
  result.vmask.assign(n * static_cast<std::size_t>(ncameras), 0);
  for (std::size_t i = 0; i < n; ++i)
    for (int e = frames_begin[i]; e < frames_begin[i + 1]; ++e)
      result.vmask[i * ncameras + frames_of[e]] = 1;
  *out = std::move(result);
  return {};
}

Status load_problem_status(const std::string &cams_path, const std::string &pts_path,
                    const std::string &calib_path, Problem *out) {
  CameraFile cams;
  if (Status s = read_cameras_status(cams_path, &cams); !s) return s;
  const bool fixed = cams.kind == euclidean::CameraKind::FixedIntrinsics;
  if (fixed && calib_path.empty())
    return Status::error(cams_path, cams.first_line,
                         "7 values per camera line mean intrinsics shared by all cameras: "
                         "a calibration file is needed");
  if (!fixed && !calib_path.empty())
    return Status::error(cams_path, cams.first_line,
                         std::to_string(camera_file_values(cams.kind)) +
                             " values per camera line give each camera its own intrinsics: "
                             "a calibration file does not apply");
  Problem result;
  result.kind = cams.kind;
  result.cameras = std::move(cams.cameras);
  if (fixed) {
    euclidean::Intrinsics K;
    if (Status s = read_calibration_status(calib_path, &K); !s) return s;
    for (euclidean::Camera &c : result.cameras) c.k = K;
  }
  if (Status s = read_points_status(pts_path, static_cast<int>(result.cameras.size()), &result.points); !s)
    return s;
  *out = std::move(result);
  return {};
}

Status write_cameras_status(const std::string &path, euclidean::CameraKind kind,
                     const std::vector<euclidean::Camera> &cameras, OutputSet *outputs) {
  SetFile f(outputs);
  if (Status s = open_for_writing(path, &f); !s) return s;
  switch (kind) {
    case euclidean::CameraKind::FixedIntrinsics: std::fputs("# q0 q1 q2 q3  tx ty tz\n", f.get()); break;
    case euclidean::CameraKind::VaryingIntrinsics:
      std::fputs("# fu u0 v0 ar s  q0 q1 q2 q3  tx ty tz\n", f.get());
      break;
    case euclidean::CameraKind::VaryingIntrinsicsDistortion:
      std::fputs("# fu u0 v0 ar s  kc0 kc1 kc2 kc3 kc4  q0 q1 q2 q3  tx ty tz\n", f.get());
      break;
  }
  for (const euclidean::Camera &c : cameras) {
    std::vector<double> v;
    if (kind != euclidean::CameraKind::FixedIntrinsics) v = {c.k.fu, c.k.u0, c.k.v0, c.k.ar, c.k.s};
    if (kind == euclidean::CameraKind::VaryingIntrinsicsDistortion) v.insert(v.end(), c.kc.begin(), c.kc.end());
    v.insert(v.end(), {c.q.w, c.q.x, c.q.y, c.q.z, c.t[0], c.t[1], c.t[2]});
    for (std::size_t k = 0; k < v.size(); ++k)
      std::fprintf(f.get(), k == 0 ? "%.10e" : " %.10e", v[k]);
    std::fputc('\n', f.get());
  }
  return close_written(path, &f);
}

Status write_points_xyz_status(const std::string &path, const std::vector<double> &xyz, OutputSet *outputs) {
  SetFile f(outputs);
  if (Status s = open_for_writing(path, &f); !s) return s;
  for (std::size_t i = 0; i + 2 < xyz.size(); i += 3)
    std::fprintf(f.get(), "%.10e %.10e %.10e\n", xyz[i], xyz[i + 1], xyz[i + 2]);
  return close_written(path, &f);
}

Status write_points_status(const std::string &path, const PointSet &tracks, const std::vector<double> &xyz,
                    OutputSet *outputs) {
  if (xyz.size() != tracks.xyz.size())
    return Status::error(path, 0, "internal error: " + std::to_string(xyz.size() / 3) +
                                      " coordinates for " + std::to_string(tracks.npoints()) + " points");
  const CovarianceForm form = tracks.has_covariances() ? tracks.form : CovarianceForm::None;
  SetFile f(outputs);
  if (Status s = open_for_writing(path, &f); !s) return s;
  std::fputs("# X Y Z  nframes  frame0 x0 y0", f.get());
  if (form == CovarianceForm::UpperTriangular) std::fputs(" cxx0 cxy0 cyy0", f.get());
  if (form == CovarianceForm::Full) std::fputs(" cxx0 cxy0 cxy0 cyy0", f.get());
  std::fputs("  frame1 ...\n", f.get());
  // A point's line starts with its number of frames: counted first.
  const int n = tracks.npoints();
  std::vector<int> nframes(static_cast<std::size_t>(n), 0);
  for_each_projection(tracks, [&](int i, int, const double *) { ++nframes[static_cast<std::size_t>(i)]; });
  int next = 0;  // the first point whose line is not begun
  auto begin_lines_to = [&](int i) {
    for (; next <= i; ++next) {
      if (next > 0) std::fputc('\n', f.get());
      const double *X = &xyz[3 * static_cast<std::size_t>(next)];
      std::fprintf(f.get(), "%.10e %.10e %.10e %d", X[0], X[1], X[2], nframes[static_cast<std::size_t>(next)]);
    }
  };
  for_each_projection(tracks, [&](int i, int j, const double *x) {
    begin_lines_to(i);
    std::fprintf(f.get(), "  %d %.10e %.10e", j, x[0], x[1]);
    const std::size_t k = static_cast<std::size_t>(x - tracks.x.data()) / 2;  // the measurement
    const double *c = form != CovarianceForm::None ? &tracks.covx[4 * k] : nullptr;
    if (form == CovarianceForm::UpperTriangular)
      std::fprintf(f.get(), " %.10e %.10e %.10e", c[0], c[1], c[3]);
    else if (form == CovarianceForm::Full)
      std::fprintf(f.get(), " %.10e %.10e %.10e %.10e", c[0], c[1], c[2], c[3]);
  });
  begin_lines_to(n - 1);
  if (n > 0) std::fputc('\n', f.get());
  return close_written(path, &f);
}

Status read_points_xyz_status(const std::string &path, std::vector<double> *xyz) {
  DataLines in(path);
  if (Status s = in.open(); !s) return s;
  std::vector<double> result;
  while (in.next()) {
    if (in.size() != 3) return in.error("expected X Y Z, found " + std::to_string(in.size()) + " values");
    double X[3];
    if (Status s = parse_reals(in, 0, 3, X, "value"); !s) return s;
    result.insert(result.end(), X, X + 3);
  }
  if (Status s = in.finish(); !s) return s;
  if (result.empty()) return in.error_at(in.last_line(), "no points (empty or comment-only file)");
  *xyz = std::move(result);
  return {};
}

}  // namespace

bool read_cameras(const std::string &path, CameraFile *out, std::string *error) {
  return reported(read_cameras_status(path, out), error);
}

bool read_calibration(const std::string &path, euclidean::Intrinsics *out, std::string *error) {
  return reported(read_calibration_status(path, out), error);
}

bool read_points(const std::string &path, int ncameras, PointSet *out, std::string *error) {
  return reported(read_points_status(path, ncameras, out), error);
}

bool load_problem(const std::string &cams_path, const std::string &pts_path, const std::string &calib_path,
                  Problem *out, std::string *error) {
  return reported(load_problem_status(cams_path, pts_path, calib_path, out), error);
}

bool write_cameras(const std::string &path, euclidean::CameraKind kind,
                   const std::vector<euclidean::Camera> &cameras, std::string *error, OutputSet *outputs) {
  return reported(write_cameras_status(path, kind, cameras, outputs), error);
}

bool write_points_xyz(const std::string &path, const std::vector<double> &xyz, std::string *error,
                      OutputSet *outputs) {
  return reported(write_points_xyz_status(path, xyz, outputs), error);
}

bool write_points(const std::string &path, const PointSet &tracks, const std::vector<double> &xyz,
                  std::string *error, OutputSet *outputs) {
  return reported(write_points_status(path, tracks, xyz, outputs), error);
}

bool read_points_xyz(const std::string &path, std::vector<double> *xyz, std::string *error) {
  return reported(read_points_xyz_status(path, xyz), error);
}

}  // namespace sbaformats::eucsba
