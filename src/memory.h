/* SPDX-License-Identifier: BSD-3-Clause */
// Large buffers whose pages are mapped in one system call rather than fault by fault.
#ifndef SBA_SRC_MEMORY_H
#define SBA_SRC_MEMORY_H

#include <cstddef>
#include <vector>

namespace sba {

// Maps the pages of [p, p + bytes) for writing now, where the system can (Linux 5.14 and
// later); elsewhere, or if it refuses, the pages are mapped as they are first written, as
// they would be anyway. A solve touches its Jacobian and work arrays first while zeroing
// them: each first touch of a page costs a trap (a slow one on a virtual machine), and one
// madvise call maps the same pages without them.
void prefault(void *p, std::size_t bytes);

// v.resize(n) for an empty v, the pages of a large allocation mapped by prefault first.
void resize_prefaulted(std::vector<double> &v, std::size_t n);
void resize_prefaulted(std::vector<float> &v, std::size_t n);

}  // namespace sba

#endif
