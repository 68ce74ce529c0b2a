// SPDX-License-Identifier: BSD-3-Clause
// Covariance of the solution through the Schur complement: with J^T J = [U W; W^T V],
// (J^T J)^-1 has camera blocks S^-1 (S = U - W V^-1 W^T) and point blocks
// V^-1 + V^-1 W^T S^-1 W V^-1. Only the requested blocks are formed. S of full rank is
// inverted through its Cholesky factor, far less work than an eigendecomposition. A gauge
// that mcon/ncon leave free makes S singular; its pseudo-inverse (from a symmetric
// eigendecomposition) is used and the rank reported. A point block V_i, by contrast, must
// have full rank: a point that its projections do not determine (seen by one camera, or by
// cameras in degenerate positions) is refused by name, since inverting its V_i would turn
// rounding into numbers.
#include "covariance.h"

#include <algorithm>
#include <cfloat>
#include <chrono>
#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include "kernels.h"
#include "lapack.h"
#include "linearization.h"
#include "parallel.h"
#include "unknowns.h"

namespace sba {
namespace {

// Eigenvalues of the symmetric n x n block a (row-major; destroyed) by cyclic Jacobi
// rotations, which are accurate to rounding relative to the largest eigenvalue. lambda gets
// them unordered.
void symmetric_eigenvalues(double *a, int n, double *lambda) {
  for (int sweep = 0; sweep < 64; ++sweep) {
    double off = 0.0, diag = 0.0;
    for (int r = 0; r < n; ++r) {
      diag += a[r * n + r] * a[r * n + r];
      for (int c = r + 1; c < n; ++c) off += a[r * n + c] * a[r * n + c];
    }
    if (!(off > DBL_EPSILON * DBL_EPSILON * 1e-4 * diag)) break;
    for (int p = 0; p < n; ++p)
      for (int q = p + 1; q < n; ++q) {
        const double apq = a[p * n + q];
        if (apq == 0.0) continue;
        // The rotation that zeroes a_pq: t = tan(theta), the smaller root.
        const double theta = (a[q * n + q] - a[p * n + p]) / (2.0 * apq);
        const double t = (theta >= 0 ? 1.0 : -1.0) / (std::fabs(theta) + std::sqrt(theta * theta + 1.0));
        const double c = 1.0 / std::sqrt(t * t + 1.0), s = t * c;
        for (int k = 0; k < n; ++k) {  // columns p, q
          const double akp = a[k * n + p], akq = a[k * n + q];
          a[k * n + p] = c * akp - s * akq;
          a[k * n + q] = s * akp + c * akq;
        }
        for (int k = 0; k < n; ++k) {  // rows p, q
          const double apk = a[p * n + k], aqk = a[q * n + k];
          a[p * n + k] = c * apk - s * aqk;
          a[q * n + k] = s * apk + c * aqk;
        }
      }
  }
  for (int r = 0; r < n; ++r) lambda[r] = a[r * n + r];
}

// The caller's cancel callback, polled at every stage boundary (now = true) and otherwise at
// most every kCancelPoll: the loops poll once per point or column, which on a small problem
// is far more often than a host's check (taking a lock, looking at its signals) is worth.
class Canceller {
 public:
  explicit Canceller(const Options &opt) : fn_(opt.cancel), ctx_(opt.cancel_ctx) {}
  bool stop(const Logger &log, bool now = false) {
    if (!fn_) return false;
    const auto t = std::chrono::steady_clock::now();
    if (!now && t - last_ < kCancelPoll) return false;
    last_ = t;
    if (fn_(ctx_) == 0) return false;
    log.error("sba: stopped by the cancel callback");
    return true;
  }

 private:
  static constexpr std::chrono::milliseconds kCancelPoll{10};
  int (*fn_)(void *);
  void *ctx_;
  std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
};

// Why point i (free, with a V_i of rank < pnp) has no covariance: one line.
std::string undetermined_point(const Layout &lay, int i, int rank) {
  const int seen = lay.rowptr[size_t(i) + 1] - lay.rowptr[size_t(i)];
  const i64 meas = i64(seen) * lay.mnp;
  std::string why;
  if (seen == 0)
    why = "point " + std::to_string(i) + " is seen by no camera";
  else if (meas < lay.pnp)
    why = "point " + std::to_string(i) + " is seen by " +
          (seen == 1 ? std::string("one camera") : std::to_string(seen) + " cameras") +
          " only: its " + std::to_string(lay.pnp) + " parameters are not determined by " +
          std::to_string(meas) + " measurements";
  else
    why = "point " + std::to_string(i) + " is not determined by its " + std::to_string(seen) +
          " projections (cameras in degenerate positions, or projections the loss ignores)";
  return why + " (V_i has rank " + std::to_string(rank) + " < pnp = " + std::to_string(lay.pnp) +
         "): its covariance is unbounded";
}

// Every free point's V_i must have full rank. Testing it before inverting matters: a V_i that
// is singular in exact arithmetic often has a tiny positive rounding pivot, and then its
// "inverse" is rounding noise of 1e10 and more, which also leaks into S and so into every
// other block. False, naming the first point that fails, when one does (or when cancelled).
bool points_determined(const Layout &lay, const double *V, Canceller &cancel, const Logger &log) {
  const int pnp = lay.pnp, pnp2 = pnp * pnp;
  std::vector<double> work;
  for (int i = lay.ncon; i < lay.n && pnp > 0; ++i) {
    if (cancel.stop(log)) return false;
    const int r = block_rank(V + i64(i) * pnp2, pnp, work);
    if (r < pnp) {
      log.error("sba: %s", undetermined_point(lay, i, r).c_str());
      return false;
    }
  }
  return true;
}

// S over the free cameras' parameters (order free cameras x cnp), assembled from the points'
// V_i^-1 and made full and symmetric (row-major).
std::vector<double> parameter_schur(const Layout &lay, ThreadPool &pool, const Kernels &kernels,
                                    const NormalEquations &ne, const double *Vinv) {
  const int nA = lay.free_cams() * lay.cnp;
  std::vector<double> S(size_t(nA) * size_t(nA), 0.0), rhs(static_cast<size_t>(nA));
  BlockMap map;
  map.base = S.data();
  map.ld = nA;
  map.cnp = lay.cnp;
  kernels.assemble(pool, ne, Vinv, 0.0, map, rhs.data());  // with Vinv: cannot fail
  for (int r = 0; r < nA; ++r)
    for (int c = r + 1; c < nA; ++c) S[size_t(c) * nA + r] = S[size_t(r) * nA + c];
  return S;
}

// The cameras' covariance (up to sigma^2) as S^+ over the unknowns holds it: entry (a, b) of
// block (j, k), free cameras j and k; zero for a held parameter. Reading S through the map
// rather than expanding it over every camera's parameters keeps one matrix of S's order.
struct CameraCovariance {
  const double *S;
  const CameraMap &map;
  double operator()(int j, int k, int a, int b) const {
    const int u = map.unknown(j, a), w = map.unknown(k, b);
    return u < 0 || w < 0 ? 0.0 : S[size_t(u) * size_t(map.unknowns()) + size_t(w)];
  }
};

void camera_blocks(const Layout &lay, const CameraCovariance &C, double scale, CovarianceRequest &req) {
  const int cnp = lay.cnp;
  for (int q = 0; q < req.ncams; ++q) {
    const int j = req.cams[q];
    double *out = req.camcov + i64(q) * cnp * cnp;
    for (int a = 0; a < cnp; ++a)
      for (int b = 0; b < cnp; ++b) out[a * cnp + b] = j >= lay.mcon ? scale * C(j, j, a, b) : 0.0;
  }
}

// A point's block V_i^-1 + sum_jk Y_ij^T S^+_jk Y_ik with Y_ij = W_ij V_i^-1 over the free
// cameras j seeing it, scaled by `scale`; its work arrays kept from one point to the next.
class PointBlocks {
 public:
  PointBlocks(const Layout &lay, const NormalEquations &ne, const double *Vinv, const CameraCovariance &C)
      : lay_(lay), ne_(ne), Vinv_(Vinv), C_(C), W_(size_t(lay.cnp) * size_t(lay.pnp)) {}

  void operator()(int i, double scale, double *out) {
    const int cnp = lay_.cnp, pnp = lay_.pnp;
    if (i < lay_.ncon) {
      std::fill(out, out + pnp * pnp, 0.0);
      return;
    }
    const double *Vi = Vinv_ + i64(i) * pnp * pnp;
    couplings(i, Vi);
    const size_t cp = size_t(cnp) * size_t(pnp);
    for (int a = 0; a < pnp; ++a)
      for (int b = 0; b < pnp; ++b) {
        double s = Vi[a * pnp + b];
        for (size_t t1 = 0; t1 < cams_.size(); ++t1)
          for (size_t t2 = 0; t2 < cams_.size(); ++t2)
            for (int c = 0; c < cnp; ++c)
              for (int d = 0; d < cnp; ++d)
                s += Y_[t1 * cp + size_t(c) * pnp + a] * C_(cams_[t1], cams_[t2], c, d) *
                     Y_[t2 * cp + size_t(d) * pnp + b];
        out[a * pnp + b] = scale * s;
      }
  }

 private:
  // Y_ij = W_ij V_i^-1 for the free cameras seeing point i, into Y_, the cameras into cams_.
  void couplings(int i, const double *Vi) {
    const int cnp = lay_.cnp, pnp = lay_.pnp;
    cams_.clear();
    Y_.clear();
    for (int k = lay_.rowptr[i]; k < lay_.rowptr[i + 1]; ++k) {
      if (lay_.colidx[k] < lay_.mcon) continue;
      cams_.push_back(lay_.colidx[k]);
      form_W(lay_, ne_.jac, k, W_.data());
      for (int a = 0; a < cnp; ++a)
        for (int b = 0; b < pnp; ++b) {
          double s = 0.0;
          for (int c = 0; c < pnp; ++c) s += W_[size_t(a) * pnp + c] * Vi[c * pnp + b];
          Y_.push_back(s);
        }
    }
  }

  const Layout &lay_;
  const NormalEquations &ne_;
  const double *Vinv_;
  CameraCovariance C_;
  std::vector<double> W_, Y_;
  std::vector<int> cams_;
};

}  // namespace

// The numerical rank: eigenvalues above a tolerance relative to the largest. The tolerance sits
// well above the rounding of forming V = sum B^T B (a few ulps of the largest eigenvalue), so
// that a direction that is zero in exact arithmetic is never counted, whatever the sign its
// rounding takes.
int block_rank(const double *V, int n, std::vector<double> &work) {
  work.assign(V, V + i64(n) * n);
  std::vector<double> lambda(size_t(n), 0.0);
  symmetric_eigenvalues(work.data(), n, lambda.data());
  double top = 0.0;
  for (double l : lambda) top = std::max(top, l);
  const double tol = top * n * DBL_EPSILON * 100.0;
  int rank = 0;
  for (double l : lambda) rank += l > tol;
  return rank;
}

bool spd_inverse(std::vector<double> &S, int n) {
  if (n == 0) return true;
  double top = 0.0;
  for (int r = 0; r < n; ++r) top = std::max(top, S[size_t(r) * n + r]);
  std::vector<double> L(S);
  int info = 0;
  // Row-major S is column-major S^T = S: "L" factors the lower triangle of either view.
  SBA_F77(dpotrf, DPOTRF)("L", &n, L.data(), &n, &info, 1);
  if (info != 0) return false;
  // A pivot L_rr^2 bounds S's smallest eigenvalue from above: one at rounding level is a
  // direction pseudo_inverse would count as null, and its inverse would be noise.
  const double tol = top * n * DBL_EPSILON * 100.0;
  for (int r = 0; r < n; ++r) {
    const double d = L[size_t(r) * n + r];
    if (!(d * d > tol)) return false;
  }
  SBA_F77(dpotri, DPOTRI)("L", &n, L.data(), &n, &info, 1);
  if (info != 0) return false;
  // The lower triangle of the column-major inverse is the upper one of the row-major view.
  for (int c = 0; c < n; ++c)
    for (int r = c; r < n; ++r) {
      const double v = L[size_t(c) * n + r];
      S[size_t(c) * n + r] = v;
      S[size_t(r) * n + c] = v;
    }
  return true;
}

bool pseudo_inverse(std::vector<double> &S, int n, const std::function<bool()> &stop, const Logger &log,
                    int *rank) {
  *rank = 0;
  if (n == 0) return true;
  std::vector<double> lambda(static_cast<size_t>(n));
  int info = 0, lwork = -1;
  double wq = 0;
  SBA_F77(dsyev, DSYEV)("V", "L", &n, S.data(), &n, lambda.data(), &wq, &lwork, &info, 1, 1);
  lwork = std::max(int(wq), 3 * n);
  std::vector<double> work(static_cast<size_t>(lwork));
  SBA_F77(dsyev, DSYEV)("V", "L", &n, S.data(), &n, lambda.data(), work.data(), &lwork, &info, 1, 1);
  if (info != 0) {
    log.error("sba: the eigendecomposition of the reduced camera system failed");
    return false;
  }
  if (stop()) return false;
  // Eigenvalues ascend; the gauge directions are zero up to rounding of the largest one.
  const double tol = lambda[size_t(n) - 1] * n * DBL_EPSILON * 100.0;
  std::vector<double> Q(S);  // column c of the column-major result is eigenvector c
  std::fill(S.begin(), S.end(), 0.0);
  for (int c = 0; c < n; ++c) {
    if (stop()) return false;
    if (!(lambda[size_t(c)] > tol)) continue;
    ++*rank;
    const double inv = 1.0 / lambda[size_t(c)];
    const double *q = Q.data() + size_t(c) * n;
    for (int r = 0; r < n; ++r) {
      const double qr = q[r] * inv;
      double *row = S.data() + size_t(r) * n;
      for (int k = 0; k < n; ++k) row[k] += qr * q[k];
    }
  }
  return true;
}

bool residual_variance(const Layout &lay, double sq_err, int nunknowns, int rank_S, const Logger &log,
                       CovarianceRequest &req, i64 prior_rows) {
  const i64 points = i64(lay.free_pts()) * lay.pnp;
  const i64 rank = rank_S + points;
  const i64 dof = lay.nvis * lay.mnp + prior_rows - rank;
  if (dof <= 0) {
    log.error("sba: no redundancy (measurements - rank = %lld): the residual variance is "
              "undefined",
              static_cast<long long>(dof));
    return false;
  }
  req.sigma2 = sq_err / double(dof);
  req.rank = int(rank);
  req.nfree = int(nunknowns + points);
  return true;
}

bool covariance(const Layout &lay, Model &model, double *p, const double *x, const double *covx,
                const Options &opt, const Logger &log, CovarianceRequest &req) {
  Canceller cancel(opt);
  if (cancel.stop(log, true)) return false;
  // Taken where a solve starts and ends: every shared parameter's copies at its first
  // camera's value (tie_copies). At copies that differ, each image's projections would see
  // its own value, and J would not be the unknowns'. p is the caller's: the tie is on a copy.
  std::vector<double> tied;
  if (lay.cams.shared()) {
    tied.assign(p, p + lay.nvars());
    tie_copies(lay, tied.data());
    p = tied.data();
  }
  ThreadPool pool(opt.nthreads, opt.avoid_shared_cores);
  const ModelThreads lend(model, &pool);
  const std::unique_ptr<Kernels> kernels = make_kernels(lay, pool.size());
  Linearization lin;
  if (!linearize(lay, model, p, x, covx, opt, log, pool, *kernels, &lin) || cancel.stop(log, true)) return false;
  const NormalEquations ne{lin.jac.data(), lin.U.data(), lin.V.data(), lin.ea.data(),
                           lin.eb.data()};
  if (!points_determined(lay, ne.V, cancel, log)) return false;
  std::vector<double> Vinv(lin.V.size());
  if (cancel.stop(log, true)) return false;
  if (!kernels->invert_damped_V(pool, ne.V, req.point_damping, Vinv.data())) {
    log.error("sba: a point is not determined by its projections (its V_i is singular): its "
              "covariance is unbounded");
    return false;
  }

  // S over the unknowns, its pseudo-inverse, and that back over the parameters.
  const CameraMap &map = lay.cams;
  const int nparams = lay.free_cams() * lay.cnp, nunknowns = map.unknowns();
  std::vector<double> S;
  if (nparams > 0) {
    S = parameter_schur(lay, pool, *kernels, ne, Vinv.data());
    if (cancel.stop(log, true)) return false;
    if (!map.plain()) S = map.reduce_matrix(S);
  }
  int rank_S = 0;
  // Polled at once after the eigendecomposition, then as any loop polls.
  const auto stop = [&cancel, &log, first = true]() mutable {
    const bool now = first;
    first = false;
    return cancel.stop(log, now);
  };
  if (spd_inverse(S, nunknowns))
    rank_S = nunknowns;
  else if (!pseudo_inverse(S, nunknowns, stop, log, &rank_S))
    return false;
  if (cancel.stop(log, true) ||
      !residual_variance(lay, lin.sq_err, nunknowns, rank_S, log, req, opt.priors.rows(lay)))
    return false;

  const double scale = req.unscaled ? 1.0 : req.sigma2;
  const CameraCovariance C{S.data(), map};
  camera_blocks(lay, C, scale, req);
  PointBlocks point_block(lay, ne, Vinv.data(), C);
  for (int q = 0; q < req.npts; ++q) {
    if (cancel.stop(log)) return false;
    point_block(req.pts[q], scale, req.ptcov + i64(q) * lay.pnp * lay.pnp);
  }
  return true;
}

}  // namespace sba
