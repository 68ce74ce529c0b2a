/* SPDX-License-Identifier: BSD-3-Clause */
// The library's structs over the priors of a solve (priors.h), with the callbacks of the camera
// priors calling Python.
#ifndef PYSBA_PRIOR_CALLBACKS_H
#define PYSBA_PRIOR_CALLBACKS_H

#include <vector>

#include "priors.h"
#include "sba_ext.h"
#include "session.h"

namespace pysba {

// The library's structs over a Priors, pointing into it (which must outlive them), with the
// callbacks of the camera priors calling Python through the session: the GIL taken, an
// exception kept and the residual made NaN, as for the projections (session.h).
class PriorStructs {
 public:
  // Sets the prior fields of *ext; cnp: the camera parameters the callbacks get.
  void attach(const Priors &p, Session &session, int cnp, sba_ext_options *ext);

  // What a camera prior's callbacks receive as data.
  struct Call {
    Session *session;
    const PriorSpec *spec;
    int cnp;
  };

 private:
  std::vector<Call> calls_;
  std::vector<sba_camera_prior> camera_;
  std::vector<sba_camera_linear_prior> linear_;
  std::vector<sba_point_prior> point_;
};

}  // namespace pysba

#endif  // PYSBA_PRIOR_CALLBACKS_H
