// SPDX-License-Identifier: BSD-3-Clause
// The C API: the functions sba.h, sba_ext.h and sba_chkjac.h export, but for the dense
// helpers (c_api_dense.cpp), the sba_crsm helpers (crsm.cpp) and the stop reasons' text
// (stop_reason.cpp). Each driver entry point only parses: it puts its C arguments into a
// DriverArgs (or ChkjacArgs) and runs it (driver.h, chkjac_driver.h), which validates, lays
// out and solves, and lets nothing escape as an exception but a forced unwind.
#include <cstring>

#include "callback_adapters.h"
#include "chkjac_driver.h"
#include "driver.h"
#include "driver_args.h"
#include "linear_solver.h"
#include "loss.h"
#include "sba_export.h"
#include "strategy.h"

using sba::DriverArgs;

extern "C" {

void sba_ext_options_init(struct sba_ext_options *opt) {
  if (!opt) return;
  std::memset(static_cast<void *>(opt), 0, sizeof *opt);
  opt->size = sizeof *opt;
}

void sba_ext_result_init(struct sba_ext_result *res) {
  if (!res) return;
  std::memset(static_cast<void *>(res), 0, sizeof *res);
  res->size = sizeof *res;
}

const char *sba_linsolver_names(void) { return sba::linsolver_names(); }

int sba_linsolver_valid(const char *name) {
  sba::LinSolver kind;
  return name && sba::linsolver_from_name(name, &kind) ? 1 : 0;
}

const char *sba_strategy_names(void) { return sba::strategy_names(); }

int sba_strategy_valid(const char *name) {
  sba::StrategyKind kind;
  return name && sba::strategy_from_name(name, &kind) ? 1 : 0;
}

const char *sba_loss_names(void) { return sba::loss_names(); }

int sba_loss_valid(const char *name) {
  sba::LossKind kind;
  return name && sba::loss_from_name(name, &kind) ? 1 : 0;
}

void sba_covariance_request_init(struct sba_covariance_request *req) {
  if (!req) return;
  std::memset(static_cast<void *>(req), 0, sizeof *req);
  req->size = sizeof *req;
}

int sba_motstr_covariance_x(const int n, const int ncon, const int m, const int mcon, char *vmask,
                            double *p, const int cnp, const int pnp, double *x, double *covx,
                            const int mnp, sba::ExpertFunc func, sba::ExpertFunc fjac, void *adata,
                            struct sba_covariance_request *req, const struct sba_ext_options *ext) {
  const DriverArgs a = sba::motstr_problem("sba_motstr_covariance_x", n, ncon, m, mcon, vmask, p,
                                           cnp, pnp, x, covx, mnp)
                           .estimating(sba::expert_callbacks(func, fjac, adata), ext);
  return sba::run_covariance(a, req);
}

int sba_motstr_covariance(const int n, const int ncon, const int m, const int mcon, char *vmask,
                          double *p, const int cnp, const int pnp, double *x, double *covx,
                          const int mnp, sba::MotStrProj proj, sba::MotStrJac projac, void *adata,
                          struct sba_covariance_request *req, const struct sba_ext_options *ext) {
  const DriverArgs a = sba::motstr_problem("sba_motstr_covariance", n, ncon, m, mcon, vmask, p,
                                           cnp, pnp, x, covx, mnp)
                           .estimating(sba::motstr_callbacks(proj, projac, adata), ext);
  return sba::run_covariance(a, req);
}

int sba_motstr_levmar_x_ext(const int n, const int ncon, const int m, const int mcon, char *vmask,
                            double *p, const int cnp, const int pnp, double *x, double *covx,
                            const int mnp, sba::ExpertFunc func, sba::ExpertFunc fjac, void *adata,
                            const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
                            double info[SBA_INFOSZ], const struct sba_ext_options *ext) {
  const DriverArgs a = sba::motstr_problem("sba_motstr_levmar_x", n, ncon, m, mcon, vmask, p, cnp,
                                           pnp, x, covx, mnp)
                           .solving(sba::expert_callbacks(func, fjac, adata), itmax, verbose,
                                    opts, info, ext);
  return sba::run_driver(a);
}

int sba_mot_levmar_x_ext(const int n, const int m, const int mcon, char *vmask, double *p,
                         const int cnp, double *x, double *covx, const int mnp,
                         sba::ExpertFunc func, sba::ExpertFunc fjac, void *adata, const int itmax,
                         const int verbose, const double opts[SBA_OPTSSZ], double info[SBA_INFOSZ],
                         const struct sba_ext_options *ext) {
  const DriverArgs a = sba::mot_problem("sba_mot_levmar_x", n, m, mcon, vmask, p, cnp, x, covx, mnp)
                           .solving(sba::expert_callbacks(func, fjac, adata), itmax, verbose,
                                    opts, info, ext);
  return sba::run_driver(a);
}

int sba_str_levmar_x_ext(const int n, const int ncon, const int m, char *vmask, double *p,
                         const int pnp, double *x, double *covx, const int mnp,
                         sba::ExpertFunc func, sba::ExpertFunc fjac, void *adata, const int itmax,
                         const int verbose, const double opts[SBA_OPTSSZ], double info[SBA_INFOSZ],
                         const struct sba_ext_options *ext) {
  const DriverArgs a = sba::str_problem("sba_str_levmar_x", n, ncon, m, vmask, p, pnp, x, covx, mnp)
                           .solving(sba::expert_callbacks(func, fjac, adata), itmax, verbose,
                                    opts, info, ext);
  return sba::run_driver(a);
}

int sba_motstr_levmar_ext(const int n, const int ncon, const int m, const int mcon, char *vmask,
                          double *p, const int cnp, const int pnp, double *x, double *covx,
                          const int mnp, sba::MotStrProj proj, sba::MotStrJac projac, void *adata,
                          const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
                          double info[SBA_INFOSZ], const struct sba_ext_options *ext) {
  const DriverArgs a = sba::motstr_problem("sba_motstr_levmar", n, ncon, m, mcon, vmask, p, cnp,
                                           pnp, x, covx, mnp)
                           .solving(sba::motstr_callbacks(proj, projac, adata), itmax, verbose,
                                    opts, info, ext);
  return sba::run_driver(a);
}

int sba_mot_levmar_ext(const int n, const int m, const int mcon, char *vmask, double *p,
                       const int cnp, double *x, double *covx, const int mnp,
                       sba::OneBlockProj proj, sba::OneBlockJac projac, void *adata,
                       const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
                       double info[SBA_INFOSZ], const struct sba_ext_options *ext) {
  const DriverArgs a = sba::mot_problem("sba_mot_levmar", n, m, mcon, vmask, p, cnp, x, covx, mnp)
                           .solving(sba::mot_callbacks(proj, projac, adata), itmax, verbose,
                                    opts, info, ext);
  return sba::run_driver(a);
}

int sba_str_levmar_ext(const int n, const int ncon, const int m, char *vmask, double *p,
                       const int pnp, double *x, double *covx, const int mnp,
                       sba::OneBlockProj proj, sba::OneBlockJac projac, void *adata,
                       const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
                       double info[SBA_INFOSZ], const struct sba_ext_options *ext) {
  const DriverArgs a = sba::str_problem("sba_str_levmar", n, ncon, m, vmask, p, pnp, x, covx, mnp)
                           .solving(sba::str_callbacks(proj, projac, adata), itmax, verbose,
                                    opts, info, ext);
  return sba::run_driver(a);
}

int sba_motstr_levmar_x_vis(const int n, const int ncon, const int m, const int mcon,
                            const struct sba_visibility *vis, double *p, const int cnp,
                            const int pnp, double *x, double *covx, const int mnp,
                            sba::ExpertFunc func, sba::ExpertFunc fjac, void *adata,
                            const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
                            double info[SBA_INFOSZ], const struct sba_ext_options *ext) {
  const DriverArgs a = sba::by_pairs(sba::motstr_problem("sba_motstr_levmar_x_vis", n, ncon, m, mcon, nullptr, p,
                                                         cnp, pnp, x, covx, mnp),
                                     vis)
                           .solving(sba::expert_callbacks(func, fjac, adata), itmax, verbose,
                                    opts, info, ext);
  return sba::run_driver(a);
}

int sba_motstr_levmar_vis(const int n, const int ncon, const int m, const int mcon,
                          const struct sba_visibility *vis, double *p, const int cnp,
                          const int pnp, double *x, double *covx, const int mnp,
                          sba::MotStrProj proj, sba::MotStrJac projac, void *adata,
                          const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
                          double info[SBA_INFOSZ], const struct sba_ext_options *ext) {
  const DriverArgs a = sba::by_pairs(sba::motstr_problem("sba_motstr_levmar_vis", n, ncon, m, mcon, nullptr, p,
                                                         cnp, pnp, x, covx, mnp),
                                     vis)
                           .solving(sba::motstr_callbacks(proj, projac, adata), itmax, verbose,
                                    opts, info, ext);
  return sba::run_driver(a);
}

int sba_mot_levmar_x_vis(const int n, const int m, const int mcon, const struct sba_visibility *vis,
                         double *p, const int cnp, double *x, double *covx, const int mnp,
                         sba::ExpertFunc func, sba::ExpertFunc fjac, void *adata, const int itmax,
                         const int verbose, const double opts[SBA_OPTSSZ], double info[SBA_INFOSZ],
                         const struct sba_ext_options *ext) {
  const DriverArgs a =
      sba::by_pairs(sba::mot_problem("sba_mot_levmar_x_vis", n, m, mcon, nullptr, p, cnp, x, covx, mnp), vis)
          .solving(sba::expert_callbacks(func, fjac, adata), itmax, verbose, opts, info, ext);
  return sba::run_driver(a);
}

int sba_str_levmar_x_vis(const int n, const int ncon, const int m, const struct sba_visibility *vis,
                         double *p, const int pnp, double *x, double *covx, const int mnp,
                         sba::ExpertFunc func, sba::ExpertFunc fjac, void *adata, const int itmax,
                         const int verbose, const double opts[SBA_OPTSSZ], double info[SBA_INFOSZ],
                         const struct sba_ext_options *ext) {
  const DriverArgs a =
      sba::by_pairs(sba::str_problem("sba_str_levmar_x_vis", n, ncon, m, nullptr, p, pnp, x, covx, mnp), vis)
          .solving(sba::expert_callbacks(func, fjac, adata), itmax, verbose, opts, info, ext);
  return sba::run_driver(a);
}

int sba_motstr_covariance_x_vis(const int n, const int ncon, const int m, const int mcon,
                                const struct sba_visibility *vis, double *p, const int cnp,
                                const int pnp, double *x, double *covx, const int mnp,
                                sba::ExpertFunc func, sba::ExpertFunc fjac, void *adata,
                                struct sba_covariance_request *req, const struct sba_ext_options *ext) {
  const DriverArgs a = sba::by_pairs(sba::motstr_problem("sba_motstr_covariance_x_vis", n, ncon, m, mcon, nullptr,
                                                         p, cnp, pnp, x, covx, mnp),
                                     vis)
                           .estimating(sba::expert_callbacks(func, fjac, adata), ext);
  return sba::run_covariance(a, req);
}

// ---- sba_chkjac.h ----

void sba_motstr_chkjac_x(sba::ExpertFunc func, sba::ExpertFunc jacf, double *p,
                         struct sba_crsm *idxij, int *rcidxs, int *rcsubs, int ncon, int mcon,
                         int cnp, int pnp, int mnp, void *func_adata, void *jac_adata) {
  sba::run_chkjac({"sba_motstr_chkjac_x", sba::Mode::MotStr, func, jacf, p, idxij, rcidxs, rcsubs,
                   ncon, mcon, cnp, pnp, mnp, func_adata, jac_adata});
}

void sba_mot_chkjac_x(sba::ExpertFunc func, sba::ExpertFunc jacf, double *p,
                      struct sba_crsm *idxij, int *rcidxs, int *rcsubs, int mcon, int cnp, int mnp,
                      void *func_adata, void *jac_adata) {
  sba::run_chkjac({"sba_mot_chkjac_x", sba::Mode::Mot, func, jacf, p, idxij, rcidxs, rcsubs, 0,
                   mcon, cnp, 0, mnp, func_adata, jac_adata});
}

void sba_str_chkjac_x(sba::ExpertFunc func, sba::ExpertFunc jacf, double *p,
                      struct sba_crsm *idxij, int *rcidxs, int *rcsubs, int ncon, int pnp, int mnp,
                      void *func_adata, void *jac_adata) {
  sba::run_chkjac({"sba_str_chkjac_x", sba::Mode::Str, func, jacf, p, idxij, rcidxs, rcsubs, ncon,
                   0, 0, pnp, mnp, func_adata, jac_adata});
}

// ---- the 1.6 entry points: the extension ones with the defaults ----

int sba_motstr_levmar_x(const int n, const int ncon, const int m, const int mcon, char *vmask,
                        double *p, const int cnp, const int pnp, double *x, double *covx,
                        const int mnp, sba::ExpertFunc func, sba::ExpertFunc fjac, void *adata,
                        const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
                        double info[SBA_INFOSZ]) {
  return sba_motstr_levmar_x_ext(n, ncon, m, mcon, vmask, p, cnp, pnp, x, covx, mnp, func, fjac,
                                 adata, itmax, verbose, opts, info, nullptr);
}

int sba_mot_levmar_x(const int n, const int m, const int mcon, char *vmask, double *p,
                     const int cnp, double *x, double *covx, const int mnp, sba::ExpertFunc func,
                     sba::ExpertFunc fjac, void *adata, const int itmax, const int verbose,
                     const double opts[SBA_OPTSSZ], double info[SBA_INFOSZ]) {
  return sba_mot_levmar_x_ext(n, m, mcon, vmask, p, cnp, x, covx, mnp, func, fjac, adata, itmax,
                              verbose, opts, info, nullptr);
}

int sba_str_levmar_x(const int n, const int ncon, const int m, char *vmask, double *p,
                     const int pnp, double *x, double *covx, const int mnp, sba::ExpertFunc func,
                     sba::ExpertFunc fjac, void *adata, const int itmax, const int verbose,
                     const double opts[SBA_OPTSSZ], double info[SBA_INFOSZ]) {
  return sba_str_levmar_x_ext(n, ncon, m, vmask, p, pnp, x, covx, mnp, func, fjac, adata, itmax,
                              verbose, opts, info, nullptr);
}

int sba_motstr_levmar(const int n, const int ncon, const int m, const int mcon, char *vmask,
                      double *p, const int cnp, const int pnp, double *x, double *covx,
                      const int mnp, sba::MotStrProj proj, sba::MotStrJac projac, void *adata,
                      const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
                      double info[SBA_INFOSZ]) {
  return sba_motstr_levmar_ext(n, ncon, m, mcon, vmask, p, cnp, pnp, x, covx, mnp, proj, projac,
                               adata, itmax, verbose, opts, info, nullptr);
}

int sba_mot_levmar(const int n, const int m, const int mcon, char *vmask, double *p,
                   const int cnp, double *x, double *covx, const int mnp, sba::OneBlockProj proj,
                   sba::OneBlockJac projac, void *adata, const int itmax, const int verbose,
                   const double opts[SBA_OPTSSZ], double info[SBA_INFOSZ]) {
  return sba_mot_levmar_ext(n, m, mcon, vmask, p, cnp, x, covx, mnp, proj, projac, adata, itmax,
                            verbose, opts, info, nullptr);
}

int sba_str_levmar(const int n, const int ncon, const int m, char *vmask, double *p,
                   const int pnp, double *x, double *covx, const int mnp, sba::OneBlockProj proj,
                   sba::OneBlockJac projac, void *adata, const int itmax, const int verbose,
                   const double opts[SBA_OPTSSZ], double info[SBA_INFOSZ]) {
  return sba_str_levmar_ext(n, ncon, m, vmask, p, pnp, x, covx, mnp, proj, projac, adata, itmax,
                            verbose, opts, info, nullptr);
}

}  // extern "C"
