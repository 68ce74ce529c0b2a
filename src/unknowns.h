/* SPDX-License-Identifier: BSD-3-Clause */
// What a solve does with the unknowns of the Layout's CameraMap (camera_map.h) on p itself:
// counts them, and ties the copies of a shared parameter together (and undoes that).
#ifndef SBA_SRC_UNKNOWNS_H
#define SBA_SRC_UNKNOWNS_H

#include <vector>

#include "layout.h"

namespace sba {

// The unknowns a solve of lay has: its free parameters less the held ones, a shared one
// counted once.
i64 count_unknowns(const Layout &lay);

// The shared parameters' copies in p set to the value of their first camera (the one of
// least index); returns the values they replaced, for restore_copies.
std::vector<double> tie_copies(const Layout &lay, double *p);
// p's copies as they were before tie_copies returned given.
void restore_copies(const Layout &lay, double *p, const std::vector<double> &given);

}  // namespace sba

#endif
