/* SPDX-License-Identifier: BSD-3-Clause */
// The values of a whitespace-separated text file (Bundler's bundle.out, VisualSFM's NVM), one
// at a time with the line each is on, and the strict conversions their readers share: a
// number must be the whole token, decimal and finite, an integer must lie in its range.
// Errors are one line, "<file>:<line>: <message>", and never echo a control byte.
#ifndef SBA_LIB_FORMATS_TEXT_TOKENS_H
#define SBA_LIB_FORMATS_TEXT_TOKENS_H

#include <cctype>
#include <charconv>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>
#include <system_error>

namespace sbaformats {

// strtod for the text readers of every program: *out is the value of tok when the whole of it
// is a number, NaN and Inf included (the readers refuse those by name). A hexadecimal float
// (0x1p10) is not taken: no program writes these formats with one, and a file that holds one
// would read as other numbers elsewhere. Neither is a leading blank, which strtod skips.
inline bool decimal_number(const std::string &tok, double *out) {
  const std::size_t k = !tok.empty() && (tok[0] == '+' || tok[0] == '-') ? 1 : 0;
  if (k >= tok.size() || std::isspace(static_cast<unsigned char>(tok[0]))) return false;
  if (tok[k] == '0' && k + 1 < tok.size() && (tok[k + 1] == 'x' || tok[k + 1] == 'X')) return false;
  char *end = nullptr;
  *out = std::strtod(tok.c_str(), &end);
  return end == tok.c_str() + tok.size();
}

// The same for a token inside a larger text, read where it lies (strtod needs a terminated
// copy). std::from_chars reads what it accepts to the same double as strtod (both round
// correctly), and faster: a model holds millions of numbers (bench/colmap_io.sh). What it
// refuses (a leading '+', a value that overflows or underflows, anything malformed) goes
// through the strtod above, so that both overloads accept and refuse the same tokens.
inline bool decimal_number(std::string_view tok, double *out) {
  if (!tok.empty() && tok[0] != '+') {
    double v;
    const std::from_chars_result r = std::from_chars(tok.data(), tok.data() + tok.size(), v);
    if (r.ec == std::errc() && r.ptr == tok.data() + tok.size()) {
      *out = v;
      return true;
    }
  }
  return decimal_number(std::string(tok), out);
}
class TextTokens {
 public:
  // The tokens of text from pos on, pos being on line `line`; name stands for the file. Until
  // a token is read, an early end is reported at the line before (a header's).
  TextTokens(const std::string &text, const std::string &name, std::size_t pos, int line)
      : text_(text), name_(name), pos_(pos), line_(line), last_line_(line > 1 ? line - 1 : line) {}

  // The next token; false at the end of the text.
  bool next(std::string *tok) {
    while (pos_ < text_.size() && is_space(text_[pos_])) {
      if (text_[pos_] == '\n') ++line_;
      ++pos_;
    }
    if (pos_ >= text_.size()) return false;
    const std::size_t b = pos_;
    while (pos_ < text_.size() && !is_space(text_[pos_])) ++pos_;
    tok->assign(text_, b, pos_ - b);
    last_line_ = line_;
    return true;
  }
  // Just after the last token read.
  std::size_t pos() const { return pos_; }
  std::string where() const { return name_ + ":" + std::to_string(line_) + ": "; }
  // The end of the file, at the line of the last value.
  std::string ends_before(const std::string &what) const {
    return name_ + ":" + std::to_string(last_line_) + ": the file ends before " + what;
  }

  bool real(const std::string &what, double *out, std::string *error) {
    std::string tok;
    if (!next(&tok)) return fail(error, ends_before(what));
    double v;
    if (!decimal_number(tok, &v) || !std::isfinite(v))
      return fail(error, where() + what + " must be a finite number, got '" + printable(tok) + "'");
    *out = v;
    return true;
  }
  bool integer(const std::string &what, long long lo, long long hi, long long *out, std::string *error) {
    std::string tok;
    if (!next(&tok)) return fail(error, ends_before(what));
    bool digits = !tok.empty() && tok.size() <= 18;
    for (std::size_t k = tok[0] == '-' ? 1 : 0; digits && k < tok.size(); ++k) digits = tok[k] >= '0' && tok[k] <= '9';
    if (!digits || tok == "-") return fail(error, where() + what + " must be an integer, got '" + printable(tok) + "'");
    const long long v = std::strtoll(tok.c_str(), nullptr, 10);
    if (v < lo || v > hi)
      return fail(error, where() + what + " is " + std::to_string(v) + ", expected " + std::to_string(lo) + ".." +
                             std::to_string(hi));
    *out = v;
    return true;
  }

  // At most 40 characters of s, control and non-ASCII bytes as '?'.
  static std::string printable(const std::string &s) {
    std::string out;
    for (char c : s) {
      if (out.size() >= 40) return out + "...";
      out += (c >= 32 && c < 127) ? c : '?';
    }
    return out;
  }
  static bool fail(std::string *error, const std::string &msg) {
    if (error) *error = msg;
    return false;
  }

 private:
  static bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; }

  const std::string &text_;
  const std::string &name_;
  std::size_t pos_;
  int line_;
  int last_line_;
};

// 17 significant digits: the text reads back to the same double. std::to_chars with a
// precision is specified as printf's %.17g, the text these files have always held, and is
// faster than snprintf (bench/colmap_io.sh; tests/test_colmap_text_numbers.cpp checks that
// the two agree).
inline std::size_t g17(double v, char (&buf)[32]) {
  const std::to_chars_result r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::general, 17);
  return static_cast<std::size_t>(r.ptr - buf);
}
inline std::string g17(double v) {
  char buf[32];
  return std::string(buf, g17(v, buf));
}
// g17(v) appended to *out.
inline void append_g17(std::string *out, double v) {
  char buf[32];
  out->append(buf, g17(v, buf));
}
// An unsigned integer in decimal appended to *out.
inline void append_uint(std::string *out, unsigned long long v) {
  char buf[24];
  const std::to_chars_result r = std::to_chars(buf, buf + sizeof buf, v);
  out->append(buf, static_cast<std::size_t>(r.ptr - buf));
}

}  // namespace sbaformats

#endif  // SBA_LIB_FORMATS_TEXT_TOKENS_H
