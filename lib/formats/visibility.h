/* SPDX-License-Identifier: BSD-3-Clause */
// Which camera sees which point, as the visible (point, camera) pairs in the order of the
// measurements (point by point, cameras ascending): what sba's _vis entry points take
// (sba_ext.h). Its memory follows the observations, where the dense n*m vmask of the 1.6
// entry points follows cameras times points and does not fit a large sparse model.
#ifndef SBA_LIB_FORMATS_VISIBILITY_H
#define SBA_LIB_FORMATS_VISIBILITY_H

#include <cstddef>
#include <vector>

namespace sbaformats {

struct Visibility {
  std::vector<int> point, camera;  // of measurement k

  void add(int i, int j) {
    point.push_back(i);
    camera.push_back(j);
  }
  std::size_t size() const { return point.size(); }
  bool empty() const { return point.empty(); }
  // The same as the dense vmask of n points and m cameras that the 1.6 entry points take.
  std::vector<char> vmask(int n, int m) const {
    std::vector<char> v(static_cast<std::size_t>(n) * static_cast<std::size_t>(m), 0);
    for (std::size_t k = 0; k < size(); ++k)
      v[static_cast<std::size_t>(point[k]) * static_cast<std::size_t>(m) + static_cast<std::size_t>(camera[k])] = 1;
    return v;
  }
};

}  // namespace sbaformats

#endif  // SBA_LIB_FORMATS_VISIBILITY_H
