// SPDX-License-Identifier: BSD-3-Clause
#include "formats/bal_io.h"

#include <bzlib.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <new>
#include <numeric>
#include <string>
#include <vector>

#include "formats/output_file.h"
#include "formats/text_tokens.h"

namespace sbaformats::bal {
namespace {

bool fail(std::string *error, const std::string &name, const std::string &message) {
  if (error) *error = name + ": " + message;
  return false;
}

struct FileCloser {
  void operator()(std::FILE *f) const { std::fclose(f); }
};
using File = std::unique_ptr<std::FILE, FileCloser>;

// ---- reading the bytes ----
//
// The text is parsed as it is read, never held whole: a small compressed file can expand to
// gigabytes, and a header announcing more than the file holds must not reserve it either.

// Where the text comes from: a string, a plain file, or the bzip2 streams of a file.
class Source {
 public:
  virtual ~Source() = default;
  // Up to n bytes into buf; 0 at the end of the text or on an error (then error() is set).
  virtual std::size_t read(char *buf, std::size_t n) = 0;
  const std::string &error() const { return error_; }

 protected:
  std::string error_;
};

class StringSource : public Source {
 public:
  explicit StringSource(const std::string &text) : text_(text) {}
  std::size_t read(char *buf, std::size_t n) override {
    const std::size_t k = std::min(n, text_.size() - pos_);
    std::memcpy(buf, text_.data() + pos_, k);
    pos_ += k;
    return k;
  }

 private:
  const std::string &text_;
  std::size_t pos_ = 0;
};

// head: the bytes already read from f (to tell text from bzip2), given back first.
class PlainSource : public Source {
 public:
  PlainSource(std::FILE *f, const std::string &head) : f_(f), head_(head) {}
  std::size_t read(char *buf, std::size_t n) override {
    if (const std::size_t got = head_.read(buf, n)) return got;
    const std::size_t got = std::fread(buf, 1, n, f_);
    if (got == 0 && std::ferror(f_)) error_ = std::string("read error: ") + std::strerror(errno);
    return got;
  }

 private:
  std::FILE *f_;
  StringSource head_;
};

std::string bz_message(int code) {
  switch (code) {
    case BZ_DATA_ERROR: return "corrupt bzip2 data";
    case BZ_DATA_ERROR_MAGIC: return "data after the end of the bzip2 stream is not bzip2";
    case BZ_UNEXPECTED_EOF: return "truncated bzip2 file (the compressed stream ends early)";
    case BZ_IO_ERROR: return std::string("read error: ") + std::strerror(errno);
    default: return "bzip2 error " + std::to_string(code);
  }
}

// Every bzip2 stream in f, one after the other (pbzip2 writes several); head: the bytes
// already read from f, the first stream's start.
class Bzip2Source : public Source {
 public:
  Bzip2Source(std::FILE *f, const std::string &head) : f_(f), unused_(head.begin(), head.end()) {}
  ~Bzip2Source() override { close(); }
  Bzip2Source(const Bzip2Source &) = delete;
  Bzip2Source &operator=(const Bzip2Source &) = delete;

  std::size_t read(char *buf, std::size_t n) override {
    while (!done_ && error_.empty()) {
      int bzerr = BZ_OK;
      if (!bz_) {
        bz_ = BZ2_bzReadOpen(&bzerr, f_, 0, 0, unused_.empty() ? nullptr : unused_.data(),
                             static_cast<int>(unused_.size()));
        if (bzerr != BZ_OK) {
          close();
          if (bzerr == BZ_MEM_ERROR) throw std::bad_alloc();
          error_ = bz_message(bzerr);
          return 0;
        }
      }
      const int got = BZ2_bzRead(&bzerr, bz_, buf, static_cast<int>(std::min<std::size_t>(n, INT_MAX)));
      if (bzerr == BZ_STREAM_END) {
        // Bytes read past this stream's end are the next one's start.
        void *rest = nullptr;
        int nrest = 0;
        BZ2_bzReadGetUnused(&bzerr, bz_, &rest, &nrest);
        unused_.assign(static_cast<char *>(rest), static_cast<char *>(rest) + nrest);
        close();
        if (unused_.empty()) {
          // Another stream may follow in the part of the file not read yet.
          const int c = std::fgetc(f_);
          if (c != EOF) unused_.push_back(static_cast<char>(c));
          else if (std::ferror(f_)) error_ = std::string("read error: ") + std::strerror(errno);
          else done_ = true;
        }
        if (got > 0) return static_cast<std::size_t>(got);
        continue;
      }
      if (bzerr != BZ_OK) {
        close();
        if (bzerr == BZ_MEM_ERROR) throw std::bad_alloc();
        error_ = bz_message(bzerr);
        return 0;
      }
      if (got > 0) return static_cast<std::size_t>(got);
    }
    return 0;
  }

 private:
  void close() {
    if (!bz_) return;
    int ignored;
    BZ2_bzReadClose(&ignored, bz_);
    bz_ = nullptr;
  }

  std::FILE *f_;
  BZFILE *bz_ = nullptr;
  std::vector<char> unused_;
  bool done_ = false;
};

// ---- the tokenizer ----

// No number needs this many bytes; a longer run without white space (a binary file,
// /dev/zero) is refused at once instead of being gathered into one huge token.
constexpr std::size_t kMaxTokenBytes = 4096;
// Nor does any BAL writer put this much white space in a row; refusing it bounds the time
// spent reading a file padded with blanks.
constexpr std::size_t kMaxSpaceBytes = std::size_t(1) << 20;

bool is_space(char c) {
  return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f';
}

std::string at_line(long long line) { return "line " + std::to_string(line) + ": "; }

class Tokens {
 public:
  explicit Tokens(Source *source) : source_(source) {}

  // The next token; false at the end of the text or on an error (then failed() is true).
  bool next() {
    tok_.clear();
    std::size_t space = 0;
    char c;
    while (peek(&c) && is_space(c)) {
      if (c == '\n') ++line_;
      if (++space > kMaxSpaceBytes)
        return fail(at_line(line_) + "more than " + std::to_string(kMaxSpaceBytes) +
                    " bytes of white space in a row");
      ++pos_;
    }
    if (!error_.empty()) return false;
    tok_line_ = line_;
    while (peek(&c) && !is_space(c)) {
      if (tok_.size() == kMaxTokenBytes)
        return fail(at_line(tok_line_) + "more than " + std::to_string(kMaxTokenBytes) +
                    " bytes without white space (no number is that long)");
      tok_.push_back(c);
      ++pos_;
    }
    return error_.empty() && !tok_.empty();
  }

  bool failed() const { return !error_.empty(); }
  // Why next() failed: the source's message, or the line and what was found there.
  const std::string &error() const { return error_; }

  long long line() const { return tok_line_; }
  // The current token for messages, cut to a readable length.
  std::string quoted() const {
    std::string s = tok_.substr(0, 40);
    for (char &ch : s)
      if (static_cast<unsigned char>(ch) < 32 || static_cast<unsigned char>(ch) > 126) ch = '?';
    if (tok_.size() > 40) s += "...";
    return "'" + s + "'";
  }

  // The current token as an integer written as one (optional sign, digits).
  bool integer(long long *v) const {
    const std::size_t k = (tok_[0] == '-' || tok_[0] == '+') ? 1 : 0;
    if (k == tok_.size()) return false;
    for (std::size_t i = k; i < tok_.size(); ++i)
      if (tok_[i] < '0' || tok_[i] > '9') return false;
    if (tok_.size() - k > 18) return false;  // beyond any count we accept; avoids overflow
    errno = 0;
    char *stop = nullptr;
    *v = std::strtoll(tok_.c_str(), &stop, 10);
    return errno == 0 && stop == tok_.c_str() + tok_.size();
  }

  // The current token as a finite decimal number; the whole token must be the number (strtod
  // stops at a NUL inside it, which must not pass for the end).
  bool real(double *v) const { return decimal_number(tok_, v) && std::isfinite(*v); }

 private:
  // The byte at the read position, refilling the buffer; false at the end or on an error.
  bool peek(char *c) {
    if (pos_ == len_) {
      if (!error_.empty()) return false;
      len_ = source_->read(buf_, sizeof buf_);
      pos_ = 0;
      if (len_ == 0) {
        error_ = source_->error();
        return false;
      }
    }
    *c = buf_[pos_];
    return true;
  }

  bool fail(const std::string &message) {
    error_ = message;
    return false;
  }

  Source *source_;
  char buf_[1 << 16];
  std::size_t pos_ = 0, len_ = 0;
  std::string tok_;
  std::string error_;
  long long line_ = 1, tok_line_ = 1;
};

const char *const kCameraParamNames[kCameraParams] = {"w1", "w2", "w3", "t1", "t2", "t3", "f", "k1", "k2"};
const char *const kPointParamNames[kPointParams] = {"X", "Y", "Z"};

// Storage reserved ahead of the values at most: beyond it, vectors grow as values arrive, so
// a header announcing more than the file holds cannot exhaust memory by itself.
constexpr std::size_t kMaxReserve = std::size_t(1) << 16;

// The end of the text where more was expected: the source's error if it had one (a
// truncated or corrupt bzip2 file), else the truncation.
bool ended(const Tokens &tok, const std::string &name, const std::string &truncated, std::string *error) {
  return fail(error, name, tok.failed() ? tok.error() : truncated);
}

std::size_t reserve_for(long long values) {
  return std::min<std::size_t>(static_cast<std::size_t>(values), kMaxReserve);
}

// The header's three counts, each in 1..INT_MAX, and no more observations than pairs.
bool parse_header(Tokens &tok, const std::string &name, long long counts[3], std::string *error) {
  const char *const header_names[3] = {"number of cameras", "number of points", "number of observations"};
  for (int c = 0; c < 3; ++c) {
    if (!tok.next()) {
      if (c == 0) return ended(tok, name, "empty file: expected the header 'ncameras npoints nobservations'", error);
      return ended(tok, name, "truncated file: the header 'ncameras npoints nobservations' is incomplete", error);
    }
    if (!tok.integer(&counts[c]))
      return fail(error, name, at_line(tok.line()) + std::string("header: the ") + header_names[c] +
                                   " must be an integer, got " + tok.quoted());
    if (counts[c] <= 0 || counts[c] > INT_MAX)
      return fail(error, name, at_line(tok.line()) + std::string("header: the ") + header_names[c] +
                                   " must be between 1 and " + std::to_string(INT_MAX) + ", got " +
                                   std::to_string(counts[c]));
  }
  if (counts[2] > counts[0] * counts[1])
    return fail(error, name, "header: " + std::to_string(counts[2]) + " observations but only " +
                                 std::to_string(counts[0] * counts[1]) +
                                 " camera-point pairs (each pair is observed at most once)");
  return true;
}

// p's nobs observations, and the line of each (for the repeats' message). expected: what
// the header announced, for the truncation's message.
bool parse_observations(Tokens &tok, const std::string &name, long long nobs, const std::string &expected,
                        Problem *p, std::vector<long long> *obs_line, std::string *error) {
  p->observations.reserve(reserve_for(nobs));
  obs_line->reserve(reserve_for(nobs));
  for (long long k = 0; k < nobs; ++k) {
    Observation o;
    auto what = [k] { return "observation " + std::to_string(k) + ": "; };
    const char *const fields[4] = {"camera index", "point index", "x", "y"};
    for (int f = 0; f < 4; ++f) {
      if (!tok.next())
        return ended(tok, name,
                     "truncated file: it ends inside observation " + std::to_string(k) + " (" + expected + ")", error);
      if (f < 2) {
        long long v;
        if (!tok.integer(&v))
          return fail(error, name, at_line(tok.line()) + what() + "the " + fields[f] +
                                       " must be an integer, got " + tok.quoted());
        const int limit = f == 0 ? p->ncameras : p->npoints;
        if (v < 0 || v >= limit)
          return fail(error, name, at_line(tok.line()) + what() + "the " + fields[f] + " " +
                                       std::to_string(v) + " is out of range 0.." + std::to_string(limit - 1));
        (f == 0 ? o.camera : o.point) = static_cast<int>(v);
        if (f == 0) obs_line->push_back(tok.line());
      } else {
        double v;
        if (!tok.real(&v))
          return fail(error, name, at_line(tok.line()) + what() + fields[f] +
                                       " must be a finite number, got " + tok.quoted());
        (f == 2 ? o.x : o.y) = v;
      }
    }
    p->observations.push_back(o);
  }
  return true;
}

// count objects (cameras or points, named `what`) of n values each, named by `names`, into
// *values.
bool parse_values(Tokens &tok, const std::string &name, long long count, int n, const char *const *names,
                  const char *what, const std::string &expected, std::vector<double> *values, std::string *error) {
  values->reserve(reserve_for(count * n));
  for (long long c = 0; c < count * n; ++c) {
    const long long j = c / n, q = c % n;
    double v;
    if (!tok.next())
      return ended(tok, name,
                   "truncated file: it ends inside " + std::string(what) + " " + std::to_string(j) + " (" + expected +
                       ")", error);
    if (!tok.real(&v))
      return fail(error, name, at_line(tok.line()) + what + " " + std::to_string(j) + ": " + names[q] +
                                   " must be a finite number, got " + tok.quoted());
    values->push_back(v);
  }
  return true;
}

// At most one observation per (point, camera): sba has one slot per pair.
bool check_no_repeats(const Problem &p, const std::vector<long long> &obs_line, const std::string &name,
                      std::string *error) {
  std::vector<int> idx(p.observations.size());
  std::iota(idx.begin(), idx.end(), 0);
  const auto &obs = p.observations;
  std::stable_sort(idx.begin(), idx.end(), [&](int a, int b) {
    return obs[a].point != obs[b].point ? obs[a].point < obs[b].point : obs[a].camera < obs[b].camera;
  });
  for (std::size_t k = 1; k < idx.size(); ++k) {
    const Observation &a = obs[idx[k - 1]], &b = obs[idx[k]];
    if (a.point == b.point && a.camera == b.camera)
      return fail(error, name, at_line(obs_line[idx[k]]) + "observation " + std::to_string(idx[k]) +
                                   " repeats point " + std::to_string(b.point) + " in camera " +
                                   std::to_string(b.camera) + " (already observation " +
                                   std::to_string(idx[k - 1]) + ")");
  }
  return true;
}

bool parse(Tokens &tok, const std::string &name, Problem *out, std::string *error) {
  long long counts[3];
  if (!parse_header(tok, name, counts, error)) return false;
  Problem p;
  p.ncameras = static_cast<int>(counts[0]);
  p.npoints = static_cast<int>(counts[1]);
  const long long nobs = counts[2];
  const std::string expected = "expected " + std::to_string(nobs) + " observations, " +
                               std::to_string(p.ncameras) + " cameras and " + std::to_string(p.npoints) + " points";
  std::vector<long long> obs_line;
  if (!parse_observations(tok, name, nobs, expected, &p, &obs_line, error) ||
      !parse_values(tok, name, p.ncameras, kCameraParams, kCameraParamNames, "camera", expected, &p.cameras,
                    error) ||
      !parse_values(tok, name, p.npoints, kPointParams, kPointParamNames, "point", expected, &p.points, error))
    return false;
  // Reading stops at the first value beyond the announced ones: whatever follows (a
  // decompression bomb, a second problem) is not read.
  if (tok.next())
    return fail(error, name, at_line(tok.line()) + "more data than the header announces (" +
                                 std::to_string(nobs) + " observations, " + std::to_string(p.ncameras) +
                                 " cameras, " + std::to_string(p.npoints) + " points): " + tok.quoted() +
                                 " after the last point");
  if (tok.failed()) return fail(error, name, tok.error());
  if (!check_no_repeats(p, obs_line, name, error)) return false;
  *out = std::move(p);
  return true;
}

// A bzip2 block checks its CRC only after all its output has been delivered, so a damaged
// block can hand the parser garbage before the decompressor notices. One block decompresses
// to at most 900,000 bytes of run-length code in which 5 bytes stand for up to 255, about
// 46 MB: reading that much past a parse error reaches the check of the block it came from.
constexpr std::size_t kBzip2BlockOutputMax = std::size_t(48) << 20;

}  // namespace

bool parse_problem(const std::string &text, const std::string &name, Problem *out,
                   std::string *error) {
  StringSource source(text);
  Tokens tok(&source);
  return parse(tok, name, out, error);
}

bool read_problem(const std::string &path, Problem *out, std::string *error) {
  File f(std::fopen(path.c_str(), "rb"));
  if (!f) return fail(error, path, std::string("cannot open: ") + std::strerror(errno));
  // The magic bytes are read once and handed on, not rewound over: a pipe cannot rewind.
  char magic[3];
  const std::string head(magic, std::fread(magic, 1, sizeof magic, f.get()));
  if (head != "BZh") {
    PlainSource source(f.get(), head);
    Tokens tok(&source);
    return parse(tok, path, out, error);
  }
  Bzip2Source source(f.get(), head);
  Tokens tok(&source);
  if (parse(tok, path, out, error)) return true;
  if (source.error().empty()) {
    // A parse error in compressed data: if the block it came from is damaged, say that.
    std::vector<char> buf(1 << 16);
    for (std::size_t seen = 0; seen < kBzip2BlockOutputMax;) {
      const std::size_t got = source.read(buf.data(), buf.size());
      if (got == 0) break;
      seen += got;
    }
    if (!source.error().empty()) fail(error, path, source.error());
  }
  return false;
}

bool to_sba(const Problem &problem, const std::string &name, SbaLayout *out, std::string *error) {
  const int n = problem.npoints, m = problem.ncameras;
  const auto &obs = problem.observations;
  SbaLayout s;
  s.n = n;
  s.m = m;
  s.order.resize(obs.size());
  std::iota(s.order.begin(), s.order.end(), 0);
  std::stable_sort(s.order.begin(), s.order.end(), [&](int a, int b) {
    return obs[a].point != obs[b].point ? obs[a].point < obs[b].point : obs[a].camera < obs[b].camera;
  });
  s.vis.point.reserve(obs.size());
  s.vis.camera.reserve(obs.size());
  s.x.resize(2 * obs.size());
  for (std::size_t k = 0; k < s.order.size(); ++k) {
    const Observation &o = obs[s.order[k]];
    if (o.camera < 0 || o.camera >= m || o.point < 0 || o.point >= n)
      return fail(error, name, "observation " + std::to_string(s.order[k]) + " has an index out of range");
    // Sorted, a repeated pair follows its first.
    if (k > 0 && s.vis.point.back() == o.point && s.vis.camera.back() == o.camera)
      return fail(error, name, "observation " + std::to_string(s.order[k]) + " repeats point " +
                                   std::to_string(o.point) + " in camera " + std::to_string(o.camera));
    s.vis.add(o.point, o.camera);
    s.x[2 * k] = o.x;
    s.x[2 * k + 1] = o.y;
  }
  s.p.reserve(problem.cameras.size() + problem.points.size());
  s.p = problem.cameras;
  s.p.insert(s.p.end(), problem.points.begin(), problem.points.end());
  *out = std::move(s);
  return true;
}

void from_sba_params(const double *p, Problem *problem) {
  std::copy(p, p + problem->cameras.size(), problem->cameras.begin());
  std::copy(p + problem->cameras.size(), p + problem->cameras.size() + problem->points.size(),
            problem->points.begin());
}

namespace {

void append_number(std::string *s, double v) {
  char buf[40];
  const int len = std::snprintf(buf, sizeof buf, "%.17g\n", v);
  s->append(buf, static_cast<std::size_t>(len));
}

bool ends_with(const std::string &s, const char *suffix) {
  const std::size_t k = std::strlen(suffix);
  return s.size() >= k && s.compare(s.size() - k, k, suffix) == 0;
}

}  // namespace

bool write_problem(const std::string &path, const Problem &problem, std::string *error, OutputSet *outputs) {
  std::string text;
  text.reserve(64 * (problem.observations.size() + problem.cameras.size() + problem.points.size()) + 64);
  char buf[120];
  int len = std::snprintf(buf, sizeof buf, "%d %d %d\n", problem.ncameras, problem.npoints,
                          problem.nobservations());
  text.append(buf, static_cast<std::size_t>(len));
  for (const Observation &o : problem.observations) {
    len = std::snprintf(buf, sizeof buf, "%d %d %.17g %.17g\n", o.camera, o.point, o.x, o.y);
    text.append(buf, static_cast<std::size_t>(len));
  }
  for (double v : problem.cameras) append_number(&text, v);
  for (double v : problem.points) append_number(&text, v);

  // Written under a temporary name and renamed: the result appears whole or not at all.
  SetFile out(outputs);
  std::string why;
  if (!out.open(path, &why)) return fail(error, path, why);
  std::FILE *f = out.get();
  if (ends_with(path, ".bz2")) {
    int bzerr = BZ_OK;
    BZFILE *bz = BZ2_bzWriteOpen(&bzerr, f, 9, 0, 0);
    if (bzerr == BZ_MEM_ERROR) throw std::bad_alloc();
    if (bzerr != BZ_OK) return fail(error, path, "cannot start bzip2 compression (error " + std::to_string(bzerr) + ")");
    std::size_t done = 0;
    while (bzerr == BZ_OK && done < text.size()) {
      const int chunk = static_cast<int>(std::min<std::size_t>(text.size() - done, 1 << 20));
      BZ2_bzWrite(&bzerr, bz, &text[done], chunk);
      done += static_cast<std::size_t>(chunk);
    }
    const int write_err = bzerr;
    const int write_errno = errno;
    BZ2_bzWriteClose(&bzerr, bz, write_err != BZ_OK, nullptr, nullptr);
    if (bzerr == BZ_IO_ERROR) {
      // A close that meets a stream error returns before libbz2 frees its state; once the
      // error flag is cleared, a second close that abandons the data frees it.
      const int close_errno = errno;
      std::clearerr(f);
      int ignored = BZ_OK;
      BZ2_bzWriteClose(&ignored, bz, 1, nullptr, nullptr);
      errno = close_errno;
    }
    if (write_err != BZ_OK || bzerr != BZ_OK) {
      errno = write_err != BZ_OK ? write_errno : errno;
      return fail(error, path, std::string("write error: ") + std::strerror(errno));
    }
  } else if (std::fwrite(text.data(), 1, text.size(), f) != text.size()) {
    return fail(error, path, std::string("write error: ") + std::strerror(errno));
  }
  if (!out.close(&why)) return fail(error, path, why);
  return true;
}

}  // namespace sbaformats::bal
