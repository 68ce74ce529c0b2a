// SPDX-License-Identifier: BSD-3-Clause
#include "run.h"

#include <numeric>
#include <string>

#include "prior_callbacks.h"

namespace pysba {

namespace {

// The session's options with o's priors, whose structs *priors holds.
sba_ext_options with_priors(Session &session, const Run &run, const SolveOptions &o, PriorStructs *priors) {
  sba_ext_options ext = *session.ext(run.parallel);
  if (run.colmap_priors) run.colmap_priors->attach(&ext);
  else priors->attach(o.priors, session, run.cnp, &ext);
  return ext;
}

}  // namespace

py::dict run_driver(Run &run, Session &session, const SolveOptions &o) {
  Observations &obs = run.obs;
  const int n = obs.n, m = obs.m, mnp = obs.mnp;
  if (o.mcon < 0 || o.mcon > m)
    throw py::value_error("mcon must be in [0, " + std::to_string(m) + "], got " + std::to_string(o.mcon));
  if (o.ncon < 0 || o.ncon > n)
    throw py::value_error("ncon must be in [0, " + std::to_string(n) + "], got " + std::to_string(o.ncon));
  if (run.refine != Refine::Str) check_camera_params(o, m, run.cnp);
  check_prior_shapes(o.priors, run.pnp);
  double info[SBA_INFOSZ] = {0};
  PriorStructs priors;
  const sba_ext_options ext = with_priors(session, run, o, &priors);
  const sba_visibility vis = obs.vis();
  const int ret = without_gil(session.released_thread(), [&] {
    switch (run.refine) {
      case Refine::MotStr:
        return sba_motstr_levmar_x_vis(n, o.ncon, m, o.mcon, &vis, run.p.data(), run.cnp, run.pnp, obs.x.data(),
                                       obs.covx_or_null(), mnp, run.func, run.fjac, run.adata, o.itmax, 0,
                                       o.opts.data(), info, &ext);
      case Refine::Mot:
        return sba_mot_levmar_x_vis(n, m, o.mcon, &vis, run.p.data(), run.cnp, obs.x.data(), obs.covx_or_null(),
                                    mnp, run.func, run.fjac, run.adata, o.itmax, 0, o.opts.data(), info, &ext);
      case Refine::Str:
        return sba_str_levmar_x_vis(n, o.ncon, m, &vis, run.p.data(), run.pnp, obs.x.data(), obs.covx_or_null(),
                                    mnp, run.func, run.fjac, run.adata, o.itmax, 0, o.opts.data(), info, &ext);
    }
    return SBA_ERROR;
  });
  py::dict d = session.report(ret, info);
  if (!o.covariance || ret == SBA_ERROR || session.failed()) return d;
  if (run.refine != Refine::MotStr)
    throw py::value_error("covariance needs motion and structure refinement");

  std::vector<int> cams(static_cast<size_t>(m)), pts(static_cast<size_t>(n));
  std::iota(cams.begin(), cams.end(), 0);
  std::iota(pts.begin(), pts.end(), 0);
  std::vector<double> camcov(size_t(m) * run.cnp * run.cnp), ptcov(size_t(n) * run.pnp * run.pnp);
  sba_covariance_request req;
  sba_covariance_request_init(&req);
  req.ncams = m;
  req.cams = cams.data();
  req.camcov = camcov.data();
  req.npts = n;
  req.pts = pts.data();
  req.ptcov = ptcov.data();
  // The covariance reads p and does not change it, but takes it as non-const.
  std::vector<double> p = run.p;
  const size_t nerrors = session.errors().size();
  const sba_ext_options cov_ext = with_priors(session, run, o, &priors);
  const int status = without_gil(session.released_thread(), [&] {
    return sba_motstr_covariance_x_vis(n, o.ncon, m, o.mcon, &vis, p.data(), run.cnp, run.pnp, obs.x.data(),
                                       obs.covx_or_null(), mnp, run.func, run.fjac, run.adata, &req, &cov_ext);
  });
  if (session.failed()) {
    d["error"] = session.error();
    return d;
  }
  if (status != 0) {
    const std::vector<std::string> &errors = session.errors();
    d["covariance_error"] = errors.size() > nerrors ? errors[nerrors] : "the covariance could not be computed";
    return d;
  }
  d["camera_covariance"] = adopt(std::move(camcov), {m, run.cnp, run.cnp});
  d["point_covariance"] = adopt(std::move(ptcov), {n, run.pnp, run.pnp});
  d["sigma2"] = req.sigma2;
  d["rank"] = req.rank;
  d["nfree"] = req.nfree;
  return d;
}

}  // namespace pysba
