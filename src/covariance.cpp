// SPDX-License-Identifier: BSD-3-Clause
// Covariance of the solution through the Schur complement: with J^T J = [U W; W^T V],
// (J^T J)^-1 has camera blocks S^-1 (S = U - W V^-1 W^T) and point blocks
// V^-1 + V^-1 W^T S^-1 W V^-1. Only the requested blocks are formed. A gauge that mcon/ncon
// leave free makes S singular; its pseudo-inverse (from a symmetric eigendecomposition) is
// used and the rank reported. A point block V_i, by contrast, must have full rank: a point
// that its projections do not determine (seen by one camera, or by cameras in degenerate
// positions) is refused by name, since inverting its V_i would turn rounding into numbers.
#include "covariance.h"

#include <algorithm>
#include <cfloat>
#include <chrono>
#include <cmath>
#include <string>
#include <vector>

#include "kernels.h"
#include "lapack.h"
#include "linearization.h"
#include "parallel.h"
#include "step_solver.h"

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

// The numerical rank of the symmetric positive semi-definite block V (n x n): eigenvalues
// above a tolerance relative to the largest. The tolerance sits well above the rounding of
// forming V = sum B^T B (a few ulps of the largest eigenvalue), so that a direction that is
// zero in exact arithmetic is never counted, whatever the sign its rounding takes.
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

// Per free camera parameter ((j - mcon) cnp + c), the index of its unknown, -1 for a held
// one; returns how many unknowns there are.
int unknown_index(const Layout &lay, std::vector<int> *out) {
  const int cnp = lay.cnp;
  out->assign(size_t(lay.free_cams()) * size_t(cnp), -1);
  if (lay.cams.shared()) {
    std::copy(lay.cams.unknown.begin() + i64(lay.mcon) * cnp, lay.cams.unknown.end(), out->begin());
    return lay.cams.nunknowns;
  }
  int nz = 0;
  for (i64 q = 0; q < i64(out->size()); ++q)
    if (!lay.cams.held[size_t(i64(lay.mcon) * cnp + q)]) (*out)[size_t(q)] = nz++;
  return nz;
}

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

}  // namespace

bool covariance(const Layout &lay, Model &model, double *p, const double *x, const double *covx,
                const Options &opt, const Logger &log, CovarianceRequest &req) {
  Canceller cancel(opt);
  if (cancel.stop(log, true)) return false;
  ThreadPool pool(opt.nthreads, opt.avoid_shared_cores);
  const ModelThreads lend(model, &pool);
  const std::unique_ptr<Kernels> kernels = make_kernels(lay, pool.size());
  Linearization lin;
  if (!linearize(lay, model, p, x, covx, opt, log, pool, *kernels, &lin) || cancel.stop(log, true)) return false;
  const NormalEquations ne{lin.jac.data(), lin.U.data(), lin.V.data(), lin.ea.data(),
                           lin.eb.data()};
  const int cnp = lay.cnp, pnp = lay.pnp;

  // Every free point's V_i must have full rank. Testing it before inverting matters: a V_i
  // that is singular in exact arithmetic often has a tiny positive rounding pivot, and then
  // its "inverse" is rounding noise of 1e10 and more, which also leaks into S and so into
  // every other block.
  {
    std::vector<double> work;
    const int pnp2 = pnp * pnp;
    for (int i = lay.ncon; i < lay.n && pnp > 0; ++i) {
      if (cancel.stop(log)) return false;
      const int r = block_rank(ne.V + i64(i) * pnp2, pnp, work);
      if (r < pnp) {
        log.error("sba: %s", undetermined_point(lay, i, r).c_str());
        return false;
      }
    }
  }
  std::vector<double> Vinv(lin.V.size());
  if (cancel.stop(log, true)) return false;
  if (!kernels->invert_damped_V(pool, ne.V, 0.0, Vinv.data())) {
    log.error("sba: a point is not determined by its projections (its V_i is singular): its "
              "covariance is unbounded");
    return false;
  }

  // S, made full and symmetric, then its (pseudo-)inverse Q diag(1/lambda) Q^T.
  const int nA = lay.free_cams() * cnp;
  std::vector<double> S(size_t(nA) * size_t(nA), 0.0), rhs(static_cast<size_t>(nA));
  int rankS = 0;
  // With held or shared camera parameters the unknowns are fewer than the camera
  // parameters: S over the unknowns is T^T S T, where T maps each unknown to the parameters
  // it moves (unknown[r], -1 for a held one), and the parameters' covariance T S^+ T^T.
  const bool reduced = (lay.cams.shared() || lay.cams.any_held()) && cnp > 0;
  std::vector<int> unknown;
  int nS = nA;
  if (reduced) nS = unknown_index(lay, &unknown);
  std::vector<double> Sa;
  if (nA > 0) {
    BlockMap map;
    map.base = S.data();
    map.ld = nA;
    map.cnp = cnp;
    kernels->assemble(pool, ne, Vinv.data(), 0.0, map, rhs.data());  // with Vinv: cannot fail
    if (cancel.stop(log, true)) return false;
    for (int r = 0; r < nA; ++r)
      for (int c = r + 1; c < nA; ++c) S[size_t(c) * nA + r] = S[size_t(r) * nA + c];
    if (reduced) {
      Sa.swap(S);
      S.assign(size_t(nS) * size_t(nS), 0.0);
      for (int r = 0; r < nA; ++r) {
        if (unknown[size_t(r)] < 0) continue;
        double *row = S.data() + size_t(unknown[size_t(r)]) * nS;
        for (int c = 0; c < nA; ++c)
          if (unknown[size_t(c)] >= 0) row[unknown[size_t(c)]] += Sa[size_t(r) * nA + size_t(c)];
      }
    }
  }
  if (nS > 0) {
    std::vector<double> lambda(static_cast<size_t>(nS));
    int info = 0, lwork = -1;
    double wq = 0;
    SBA_F77(dsyev, DSYEV)("V", "L", &nS, S.data(), &nS, lambda.data(), &wq, &lwork, &info, 1, 1);
    lwork = std::max(int(wq), 3 * nS);
    std::vector<double> work(static_cast<size_t>(lwork));
    SBA_F77(dsyev, DSYEV)("V", "L", &nS, S.data(), &nS, lambda.data(), work.data(), &lwork, &info,
                          1, 1);
    if (info != 0) {
      log.error("sba: the eigendecomposition of the reduced camera system failed");
      return false;
    }
    if (cancel.stop(log, true)) return false;
    // Eigenvalues ascend; the gauge directions are zero up to rounding of the largest one.
    const double tol = lambda[size_t(nS) - 1] * nS * DBL_EPSILON * 100.0;
    std::vector<double> Q(S);  // column c of the column-major result is eigenvector c
    std::fill(S.begin(), S.end(), 0.0);
    for (int c = 0; c < nS; ++c) {
      if (cancel.stop(log)) return false;
      if (!(lambda[size_t(c)] > tol)) continue;
      ++rankS;
      const double inv = 1.0 / lambda[size_t(c)];
      const double *q = Q.data() + size_t(c) * nS;
      for (int r = 0; r < nS; ++r) {
        const double qr = q[r] * inv;
        double *row = S.data() + size_t(r) * nS;
        for (int k = 0; k < nS; ++k) row[k] += qr * q[k];
      }
    }
  }
  if (reduced) {  // back to the parameters: T S^+ T^T
    for (int r = 0; r < nA; ++r)
      for (int c = 0; c < nA; ++c) {
        const int zr = unknown[size_t(r)], zc = unknown[size_t(c)];
        Sa[size_t(r) * nA + size_t(c)] = zr < 0 || zc < 0 ? 0.0 : S[size_t(zr) * nS + size_t(zc)];
      }
    S.swap(Sa);
  }
  const i64 nfree = nS + i64(lay.free_pts()) * pnp;
  const i64 rank = rankS + i64(lay.free_pts()) * pnp;
  const i64 dof = lay.nvis * lay.mnp - rank;
  if (dof <= 0) {
    log.error("sba: no redundancy (measurements - rank = %lld): the residual variance is "
              "undefined",
              static_cast<long long>(dof));
    return false;
  }
  const double sigma2 = lin.sq_err / double(dof);
  req.sigma2 = sigma2;
  req.rank = int(rank);
  req.nfree = int(nfree);

  auto Sinv = [&](int j, int k, int a, int b) {  // entry (a,b) of block (j,k), free cameras
    return S[size_t(i64(j - lay.mcon) * cnp + a) * nA + size_t(i64(k - lay.mcon) * cnp + b)];
  };
  for (int q = 0; q < req.ncams; ++q) {
    const int j = req.cams[q];
    double *out = req.camcov + i64(q) * cnp * cnp;
    for (int a = 0; a < cnp; ++a)
      for (int b = 0; b < cnp; ++b)
        out[a * cnp + b] = j >= lay.mcon ? sigma2 * Sinv(j, j, a, b) : 0.0;
  }
  std::vector<double> W(size_t(cnp) * size_t(pnp)), Y;
  std::vector<int> cams;
  for (int q = 0; q < req.npts; ++q) {
    if (cancel.stop(log)) return false;
    const int i = req.pts[q];
    double *out = req.ptcov + i64(q) * pnp * pnp;
    if (i < lay.ncon) {
      std::fill(out, out + pnp * pnp, 0.0);
      continue;
    }
    const double *Vi = Vinv.data() + i64(i) * pnp * pnp;
    // Y_ij = W_ij V_i^-1 for the free cameras seeing i.
    cams.clear();
    Y.clear();
    for (int k = lay.rowptr[i]; k < lay.rowptr[i + 1]; ++k) {
      if (lay.colidx[k] < lay.mcon) continue;
      cams.push_back(lay.colidx[k]);
      form_W(lay, ne.jac, k, W.data());
      for (int a = 0; a < cnp; ++a)
        for (int b = 0; b < pnp; ++b) {
          double s = 0.0;
          for (int c = 0; c < pnp; ++c) s += W[size_t(a) * pnp + c] * Vi[c * pnp + b];
          Y.push_back(s);
        }
    }
    const size_t cp = size_t(cnp) * size_t(pnp);
    for (int a = 0; a < pnp; ++a)
      for (int b = 0; b < pnp; ++b) {
        double s = Vi[a * pnp + b];
        for (size_t t1 = 0; t1 < cams.size(); ++t1)
          for (size_t t2 = 0; t2 < cams.size(); ++t2)
            for (int c = 0; c < cnp; ++c)
              for (int d = 0; d < cnp; ++d)
                s += Y[t1 * cp + size_t(c) * pnp + a] * Sinv(cams[t1], cams[t2], c, d) *
                     Y[t2 * cp + size_t(d) * pnp + b];
        out[a * pnp + b] = sigma2 * s;
      }
  }
  return true;
}

}  // namespace sba
