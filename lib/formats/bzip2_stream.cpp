// SPDX-License-Identifier: BSD-3-Clause
#include "formats/bzip2_stream.h"

#include <bzlib.h>
#include <sys/types.h>

#include <cerrno>
#include <climits>
#include <cstring>
#include <new>
#include <vector>

namespace sbaformats {

namespace {

struct Bzip2Cookie {
  std::FILE *f = nullptr;
  BZFILE *bz = nullptr;
  std::vector<char> unused;  // bytes read past one stream's end: the next stream's start
  bool done = false;
  std::string *error = nullptr;

  void close_stream() {
    if (!bz) return;
    int ignored;
    BZ2_bzReadClose(&ignored, bz);
    bz = nullptr;
  }
  ssize_t fail(const std::string &why) {
    close_stream();
    *error = why;
    errno = EIO;
    return -1;
  }
};

const char *bz_message(int bzerr) {
  switch (bzerr) {
    case BZ_DATA_ERROR: return "damaged bzip2 data";
    case BZ_DATA_ERROR_MAGIC: return "not bzip2 data where a bzip2 stream should follow";
    case BZ_UNEXPECTED_EOF: return "the bzip2 data end too early (truncated file)";
    case BZ_IO_ERROR: return "read error";
    default: return "bzip2 error";
  }
}

ssize_t read_bzip2(void *cookie, char *buf, std::size_t n) {
  auto *c = static_cast<Bzip2Cookie *>(cookie);
  while (!c->done) {
    int bzerr = BZ_OK;
    if (!c->bz) {
      c->bz = BZ2_bzReadOpen(&bzerr, c->f, 0, 0, c->unused.empty() ? nullptr : c->unused.data(),
                             static_cast<int>(c->unused.size()));
      if (bzerr != BZ_OK) return c->fail(bzerr == BZ_MEM_ERROR ? "out of memory" : bz_message(bzerr));
    }
    const int got = BZ2_bzRead(&bzerr, c->bz, buf, static_cast<int>(n < INT_MAX ? n : INT_MAX));
    if (bzerr == BZ_STREAM_END) {
      void *rest = nullptr;
      int nrest = 0;
      BZ2_bzReadGetUnused(&bzerr, c->bz, &rest, &nrest);
      c->unused.assign(static_cast<char *>(rest), static_cast<char *>(rest) + nrest);
      c->close_stream();
      if (c->unused.empty()) {
        // Another stream may follow in the part of the file not read yet.
        const int ch = std::fgetc(c->f);
        if (ch != EOF) c->unused.push_back(static_cast<char>(ch));
        else if (std::ferror(c->f)) return c->fail(std::string("read error: ") + std::strerror(errno));
        else c->done = true;
      }
      if (got > 0) return got;
      continue;
    }
    if (bzerr != BZ_OK) return c->fail(bzerr == BZ_MEM_ERROR ? "out of memory" : bz_message(bzerr));
    if (got > 0) return got;
  }
  return 0;
}

int close_bzip2(void *cookie) {
  auto *c = static_cast<Bzip2Cookie *>(cookie);
  c->close_stream();
  std::fclose(c->f);
  delete c;
  return 0;
}

}  // namespace

bool is_bzip2(std::FILE *f) {
  const long at = std::ftell(f);
  char magic[3] = {0, 0, 0};
  const std::size_t n = std::fread(magic, 1, 3, f);
  std::clearerr(f);
  if (at < 0 || std::fseek(f, at, SEEK_SET) != 0) return false;
  return n == 3 && magic[0] == 'B' && magic[1] == 'Z' && magic[2] == 'h';
}

std::FILE *open_bzip2_stream(std::FILE *compressed, std::string *error) {
  auto *c = new (std::nothrow) Bzip2Cookie;
  if (!c) {
    std::fclose(compressed);
    return nullptr;
  }
  c->f = compressed;
  c->error = error;
  cookie_io_functions_t io{};
  io.read = read_bzip2;
  io.close = close_bzip2;
  std::FILE *f = fopencookie(c, "r", io);
  if (!f) {
    std::fclose(compressed);
    delete c;
  }
  return f;
}

}  // namespace sbaformats
