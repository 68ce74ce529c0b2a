// SPDX-License-Identifier: BSD-3-Clause
#include "camera_params.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>

#include "small_dense.h"

namespace sba {

namespace {

bool held(const CameraParamOptions &o, const Layout &lay, int j, int a) {
  if (!o.fixed) return false;
  return o.fixed[o.fixed_per_camera ? i64(j) * lay.cnp + a : a] != 0;
}

}  // namespace

std::string check_camera_params(const CameraParamOptions &o, const Layout &lay, const double *p) {
  if (lay.cnp == 0) return {};
  if (o.shared && !o.group) return "cam_shared is given but cam_group is NULL";
  if (!o.group) return {};
  if (!o.shared) return "cam_group is given but cam_shared is NULL";
  std::map<int, int> first;  // group number -> its first camera
  for (int j = 0; j < lay.m; ++j) {
    const int g = o.group[j];
    if (g == -1) continue;
    if (g < 0 || g >= lay.m)
      return "cam_group[" + std::to_string(j) + "] = " + std::to_string(g) +
             " is neither -1 nor a group number in [0, m-1]";
    if (j < lay.mcon)
      return "camera " + std::to_string(j) + " is below mcon = " + std::to_string(lay.mcon) +
             " (held whole) but in group " + std::to_string(g);
    const auto f = first.emplace(g, j);
    if (f.second) continue;
    const int j0 = f.first->second;
    const std::string pair = " by cameras " + std::to_string(j0) + " and " + std::to_string(j) + " (group " +
                             std::to_string(g) + ")";
    for (int a = 0; a < lay.cnp; ++a) {
      if (!o.shared[a]) continue;
      if (held(o, lay, j, a) != held(o, lay, j0, a))
        return "parameter " + std::to_string(a) + " is shared" + pair + " but held (cam_fixed) in only one of them";
      // A held value is never rewritten, so one shared value held apart would come back apart.
      const double v = p[lay.a_off(j) + a], v0 = p[lay.a_off(j0) + a];
      if (held(o, lay, j, a) && std::memcmp(&v, &v0, sizeof v) != 0) {
        char values[64];
        std::snprintf(values, sizeof values, "%.17g and %.17g", v0, v);
        return "parameter " + std::to_string(a) + " is shared" + pair + " and held, but its values differ: " +
               values;
      }
    }
  }
  return {};
}

CameraUnknowns::CameraUnknowns(const Layout &lay, const CameraParamOptions &o) {
  const int cnp = lay.cnp;
  kind.assign(size_t(lay.m) * size_t(cnp), 0);
  for (int j = lay.mcon; j < lay.m; ++j)
    for (int a = 0; a < cnp; ++a)
      if (held(o, lay, j, a)) kind[size_t(j) * cnp + a] = 1;
  if (o.group && cnp > 0) {
    std::map<int, std::vector<int>> by_number;
    for (int j = lay.mcon; j < lay.m; ++j)
      if (o.group[j] >= 0) by_number[o.group[j]].push_back(j);
    for (auto &g : by_number) {
      // A group of one camera shares with nobody: its parameters stay its own.
      if (g.second.size() < 2) continue;
      const int gi = int(groups.size());
      for (int a = 0; a < cnp; ++a) {
        if (!o.shared[a] || kind[size_t(g.second[0]) * cnp + a] == 1) continue;
        cols.push_back({gi, a});
        for (int j : g.second) kind[size_t(j) * cnp + a] = 2;
      }
      groups.push_back(std::move(g.second));
    }
  }
}

int CameraUnknowns::index(const Layout &lay, std::vector<int> *out) const {
  const int cnp = lay.cnp;
  out->assign(size_t(lay.free_cams()) * size_t(cnp), -1);
  int nz = 0;
  for (int j = lay.mcon; j < lay.m; ++j)
    for (int a = 0; a < cnp; ++a)
      if (kind[size_t(j) * cnp + a] == 0) (*out)[size_t(j - lay.mcon) * cnp + a] = nz++;
  for (const Column &c : cols) {
    for (int j : groups[size_t(c.group)]) (*out)[size_t(j - lay.mcon) * cnp + c.a] = nz;
    ++nz;
  }
  return nz;
}

i64 CameraUnknowns::count(const Layout &lay) const {
  const auto own = std::count(kind.begin() + i64(lay.mcon) * lay.cnp, kind.end(), char(0));
  return i64(own) + i64(cols.size());
}

CameraParams::CameraParams(const Layout &lay, const CameraParamOptions &o, ThreadPool &pool,
                           std::unique_ptr<StepSolver> inner)
    : lay_(lay), pool_(pool), inner_(std::move(inner)) {
  CameraUnknowns u(lay, o);
  kind_ = std::move(u.kind);
  groups_ = std::move(u.groups);
  cols_ = std::move(u.cols);
  const size_t K = cols_.size();
  t_.resize(K);
  ca_.resize(K);
  cb_.resize(K);
  x_.resize(K);
  G_.assign(K * K, 0.0);
  wdiag_.assign(K, 0.0);
  gs_.assign(K, 0.0);
}

std::vector<double> CameraParams::start(double *p) const {
  std::vector<double> given;
  for (const Column &c : cols_) {
    const std::vector<int> &g = groups_[size_t(c.group)];
    for (size_t q = 1; q < g.size(); ++q) {
      double &v = p[lay_.a_off(g[q]) + c.a];
      given.push_back(v);
      v = p[lay_.a_off(g[0]) + c.a];
    }
  }
  return given;
}

void CameraParams::restore(double *p, const std::vector<double> &given) const {
  size_t k = 0;
  for (const Column &c : cols_) {
    const std::vector<int> &g = groups_[size_t(c.group)];
    for (size_t q = 1; q < g.size(); ++q) p[lay_.a_off(g[q]) + c.a] = given[k++];
  }
}

void CameraParams::gradient_stats(const double *U, const double *ea, double *ginf,
                                  double *maxdiag) const {
  const int cnp = lay_.cnp;
  double g = 0.0, d = 0.0;
  for (int j = lay_.mcon; j < lay_.m; ++j)
    for (int a = 0; a < cnp; ++a)
      if (kind_[size_t(j) * cnp + a] == 0) {
        g = std::max(g, std::fabs(ea[lay_.a_off(j) + a]));
        d = std::max(d, U[i64(j) * cnp * cnp + a * (cnp + 1)]);
      }
  for (const Column &c : cols_) {
    double gc = 0.0, dc = 0.0;
    for (int j : groups_[size_t(c.group)]) {
      gc += ea[lay_.a_off(j) + c.a];
      dc += U[i64(j) * cnp * cnp + c.a * (cnp + 1)];
    }
    g = std::max(g, std::fabs(gc));
    d = std::max(d, dc);
  }
  *ginf = g;
  *maxdiag = d;
}

void CameraParams::linearized(double *jac, double *U, const double *ea, const double *scale) {
  const Layout &lay = lay_;
  const int cnp = lay.cnp, pnp = lay.pnp, mnp = lay.mnp, jb = lay.jblk();
  const size_t K = cols_.size();
  const i64 ncam = i64(lay.m) * cnp;

  // Every column's t first: G_ below pairs each column with every other.
  for (size_t c = 0; c < K; ++c) {
    const std::vector<int> &g = groups_[size_t(cols_[c].group)];
    t_[c].resize(g.size());
    for (size_t q = 0; q < g.size(); ++q)
      t_[c][q] = scale ? 1.0 / scale[lay.a_off(g[q]) + cols_[c].a] : 1.0;
  }
  // The bordering, from the blocks as they still are.
  for (size_t c = 0; c < K; ++c) {
    const std::vector<int> &g = groups_[size_t(cols_[c].group)];
    const int a = cols_[c].a;
    ca_[c].assign(size_t(ncam), 0.0);
    for (size_t q = 0; q < g.size(); ++q) {
      const int j = g[q];
      const double *u = U + i64(j) * cnp * cnp;
      for (int b = 0; b < cnp; ++b)
        if (kind_[size_t(j) * cnp + b] == 0) ca_[c][size_t(lay.a_off(j) + b)] = t_[c][q] * u[b * cnp + a];
    }
    double gs = 0.0, w = 0.0;
    for (size_t q = 0; q < g.size(); ++q) {
      gs += t_[c][q] * ea[lay.a_off(g[q]) + a];
      w += t_[c][q] * t_[c][q];
    }
    gs_[c] = gs;
    wdiag_[c] = w;
    for (size_t d = 0; d < K; ++d) {
      double s = 0.0;
      if (cols_[d].group == cols_[c].group)
        for (size_t q = 0; q < g.size(); ++q)
          s += t_[c][q] * t_[d][q] * U[i64(g[q]) * cnp * cnp + a * cnp + cols_[d].a];
      G_[c * K + d] = s;
    }
  }
  if (K > 0 && pnp > 0) {
    // Where each camera's t sits: the column and the camera's position in its group.
    std::vector<int> grp(size_t(lay.m), -1), pos(size_t(lay.m), -1);
    for (size_t gi = 0; gi < groups_.size(); ++gi)
      for (size_t q = 0; q < groups_[gi].size(); ++q) {
        grp[size_t(groups_[gi][q])] = int(gi);
        pos[size_t(groups_[gi][q])] = int(q);
      }
    for (size_t c = 0; c < K; ++c) cb_[c].assign(size_t(lay.n) * size_t(pnp), 0.0);
    pool_.for_range(lay.n - lay.ncon, [&](i64 b, i64 e) {
      for (i64 i = b + lay.ncon; i < e + lay.ncon; ++i)
        for (int k = lay.rowptr[size_t(i)]; k < lay.rowptr[size_t(i) + 1]; ++k) {
          const int j = lay.colidx[size_t(k)];
          if (grp[size_t(j)] < 0) continue;
          const double *A = jac + i64(k) * jb, *B = A + mnp * cnp;
          for (size_t c = 0; c < K; ++c) {
            if (cols_[c].group != grp[size_t(j)]) continue;
            const double t = t_[c][size_t(pos[size_t(j)])];
            double *out = cb_[c].data() + i * pnp;
            for (int r = 0; r < pnp; ++r) {
              double s = 0.0;
              for (int q = 0; q < mnp; ++q) s += A[q * cnp + cols_[c].a] * B[q * pnp + r];
              out[r] += t * s;
            }
          }
        }
    });
  }

  // The system the inner solver sees: without the held and shared parameters.
  ea_.assign(ea, ea + ncam);
  for (int j = lay.mcon; j < lay.m; ++j) {
    double *u = U + i64(j) * cnp * cnp;
    for (int a = 0; a < cnp; ++a) {
      if (kind_[size_t(j) * cnp + a] == 0) continue;
      ea_[size_t(lay.a_off(j) + a)] = 0.0;
      for (int b = 0; b < cnp; ++b) u[a * cnp + b] = u[b * cnp + a] = 0.0;
    }
  }
  pool_.for_range(lay.nvis, [&](i64 b, i64 e) {
    for (i64 k = b; k < e; ++k) {
      const int j = lay.colidx[size_t(k)];
      if (j < lay.mcon) continue;
      double *A = jac + k * jb;
      for (int a = 0; a < cnp; ++a)
        if (kind_[size_t(j) * cnp + a] != 0)
          for (int q = 0; q < mnp; ++q) A[q * cnp + a] = 0.0;
    }
  });
}

StepStatus CameraParams::solve(const NormalEquations &ne, double mu, double *dp) {
  const Layout &lay = lay_;
  const int cnp = lay.cnp;
  const i64 nvars = lay.nvars(), ncam = i64(lay.m) * cnp;
  const NormalEquations inner{ne.jac, ne.U, ne.V, ea_.data(), ne.eb};
  StepStatus st = inner_->solve(inner, mu, dp);
  if (st != StepStatus::Solved) return st;
  const size_t K = cols_.size();
  if (K > 0) {
    std::vector<double> M(K * K), r(K);
    for (size_t c = 0; c < K; ++c) {
      x_[c].resize(size_t(nvars));
      const NormalEquations col{ne.jac, ne.U, ne.V, ca_[c].data(), cb_[c].empty() ? ne.eb : cb_[c].data()};
      if (inner_->solve_again(col, mu, x_[c].data())) continue;
      st = inner_->solve(col, mu, x_[c].data());
      if (st != StepStatus::Solved) return st;
    }
    // c . v over the camera part and the point part of a column.
    const auto dot = [&](size_t c, const double *v) {
      const double *a = ca_[c].data(), *b = cb_[c].data();
      return deterministic_sum(pool_, nvars, [=](i64 q) {
        return q < ncam ? a[q] * v[q] : b[q - ncam] * v[q];
      });
    };
    for (size_t c = 0; c < K; ++c) {
      r[c] = gs_[c] - dot(c, dp);
      for (size_t d = 0; d <= c; ++d) {
        const double v = G_[c * K + d] - dot(c, x_[d].data()) + (c == d ? mu * wdiag_[c] : 0.0);
        M[c * K + d] = M[d * K + c] = v;
      }
    }
    if (!small::chol(M.data(), int(K))) return StepStatus::Failed;
    small::chol_solve(M.data(), r.data(), int(K));
    pool_.for_range(nvars, [&](i64 b, i64 e) {
      for (i64 q = b; q < e; ++q) {
        double s = dp[q];
        for (size_t c = 0; c < K; ++c) s -= x_[c][size_t(q)] * r[c];
        dp[q] = s;
      }
    });
    for (size_t c = 0; c < K; ++c) {
      const std::vector<int> &g = groups_[size_t(cols_[c].group)];
      for (size_t q = 0; q < g.size(); ++q) dp[lay.a_off(g[q]) + cols_[c].a] = t_[c][q] * r[c];
    }
  }
  // -0.0 is the identity of addition: p + dp leaves a held value's bits as they are, -0.0
  // included.
  for (int j = lay.mcon; j < lay.m; ++j)
    for (int a = 0; a < cnp; ++a)
      if (kind_[size_t(j) * cnp + a] == 1) dp[lay.a_off(j) + a] = -0.0;
  return StepStatus::Solved;
}

void CameraParams::tie(double *dp) const {
  for (const Column &c : cols_) {
    const std::vector<int> &g = groups_[size_t(c.group)];
    const double v = dp[lay_.a_off(g[0]) + c.a];
    for (size_t q = 1; q < g.size(); ++q) dp[lay_.a_off(g[q]) + c.a] = v;
  }
}

}  // namespace sba
