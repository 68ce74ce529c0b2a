// Covariance of the solution through the Schur complement: with J^T J = [U W; W^T V],
// (J^T J)^-1 has camera blocks S^-1 (S = U - W V^-1 W^T) and point blocks
// V^-1 + V^-1 W^T S^-1 W V^-1. Only the requested blocks are formed. A gauge that mcon/ncon
// leave free makes S singular; its pseudo-inverse (from a symmetric eigendecomposition) is
// used and the rank reported.
#include <algorithm>
#include <cfloat>
#include <cmath>
#include <vector>

#include "core.h"
#include "kernels.h"
#include "lapack.h"
#include "linsolve.h"
#include "parallel.h"
#include "schur.h"

namespace sba {

bool covariance(const Layout &lay, Model &model, double *p, const double *x, const double *covx,
                const Options &opt, const Logger &log, CovarianceRequest &req) {
  ThreadPool pool(opt.nthreads);
  const ModelThreads lend(model, &pool);
  const std::unique_ptr<Kernels> kernels = make_kernels(lay, pool.size());
  Linearization lin;
  if (!linearize(lay, model, p, x, covx, opt, log, pool, *kernels, &lin)) return false;
  const NormalEquations ne{lin.jac.data(), lin.U.data(), lin.V.data(), lin.ea.data(),
                           lin.eb.data()};
  const int cnp = lay.cnp, pnp = lay.pnp;

  std::vector<double> Vinv(lin.V.size());
  if (!kernels->invert_damped_V(pool, ne.V, 0.0, Vinv.data())) {
    log.error("sba: a point is not determined by its projections (its V_i is singular): its "
              "covariance is unbounded");
    return false;
  }

  // S, made full and symmetric, then its (pseudo-)inverse Q diag(1/lambda) Q^T.
  const int nS = lay.free_cams() * cnp;
  std::vector<double> S(size_t(nS) * size_t(nS), 0.0), rhs(static_cast<size_t>(nS));
  int rankS = 0;
  if (nS > 0) {
    BlockMap map;
    map.base = S.data();
    map.ld = nS;
    map.cnp = cnp;
    kernels->assemble(pool, ne, Vinv.data(), 0.0, map, rhs.data());  // with Vinv: cannot fail
    for (int r = 0; r < nS; ++r)
      for (int c = r + 1; c < nS; ++c) S[size_t(c) * nS + r] = S[size_t(r) * nS + c];
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
    // Eigenvalues ascend; the gauge directions are zero up to rounding of the largest one.
    const double tol = lambda[size_t(nS) - 1] * nS * DBL_EPSILON * 100.0;
    std::vector<double> Q(S);  // column c of the column-major result is eigenvector c
    std::fill(S.begin(), S.end(), 0.0);
    for (int c = 0; c < nS; ++c) {
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
  const i64 nfree = lay.free_vars();
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
    return S[size_t(i64(j - lay.mcon) * cnp + a) * nS + size_t(i64(k - lay.mcon) * cnp + b)];
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
      schur::form_W(lay, ne.jac, k, W.data());
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
