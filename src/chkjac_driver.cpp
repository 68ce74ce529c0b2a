// SPDX-License-Identifier: BSD-3-Clause
// sba_chkjac.h's functions: the expert drivers' Jacobian check (check_jacobian, the itmax == 0
// mode) on a visibility index the caller built, with func and jacf on their own adata
// pointers. The entry points themselves: c_api.cpp.
#include "chkjac_driver.h"

#include <algorithm>
#include <climits>
#include <exception>
#include <new>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "jacobian_check.h"
#include "layout.h"
#include "log.h"
#include "model.h"

namespace sba {
namespace {

// The caller's callbacks as a Model, called exactly as 1.6 calls them: with the caller's own
// index and scratch arrays, func with func_adata and jacf with jac_adata (the drivers' expert
// model has one adata and its own index, hence this model). check_jacobian reads hx and the
// Jacobian in the index's element order; when idx->val is not the identity the callbacks
// write in val's order into a buffer that is then put into element order.
class ChkjacModel final : public Model {
 public:
  ChkjacModel(const Layout &lay, const ChkjacArgs &a) : lay_(lay), a_(a) {
    for (i64 k = 0; k < lay.nvis && identity_; ++k) identity_ = a.idx->val[k] == k;
  }

  // The check evaluates on the calling thread only.
  void use_threads(ThreadPool *) override {}
  void eval(double *p, double *hx) override { call(a_.func, a_.func_adata, p, hx, lay_.mnp, hx_); }
  bool has_jacobian() const override { return true; }
  void jacobian(double *p, double *jac) override {
    call(a_.jacf, a_.jac_adata, p, jac, lay_.jblk(), jac_);
  }
  // check_jacobian differentiates func itself and never asks for this. The return type is
  // taken from Model's declaration, as nothing here depends on it.
  using FdResult = decltype(std::declval<Model &>().fd_jacobian(nullptr, nullptr, nullptr));
  FdResult fd_jacobian(double *, const double *, double *) override {
    throw std::logic_error("the Jacobian check has no use for a forward-difference Jacobian");
  }

 private:
  void call(ExpertFunc f, void *adata, double *p, double *out, int blk, std::vector<double> &buf) {
    if (identity_) {
      f(p, a_.idx, a_.rcidxs, a_.rcsubs, out, adata);
      return;
    }
    // Zeroed once, like the caller's buffers of check_jacobian, for callbacks that leave
    // the blocks of fixed cameras or points unwritten.
    if (buf.empty()) buf.assign(size_t(lay_.nvis * blk), 0.0);
    f(p, a_.idx, a_.rcidxs, a_.rcsubs, buf.data(), adata);
    for (i64 k = 0; k < lay_.nvis; ++k)
      std::copy_n(buf.data() + i64(a_.idx->val[k]) * blk, blk, out + k * blk);
  }

  const Layout &lay_;
  const ChkjacArgs &a_;
  bool identity_ = true;
  std::vector<double> hx_, jac_;
};

// Everything that would make the check fail or the callbacks run out of bounds, as one line
// for the caller; empty when the arguments are usable.
std::string check_args(const ChkjacArgs &a) {
  const bool cams = a.mode != Mode::Str, pts = a.mode != Mode::Mot;
  if (!a.func || !a.jacf) return "func and jacf must not be NULL";
  if (!a.p) return "p is NULL";
  if (!a.idx) return "idxij is NULL";
  if (!a.rcidxs || !a.rcsubs)
    return "rcidxs and rcsubs must not be NULL (the callbacks' scratch arrays of max(n, m) ints)";
  if ((cams && a.cnp <= 0) || (pts && a.pnp <= 0) || a.mnp <= 0) {
    std::string got;
    if (cams) got += "cnp = " + std::to_string(a.cnp) + ", ";
    if (pts) got += "pnp = " + std::to_string(a.pnp) + ", ";
    got += "mnp = " + std::to_string(a.mnp);
    return "the sizes must be positive (got " + got + ")";
  }
  const sba_crsm &s = *a.idx;
  if (s.nr <= 0 || s.nc <= 0 || s.nnz <= 0)
    return "idxij must have points (nr), cameras (nc) and elements (nnz); got nr = " +
           std::to_string(s.nr) + ", nc = " + std::to_string(s.nc) + ", nnz = " +
           std::to_string(s.nnz);
  if (!s.val || !s.colidx || !s.rowptr) return "idxij's val, colidx or rowptr is NULL";
  if (cams && (a.mcon < 0 || a.mcon > s.nc))
    return "mcon = " + std::to_string(a.mcon) + " is outside 0..m (m = idxij->nc = " +
           std::to_string(s.nc) + ")";
  if (pts && (a.ncon < 0 || a.ncon > s.nr))
    return "ncon = " + std::to_string(a.ncon) + " is outside 0..n (n = idxij->nr = " +
           std::to_string(s.nr) + ")";
  if (s.rowptr[0] != 0) return "idxij's rowptr[0] is " + std::to_string(s.rowptr[0]) + ", not 0";
  for (int i = 0; i < s.nr; ++i)
    if (s.rowptr[i + 1] < s.rowptr[i] || s.rowptr[i + 1] > s.nnz)
      return "idxij's rowptr is not ascending within 0..nnz (rowptr[" + std::to_string(i) +
             "] = " + std::to_string(s.rowptr[i]) + ", rowptr[" + std::to_string(i + 1) +
             "] = " + std::to_string(s.rowptr[i + 1]) + ", nnz = " + std::to_string(s.nnz) + ")";
  if (s.rowptr[s.nr] != s.nnz)
    return "idxij's rowptr[nr] = " + std::to_string(s.rowptr[s.nr]) + " is not nnz = " +
           std::to_string(s.nnz);
  for (int i = 0; i < s.nr; ++i)
    for (int k = s.rowptr[i]; k < s.rowptr[i + 1]; ++k) {
      const int j = s.colidx[k];
      if (j < 0 || j >= s.nc)
        return "idxij's colidx[" + std::to_string(k) + "] = " + std::to_string(j) +
               " is not a camera in 0.." + std::to_string(s.nc - 1);
      // The crsm helpers binary-search a row, and the check needs each (i, j) once.
      if (k > s.rowptr[i] && j <= s.colidx[k - 1])
        return "idxij's colidx is not strictly ascending within row " + std::to_string(i) +
               " (colidx[" + std::to_string(k - 1) + "] = " + std::to_string(s.colidx[k - 1]) +
               ", colidx[" + std::to_string(k) + "] = " + std::to_string(j) + ")";
    }
  // The callbacks write projection val[k] of hx: val must be a permutation of 0..nnz-1, or
  // they would write outside hx or leave part of it unwritten.
  std::vector<char> seen(size_t(s.nnz), 0);
  for (int k = 0; k < s.nnz; ++k) {
    const int v = s.val[k];
    if (v < 0 || v >= s.nnz || seen[size_t(v)])
      return "idxij's val is not a permutation of 0..nnz-1 (val[" + std::to_string(k) + "] = " +
             std::to_string(v) + ")";
    seen[size_t(v)] = 1;
  }
  // The callbacks index p, hx and the Jacobian with int arithmetic.
  const i64 jblk = i64(a.mnp) * ((cams ? a.cnp : 0) + (pts ? a.pnp : 0));
  const i64 nvars = (cams ? i64(s.nc) * a.cnp : 0) + (pts ? i64(s.nr) * a.pnp : 0);
  if (i64(s.nnz) * jblk > INT_MAX || nvars > INT_MAX)
    return "problem too large for the int-sized sba 1.6 API (" + std::to_string(s.nnz) +
           " projections, " + std::to_string(nvars) + " parameters)";
  return std::string();
}

}  // namespace

void run_chkjac(const ChkjacArgs &a) {
  const Logger log;  // stderr: printing the findings is what these functions are for
  catch_all(log, a.name, [&] {
    std::string msg = check_args(a);
    Layout lay;
    if (msg.empty()) {
      const sba_crsm &s = *a.idx;
      std::vector<int> point(size_t(s.nnz)), camera(s.colidx, s.colidx + s.nnz);
      for (int i = 0; i < s.nr; ++i)
        std::fill(point.begin() + s.rowptr[i], point.begin() + s.rowptr[i + 1], i);
      const sba_visibility vis{s.nnz, point.data(), camera.data()};
      const bool cams = a.mode != Mode::Str, pts = a.mode != Mode::Mot;
      build_layout(lay, a.mode, s.nr, s.nc, cams ? a.mcon : 0, pts ? a.ncon : 0, cams ? a.cnp : 0,
                   pts ? a.pnp : 0, a.mnp, vis, &msg);
    }
    if (!msg.empty()) {
      log.error("%s: %s", a.name, msg.c_str());
      return;
    }
    if (lay.free_vars() == 0) {
      log.report("%s: every camera and point is held fixed (mcon, ncon): nothing to check",
                 a.name);
      return;
    }
    // The check perturbs the vector it is given; a copy keeps the caller's p bitwise intact
    // even when a callback throws half-way.
    std::vector<double> p(a.p, a.p + lay.nvars());
    ChkjacModel model(lay, a);
    check_jacobian(lay, model, p.data(), log);
  });
}

}  // namespace sba
