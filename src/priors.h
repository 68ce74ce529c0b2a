/* SPDX-License-Identifier: BSD-3-Clause */
// Priors: residual blocks beside the projections, each on one camera's parameters or one
// point's, weighted by its own square-root information and with its own robust loss
// (sba_ext.h, docs/priors.md). They enter a solve at two places only: their cost is added to
// the projections' wherever the loop evaluates a point, and their blocks are added to U_j,
// e_a,j and V_i, e_b,i where the normal equations are formed (lm_core.cpp). Everything
// above that sees one cost and one set of normal equations.
#ifndef SBA_SRC_PRIORS_H
#define SBA_SRC_PRIORS_H

#include <string>
#include <vector>

#include "camera_unknowns.h"
#include "layout.h"
#include "log.h"
#include "loss.h"
#include "sba_export.h"

namespace sba {

// The caller's arrays as sba_ext_options gives them, valid for the call.
struct PriorOptions {
  int ncamera = 0;
  const sba_camera_prior *camera = nullptr;
  int nlinear = 0;
  const sba_camera_linear_prior *linear = nullptr;
  int npoint = 0;
  const sba_point_prior *point = nullptr;
  bool any() const { return ncamera > 0 || nlinear > 0 || npoint > 0; }
  // The residual entries of the priors (checked ones): measurements beside the projections'.
  i64 rows(const Layout &lay) const;
};

// What is wrong with the priors for this problem and its held camera parameters (empty:
// nothing), naming the first prior at fault, e.g. "point prior 3 (point 17): mean[1] is not
// finite".
std::string check_priors(const PriorOptions &o, const Layout &lay, const CameraParamOptions &cams);

// The priors' share of a cost: sum rho(s) and sum s over the priors, s = ||L r||^2.
struct PriorCost {
  double cost = 0, sq = 0;
};

// The checked priors of a solve, ready to evaluate: means copied, weights turned into their
// upper-triangular square-root information, losses made. Evaluated on the calling thread, in
// the order given, so that every thread count adds the same terms in the same order.
class PriorTerms {
 public:
  PriorTerms(const PriorOptions &o, const Layout &lay);
  bool empty() const { return terms_.empty(); }
  // The priors' cost at p; false (said through log, with where) if a residual is not finite.
  bool cost(const double *p, const Logger &log, const char *where, PriorCost *c) const;
  // Each prior's L J^T L J into its camera's U_j and -(L J)^T L r into e_a,j (held columns
  // zeroed), or into its point's V_i and e_b,i, reweighted by its loss as the projections are
  // (sqrt(rho'(s))). Returns the squared norm of the reweighted residuals.
  double add_normal_equations(const double *p, double *U, double *V, double *ea, double *eb) const;
  // The callback priors' analytic Jacobians against central differences of their residuals:
  // every suspicious entry and a verdict through log. Returns the number of suspicious rows.
  i64 check_jacobians(const double *p, const Logger &log) const;

 private:
  enum class Kind { Camera, Linear, Point };
  struct Term {
    Kind kind = Kind::Point;
    int index = 0;   // in its array of sba_ext_options
    int target = 0;  // camera or point
    int dim = 0;
    std::vector<int> params;    // linear: the camera parameters constrained
    std::vector<double> mean;   // linear and point
    const sba_camera_prior *cb = nullptr;
    std::vector<double> L;      // dim x dim, upper triangular
    Loss loss;
  };
  int width(const Term &t) const { return t.kind == Kind::Point ? lay_.pnp : lay_.cnp; }
  const double *block(const Term &t, const double *p) const {
    return p + (t.kind == Kind::Point ? lay_.b_off(t.target) : lay_.a_off(t.target));
  }
  void residual(const Term &t, const double *p, double *r) const;
  void jacobian(const Term &t, const double *p, double *J) const;
  void weigh(const Term &t, const double *r, double *y) const;
  double add_term(const Term &t, const double *p, double *G, double *g) const;
  i64 check_term(const Term &t, const double *p, const Logger &log, i64 *rows) const;

  const Layout &lay_;
  std::vector<Term> terms_;
};

}  // namespace sba

#endif
