/* SPDX-License-Identifier: BSD-3-Clause */
// Sabotaged callbacks and one uniform way to call the six drivers, shared by
// tests/test_faults.cpp and the soak test (tests/soak/soak.cpp). The callbacks forward to the
// synthetic problem of synth.h and then apply the fault that their Sabotage record asks for.
#ifndef SBA_TESTS_FAULTS_H
#define SBA_TESTS_FAULTS_H

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <limits>
#include <stdexcept>
#include <vector>

#include "sba.h"
#include "sba_ext.h"
#include "synth.h"

namespace faults {

using synth::kCnp;
using synth::kMnp;
using synth::kPnp;


enum class Driver { MotStrX, MotX, StrX, MotStr, Mot, Str };
inline const Driver kAllDrivers[] = {Driver::MotStrX, Driver::MotX, Driver::StrX,
                              Driver::MotStr, Driver::Mot, Driver::Str};

inline const char *name_of(Driver d) {
  switch (d) {
    case Driver::MotStrX: return "sba_motstr_levmar_x";
    case Driver::MotX: return "sba_mot_levmar_x";
    case Driver::StrX: return "sba_str_levmar_x";
    case Driver::MotStr: return "sba_motstr_levmar";
    case Driver::Mot: return "sba_mot_levmar";
    case Driver::Str: return "sba_str_levmar";
  }
  return "?";
}
inline bool has_cameras(Driver d) { return d != Driver::StrX && d != Driver::Str; }
inline bool has_points(Driver d) { return d != Driver::MotX && d != Driver::Mot; }
inline bool is_expert(Driver d) { return d == Driver::MotStrX || d == Driver::MotX || d == Driver::StrX; }

// Callbacks that can be sabotaged: each one forwards to the synth model and then applies
// the fault asked for in the Sabotage record (adata of every call below). The library may
// call the callbacks from several threads at once: the counters are atomic.
struct Sabotage {
  synth::Problem *pb = nullptr;
  enum Kind {
    None,
    NanValue,    // a NaN in the projections ...
    InfValue,    // ... or an Inf
    ThrowValue,  // the projection callback throws std::runtime_error
    NanJac,      // a NaN in the Jacobian
    NegatedJac,  // the Jacobian of the wrong sign
    WrongJac,    // every Jacobian entry off by up to 50%
    ZeroJac      // a Jacobian of zeros
  } kind = None;
  long after = 0;  // the fault starts at call number after + 1 of the function (value
                   // faults) or of the Jacobian (Jacobian faults)
  std::atomic<long> func_calls{0}, jac_calls{0};
  std::atomic<bool> fired{false};  // the fault was applied at least once

  bool fault_in_jac() const { return kind >= NanJac; }
  bool value_fault_due(long call) const { return !fault_in_jac() && kind != None && call > after; }
  bool jac_fault_due(long call) const { return fault_in_jac() && call > after; }
  void reset() {
    func_calls = 0;
    jac_calls = 0;
    fired = false;
  }
};

inline void spoil_values(Sabotage &s, long call, double *hx, long len) {
  if (!s.value_fault_due(call)) return;
  s.fired = true;
  if (s.kind == Sabotage::ThrowValue) throw std::runtime_error("callback failure injected by the test");
  hx[len / 2] = s.kind == Sabotage::InfValue ? -std::numeric_limits<double>::infinity()
                                             : std::numeric_limits<double>::quiet_NaN();
}
inline void spoil_jac(Sabotage &s, long call, double *jac, long len) {
  if (!s.jac_fault_due(call)) return;
  s.fired = true;
  switch (s.kind) {
    case Sabotage::NegatedJac:
      for (long q = 0; q < len; ++q) jac[q] = -jac[q];
      break;
    case Sabotage::WrongJac:
      for (long q = 0; q < len; ++q) jac[q] *= 1.0 + 0.5 * std::sin(double(q) * 0.7 + double(call));
      break;
    case Sabotage::ZeroJac:
      std::fill(jac, jac + len, 0.0);
      break;
    default:
      jac[len / 3] = std::numeric_limits<double>::quiet_NaN();
      break;
  }
}

// Expert callbacks: the fault applies to one whole call.
inline void x_func_motstr(double *p, sba_crsm *idx, int *r, int *c, double *hx, void *ad) {
  Sabotage &s = *static_cast<Sabotage *>(ad);
  const long ncall = ++s.func_calls;
  synth::func_motstr(p, idx, r, c, hx, s.pb);
  spoil_values(s, ncall, hx, long(idx->nnz) * kMnp);
}
inline void x_fjac_motstr(double *p, sba_crsm *idx, int *r, int *c, double *jac, void *ad) {
  Sabotage &s = *static_cast<Sabotage *>(ad);
  const long ncall = ++s.jac_calls;
  synth::fjac_motstr(p, idx, r, c, jac, s.pb);
  spoil_jac(s, ncall, jac, long(idx->nnz) * kMnp * (kCnp + kPnp));
}
inline void x_func_mot(double *p, sba_crsm *idx, int *r, int *c, double *hx, void *ad) {
  Sabotage &s = *static_cast<Sabotage *>(ad);
  const long ncall = ++s.func_calls;
  synth::func_mot(p, idx, r, c, hx, s.pb);
  spoil_values(s, ncall, hx, long(idx->nnz) * kMnp);
}
inline void x_fjac_mot(double *p, sba_crsm *idx, int *r, int *c, double *jac, void *ad) {
  Sabotage &s = *static_cast<Sabotage *>(ad);
  const long ncall = ++s.jac_calls;
  synth::fjac_mot(p, idx, r, c, jac, s.pb);
  spoil_jac(s, ncall, jac, long(idx->nnz) * kMnp * kCnp);
}
inline void x_func_str(double *p, sba_crsm *idx, int *r, int *c, double *hx, void *ad) {
  Sabotage &s = *static_cast<Sabotage *>(ad);
  const long ncall = ++s.func_calls;
  synth::func_str(p, idx, r, c, hx, s.pb);
  spoil_values(s, ncall, hx, long(idx->nnz) * kMnp);
}
inline void x_fjac_str(double *p, sba_crsm *idx, int *r, int *c, double *jac, void *ad) {
  Sabotage &s = *static_cast<Sabotage *>(ad);
  const long ncall = ++s.jac_calls;
  synth::fjac_str(p, idx, r, c, jac, s.pb);
  spoil_jac(s, ncall, jac, long(idx->nnz) * kMnp * kPnp);
}

// Simple callbacks: calls are counted per projection, so "after" counts projections.
inline void s_proj_motstr(int j, int i, double *a, double *b, double *x, void *ad) {
  Sabotage &s = *static_cast<Sabotage *>(ad);
  const long ncall = ++s.func_calls;
  synth::proj_motstr(j, i, a, b, x, s.pb);
  spoil_values(s, ncall, x, 2);
}
inline void s_projac_motstr(int j, int i, double *a, double *b, double *A, double *B, void *ad) {
  Sabotage &s = *static_cast<Sabotage *>(ad);
  const long ncall = ++s.jac_calls;
  synth::projac_motstr(j, i, a, b, A, B, s.pb);
  spoil_jac(s, ncall, A, kMnp * kCnp);
  spoil_jac(s, ncall, B, kMnp * kPnp);
}
inline void s_proj_mot(int j, int i, double *a, double *x, void *ad) {
  Sabotage &s = *static_cast<Sabotage *>(ad);
  const long ncall = ++s.func_calls;
  synth::proj_mot(j, i, a, x, s.pb);
  spoil_values(s, ncall, x, 2);
}
inline void s_projac_mot(int j, int i, double *a, double *A, void *ad) {
  Sabotage &s = *static_cast<Sabotage *>(ad);
  const long ncall = ++s.jac_calls;
  synth::projac_mot(j, i, a, A, s.pb);
  spoil_jac(s, ncall, A, kMnp * kCnp);
}
inline void s_proj_str(int j, int i, double *b, double *x, void *ad) {
  Sabotage &s = *static_cast<Sabotage *>(ad);
  const long ncall = ++s.func_calls;
  synth::proj_str(j, i, b, x, s.pb);
  spoil_values(s, ncall, x, 2);
}
inline void s_projac_str(int j, int i, double *b, double *B, void *ad) {
  Sabotage &s = *static_cast<Sabotage *>(ad);
  const long ncall = ++s.jac_calls;
  synth::projac_str(j, i, b, B, s.pb);
  spoil_jac(s, ncall, B, kMnp * kPnp);
}

// One call of a driver with every argument spelled out, so a test can spoil any of them.
struct Call {
  int n = 0, ncon = 0, m = 0, mcon = 0, cnp = kCnp, pnp = kPnp, mnp = kMnp, itmax = 100;
  char *vmask = nullptr;
  double *p = nullptr, *x = nullptr, *covx = nullptr;
  bool func = true, jac = true;
  const double *opts = nullptr;
  double *info = nullptr;
  const sba_ext_options *ext = nullptr;
};

inline int call(Driver d, const Call &c, Sabotage *s) {
  switch (d) {
    case Driver::MotStrX:
      return sba_motstr_levmar_x_ext(c.n, c.ncon, c.m, c.mcon, c.vmask, c.p, c.cnp, c.pnp, c.x, c.covx,
                                     c.mnp, c.func ? x_func_motstr : nullptr,
                                     c.jac ? x_fjac_motstr : nullptr, s, c.itmax, 0, c.opts, c.info, c.ext);
    case Driver::MotX:
      return sba_mot_levmar_x_ext(c.n, c.m, c.mcon, c.vmask, c.p, c.cnp, c.x, c.covx, c.mnp,
                                  c.func ? x_func_mot : nullptr, c.jac ? x_fjac_mot : nullptr, s,
                                  c.itmax, 0, c.opts, c.info, c.ext);
    case Driver::StrX:
      return sba_str_levmar_x_ext(c.n, c.ncon, c.m, c.vmask, c.p, c.pnp, c.x, c.covx, c.mnp,
                                  c.func ? x_func_str : nullptr, c.jac ? x_fjac_str : nullptr, s,
                                  c.itmax, 0, c.opts, c.info, c.ext);
    case Driver::MotStr:
      return sba_motstr_levmar_ext(c.n, c.ncon, c.m, c.mcon, c.vmask, c.p, c.cnp, c.pnp, c.x, c.covx,
                                   c.mnp, c.func ? s_proj_motstr : nullptr,
                                   c.jac ? s_projac_motstr : nullptr, s, c.itmax, 0, c.opts, c.info, c.ext);
    case Driver::Mot:
      return sba_mot_levmar_ext(c.n, c.m, c.mcon, c.vmask, c.p, c.cnp, c.x, c.covx, c.mnp,
                                c.func ? s_proj_mot : nullptr, c.jac ? s_projac_mot : nullptr, s,
                                c.itmax, 0, c.opts, c.info, c.ext);
    case Driver::Str:
      return sba_str_levmar_ext(c.n, c.ncon, c.m, c.vmask, c.p, c.pnp, c.x, c.covx, c.mnp,
                                c.func ? s_proj_str : nullptr, c.jac ? s_projac_str : nullptr, s,
                                c.itmax, 0, c.opts, c.info, c.ext);
  }
  return 0;
}

// A problem set up for driver d: p holds what the driver refines (the motion-only drivers
// see the true points, the structure-only ones the true cameras).
struct Rig {
  synth::Problem pb;
  std::vector<double> p0, p, covx;
  Sabotage sab;
  double info[SBA_INFOSZ] = {};

  Rig(Driver d, int n, int m, double sigma, unsigned seed, double vis = 0.7)
      : pb(synth::make(n, m, sigma, 0.05, seed, vis)) {
    const size_t ncam = size_t(m) * kCnp;
    if (has_cameras(d) && has_points(d)) {
      p0 = pb.p0;
    } else if (has_cameras(d)) {
      p0.assign(pb.p0.begin(), pb.p0.begin() + long(ncam));
      pb.fixed_points = pb.truth.data() + ncam;
    } else {
      p0.assign(pb.p0.begin() + long(ncam), pb.p0.end());
      pb.fixed_cams = pb.truth.data();
    }
    p = p0;
    covx.assign(size_t(pb.nvis) * 4, 0.0);
    for (int k = 0; k < pb.nvis; ++k) covx[4 * size_t(k)] = covx[4 * size_t(k) + 3] = 1.0;
    sab.pb = &pb;
  }
  Call base() {
    Call c;
    c.n = pb.n;
    c.m = pb.m;
    c.vmask = pb.vmask.data();
    c.p = p.data();
    c.x = pb.x.data();
    c.info = info;
    return c;
  }
  double sq_error_of(const std::vector<double> &q) const {
    if (q.size() == pb.p0.size()) return synth::sq_error(pb, q.data());
    std::vector<double> full = pb.truth;
    if (q.size() == size_t(pb.m) * kCnp)
      std::copy(q.begin(), q.end(), full.begin());
    else
      std::copy(q.begin(), q.end(), full.begin() + long(pb.m) * kCnp);
    return synth::sq_error(pb, full.data());
  }
};

inline bool all_finite(const std::vector<double> &v) {
  for (double x : v)
    if (!std::isfinite(x)) return false;
  return true;
}

}  // namespace faults

#endif
