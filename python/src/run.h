/* SPDX-License-Identifier: BSD-3-Clause */
// One run of an expert driver from Python, whatever the camera model: the observations,
// the parameter vector, the callbacks, and what the run reports back.
#ifndef PYSBA_RUN_H
#define PYSBA_RUN_H

#include <vector>

#include "arrays.h"
#include "formats/colmap_problem.h"
#include "session.h"

namespace pysba {

// What p holds, as in sba's three driver families.
enum class Refine { MotStr, Mot, Str };

using ExpertFn = void (*)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *out,
                          void *adata);

struct Run {
  Refine refine = Refine::MotStr;
  Observations obs;
  std::vector<double> p;  // refined in place
  int cnp = 0, pnp = 0;
  ExpertFn func = nullptr, fjac = nullptr;  // fjac null: finite differences
  void *adata = nullptr;
  bool parallel = false;  // the callbacks may run on several threads at once
  // A COLMAP problem's priors (refine_colmap), in place of SolveOptions' Python ones; null: none.
  const sbaformats::colmap::ProblemPriors *colmap_priors = nullptr;
};

// Runs the driver of run.refine with the GIL released and returns the session's report.
// With o.covariance (motion and structure only), the covariance blocks of every camera and
// point at the result follow in the report ("camera_covariance", "point_covariance",
// "sigma2", "rank", "nfree"), or "covariance_error" says why there are none.
py::dict run_driver(Run &run, Session &session, const SolveOptions &o);

}  // namespace pysba

#endif  // PYSBA_RUN_H
