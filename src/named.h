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

template <class Row, std::size_t N>
std::string joined_names(const Row (&rows)[N]) {
  std::string all;
  for (const Row &r : rows) all += (all.empty() ? "" : " ") + std::string(r.name);
  return all;
}

}  // namespace sba

#endif
