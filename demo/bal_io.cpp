#include "bal_io.h"

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

#include "output_file.h"

namespace bal {
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

bool read_plain(std::FILE *f, const std::string &path, std::string *text, std::string *error) {
  char buf[1 << 16];
  for (;;) {
    const std::size_t got = std::fread(buf, 1, sizeof buf, f);
    text->append(buf, got);
    if (got < sizeof buf) break;
  }
  if (std::ferror(f)) return fail(error, path, std::string("read error: ") + std::strerror(errno));
  return true;
}

std::string bz_message(int code) {
  switch (code) {
    case BZ_DATA_ERROR: return "corrupt bzip2 data";
    case BZ_DATA_ERROR_MAGIC: return "data after the end of the bzip2 stream is not bzip2";
    case BZ_UNEXPECTED_EOF: return "truncated bzip2 file (the compressed stream ends early)";
    case BZ_IO_ERROR: return std::string("read error: ") + std::strerror(errno);
    default: return "bzip2 error " + std::to_string(code);
  }
}

// Decompresses every bzip2 stream in f, one after the other.
bool read_bzip2(std::FILE *f, const std::string &path, std::string *text, std::string *error) {
  std::vector<char> unused;  // bytes read past the end of one stream: the next one's start
  char buf[1 << 16];
  for (;;) {
    int bzerr = BZ_OK;
    BZFILE *bz = BZ2_bzReadOpen(&bzerr, f, 0, 0, unused.empty() ? nullptr : unused.data(),
                                static_cast<int>(unused.size()));
    if (bzerr == BZ_MEM_ERROR) throw std::bad_alloc();
    if (bzerr != BZ_OK) {
      BZ2_bzReadClose(&bzerr, bz);
      return fail(error, path, bz_message(bzerr));
    }
    while (bzerr == BZ_OK) {
      const int got = BZ2_bzRead(&bzerr, bz, buf, static_cast<int>(sizeof buf));
      if (bzerr == BZ_OK || bzerr == BZ_STREAM_END) text->append(buf, static_cast<std::size_t>(got));
    }
    if (bzerr != BZ_STREAM_END) {
      int ignored;
      BZ2_bzReadClose(&ignored, bz);
      if (bzerr == BZ_MEM_ERROR) throw std::bad_alloc();
      return fail(error, path, bz_message(bzerr));
    }
    void *rest = nullptr;
    int nrest = 0;
    BZ2_bzReadGetUnused(&bzerr, bz, &rest, &nrest);
    unused.assign(static_cast<char *>(rest), static_cast<char *>(rest) + nrest);
    BZ2_bzReadClose(&bzerr, bz);
    if (unused.empty()) {
      // Another stream may follow in the part of the file not read yet.
      const int c = std::fgetc(f);
      if (c == EOF) break;
      unused.push_back(static_cast<char>(c));
    }
  }
  if (std::ferror(f)) return fail(error, path, std::string("read error: ") + std::strerror(errno));
  return true;
}

// ---- the tokenizer ----

bool is_space(char c) {
  return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f';
}

class Tokens {
 public:
  explicit Tokens(const std::string &text) : p_(text.c_str()), end_(text.c_str() + text.size()) {}

  // The next token, or false at the end of the text.
  bool next() {
    while (p_ < end_ && is_space(*p_)) {
      if (*p_ == '\n') ++line_;
      ++p_;
    }
    if (p_ == end_) return false;
    tok_ = p_;
    while (p_ < end_ && !is_space(*p_)) ++p_;
    tok_len_ = static_cast<std::size_t>(p_ - tok_);
    tok_line_ = line_;
    return true;
  }

  int line() const { return tok_line_; }
  // The current token for messages, cut to a readable length.
  std::string quoted() const {
    std::string s(tok_, std::min<std::size_t>(tok_len_, 40));
    for (char &c : s)
      if (static_cast<unsigned char>(c) < 32 || static_cast<unsigned char>(c) > 126) c = '?';
    if (tok_len_ > 40) s += "...";
    return "'" + s + "'";
  }

  // The current token as an integer written as one (optional sign, digits).
  bool integer(long long *v) const {
    std::size_t k = (tok_[0] == '-' || tok_[0] == '+') ? 1 : 0;
    if (k == tok_len_) return false;
    for (std::size_t i = k; i < tok_len_; ++i)
      if (tok_[i] < '0' || tok_[i] > '9') return false;
    if (tok_len_ - k > 18) return false;  // beyond any count we accept; avoids overflow
    errno = 0;
    char *stop = nullptr;
    *v = std::strtoll(tok_, &stop, 10);
    return errno == 0 && stop == tok_ + tok_len_;
  }

  // The current token as a finite real number; the whole token must be the number.
  bool real(double *v) const {
    char *stop = nullptr;
    *v = std::strtod(tok_, &stop);
    return stop == tok_ + tok_len_ && std::isfinite(*v);
  }

 private:
  const char *p_, *end_;
  const char *tok_ = nullptr;
  std::size_t tok_len_ = 0;
  int line_ = 1, tok_line_ = 1;
};

std::string at_line(int line) { return "line " + std::to_string(line) + ": "; }

const char *const kCameraParamNames[kCameraParams] = {"w1", "w2", "w3", "t1", "t2", "t3", "f", "k1", "k2"};
const char *const kPointParamNames[kPointParams] = {"X", "Y", "Z"};

}  // namespace

bool parse_problem(const std::string &text, const std::string &name, Problem *out,
                   std::string *error) {
  Tokens tok(text);
  const char *const header_names[3] = {"number of cameras", "number of points",
                                       "number of observations"};
  long long counts[3];
  for (int c = 0; c < 3; ++c) {
    if (!tok.next()) {
      if (c == 0) return fail(error, name, "empty file: expected the header 'ncameras npoints nobservations'");
      return fail(error, name, "truncated file: the header 'ncameras npoints nobservations' is incomplete");
    }
    if (!tok.integer(&counts[c]))
      return fail(error, name, at_line(tok.line()) + std::string("header: the ") + header_names[c] +
                                   " must be an integer, got " + tok.quoted());
    if (counts[c] <= 0 || counts[c] > INT_MAX)
      return fail(error, name, at_line(tok.line()) + std::string("header: the ") + header_names[c] +
                                   " must be between 1 and " + std::to_string(INT_MAX) + ", got " +
                                   std::to_string(counts[c]));
  }
  const int ncams = static_cast<int>(counts[0]), npts = static_cast<int>(counts[1]);
  const long long nobs = counts[2];
  if (nobs > counts[0] * counts[1])
    return fail(error, name, "header: " + std::to_string(nobs) + " observations but only " +
                                 std::to_string(counts[0] * counts[1]) +
                                 " camera-point pairs (each pair is observed at most once)");

  const std::string expected = "expected " + std::to_string(nobs) + " observations, " +
                               std::to_string(ncams) + " cameras and " + std::to_string(npts) + " points";
  // Storage grows as values arrive, reserved up to what the text can hold (every value takes
  // at least two bytes), so a header announcing more than the file has cannot exhaust memory.
  const std::size_t room = text.size() / 2 + 1;
  auto capped = [room](long long values) { return std::min<std::size_t>(static_cast<std::size_t>(values), room); };
  Problem p;
  p.ncameras = ncams;
  p.npoints = npts;
  p.observations.reserve(capped(nobs) / 4 + 1);
  std::vector<int> obs_line;
  obs_line.reserve(capped(nobs) / 4 + 1);
  for (long long k = 0; k < nobs; ++k) {
    Observation o;
    auto what = [k] { return "observation " + std::to_string(k) + ": "; };
    const char *const fields[4] = {"camera index", "point index", "x", "y"};
    for (int f = 0; f < 4; ++f) {
      if (!tok.next())
        return fail(error, name, "truncated file: it ends inside observation " + std::to_string(k) +
                                     " (" + expected + ")");
      if (f < 2) {
        long long v;
        if (!tok.integer(&v))
          return fail(error, name, at_line(tok.line()) + what() + "the " + fields[f] +
                                       " must be an integer, got " + tok.quoted());
        const int limit = f == 0 ? ncams : npts;
        if (v < 0 || v >= limit)
          return fail(error, name, at_line(tok.line()) + what() + "the " + fields[f] + " " +
                                       std::to_string(v) + " is out of range 0.." + std::to_string(limit - 1));
        (f == 0 ? o.camera : o.point) = static_cast<int>(v);
        if (f == 0) obs_line.push_back(tok.line());
      } else {
        double v;
        if (!tok.real(&v))
          return fail(error, name, at_line(tok.line()) + what() + fields[f] +
                                       " must be a finite number, got " + tok.quoted());
        (f == 2 ? o.x : o.y) = v;
      }
    }
    p.observations.push_back(o);
  }

  const long long ncamvals = 9LL * ncams, nptvals = 3LL * npts;
  p.cameras.reserve(capped(ncamvals));
  for (long long c = 0; c < ncamvals; ++c) {
    const long long j = c / kCameraParams, q = c % kCameraParams;
    double v;
    if (!tok.next())
      return fail(error, name, "truncated file: it ends inside camera " + std::to_string(j) + " (" +
                                   expected + ")");
    if (!tok.real(&v))
      return fail(error, name, at_line(tok.line()) + "camera " + std::to_string(j) + ": " +
                                   kCameraParamNames[q] + " must be a finite number, got " + tok.quoted());
    p.cameras.push_back(v);
  }
  p.points.reserve(capped(nptvals));
  for (long long c = 0; c < nptvals; ++c) {
    const long long i = c / kPointParams, q = c % kPointParams;
    double v;
    if (!tok.next())
      return fail(error, name, "truncated file: it ends inside point " + std::to_string(i) + " (" +
                                   expected + ")");
    if (!tok.real(&v))
      return fail(error, name, at_line(tok.line()) + "point " + std::to_string(i) + ": " +
                                   kPointParamNames[q] + " must be a finite number, got " + tok.quoted());
    p.points.push_back(v);
  }
  if (tok.next())
    return fail(error, name, at_line(tok.line()) + "unexpected data after the last point: " + tok.quoted() +
                                 " (" + expected + ")");

  // At most one observation per (point, camera): sba has one slot per pair.
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

  *out = std::move(p);
  return true;
}

bool read_problem(const std::string &path, Problem *out, std::string *error) {
  File f(std::fopen(path.c_str(), "rb"));
  if (!f) return fail(error, path, std::string("cannot open: ") + std::strerror(errno));
  char magic[3] = {0, 0, 0};
  const std::size_t nmagic = std::fread(magic, 1, 3, f.get());
  std::rewind(f.get());
  const bool bz2 = nmagic == 3 && magic[0] == 'B' && magic[1] == 'Z' && magic[2] == 'h';
  std::string text;
  if (!(bz2 ? read_bzip2(f.get(), path, &text, error) : read_plain(f.get(), path, &text, error)))
    return false;
  f.reset();
  return parse_problem(text, path, out, error);
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
  s.vmask.assign(static_cast<std::size_t>(n) * static_cast<std::size_t>(m), 0);
  s.x.resize(2 * obs.size());
  for (std::size_t k = 0; k < s.order.size(); ++k) {
    const Observation &o = obs[s.order[k]];
    if (o.camera < 0 || o.camera >= m || o.point < 0 || o.point >= n)
      return fail(error, name, "observation " + std::to_string(s.order[k]) + " has an index out of range");
    char &seen = s.vmask[static_cast<std::size_t>(o.point) * m + o.camera];
    if (seen)
      return fail(error, name, "observation " + std::to_string(s.order[k]) + " repeats point " +
                                   std::to_string(o.point) + " in camera " + std::to_string(o.camera));
    seen = 1;
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

bool write_problem(const std::string &path, const Problem &problem, std::string *error) {
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
  sbademo::OutputFile out;
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
    if (write_err != BZ_OK || bzerr != BZ_OK) {
      errno = write_err != BZ_OK ? write_errno : errno;
      return fail(error, path, std::string("write error: ") + std::strerror(errno));
    }
  } else if (std::fwrite(text.data(), 1, text.size(), f) != text.size()) {
    return fail(error, path, std::string("write error: ") + std::strerror(errno));
  }
  if (!out.commit(&why)) return fail(error, path, why);
  return true;
}

}  // namespace bal
