/* SPDX-License-Identifier: BSD-3-Clause */
// Tables of {name, value} rows (the linear solvers, the losses): the lookup by name and the
// names joined by spaces for messages and the C API's lists, both from the one table.
#ifndef SBA_SRC_NAMED_H
#define SBA_SRC_NAMED_H

#include <cstddef>
#include <string>

namespace sba {

template <class Row, std::size_t N, class Value>
bool value_of(const Row (&rows)[N], const std::string &name, Value *out) {
  for (const Row &r : rows)
    if (name == r.name) {
      *out = r.value;
      return true;
    }
  return false;
}

// The names joined by single spaces, made at compile time: a list the C API hands out must
// not allocate (a first call inside a caller's solve would look like a leak, and no static
// may be built at run time).
template <std::size_t L>
struct JoinedNames {
  char text[L];
};

template <class Row, std::size_t N>
constexpr std::size_t joined_length(const Row (&rows)[N]) {
  std::size_t len = 0;
  for (const Row &r : rows) {
    for (const char *c = r.name; *c; ++c) ++len;
    ++len;  // the space after it, or the terminating zero after the last
  }
  return len;
}

template <std::size_t L, class Row, std::size_t N>
constexpr JoinedNames<L> joined_names(const Row (&rows)[N]) {
  JoinedNames<L> out{};
  std::size_t k = 0;
  for (const Row &r : rows) {
    if (k > 0) out.text[k++] = ' ';
    for (const char *c = r.name; *c; ++c) out.text[k++] = *c;
  }
  out.text[k] = '\0';
  return out;
}

}  // namespace sba

#endif
