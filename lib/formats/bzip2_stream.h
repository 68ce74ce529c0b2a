/* SPDX-License-Identifier: BSD-3-Clause */
// Reading a bzip2-compressed file through stdio, so that a reader written for plain text
// (eucsbademo's line reader) reads compressed files unchanged.
#ifndef SBA_LIB_FORMATS_BZIP2_STREAM_H
#define SBA_LIB_FORMATS_BZIP2_STREAM_H

#include <cstdio>
#include <string>

namespace sbaformats {

// True when the next bytes of f are bzip2's magic "BZh"; f is left where it was (it must be
// seekable).
bool is_bzip2(std::FILE *f);

// A read-only stream of the decompressed contents of compressed, every bzip2 stream in it one
// after the other (as pbzip2 writes them). The stream owns compressed and closes it when it is
// closed. When the compressed data are damaged, reading fails (ferror) and *error, which must
// outlive the stream, says why. Null if the stream cannot be made (compressed is then closed).
std::FILE *open_bzip2_stream(std::FILE *compressed, std::string *error);

}  // namespace sbaformats

#endif  // SBA_LIB_FORMATS_BZIP2_STREAM_H
