// SPDX-License-Identifier: BSD-3-Clause
// No Schur complement: the whole damped system (U*, W; W^T, V*) in compressed-column form,
// ordered once per solve by AMD and factored by LDL^T for every damping value (the sba
// paper's Table II comparison). The pattern and the symbolic factorization are fixed by the
// visibility, so only the numeric factorization is repeated.
#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include "kernels.h"
#include "mapped_schur.h"
#include "step_solver.h"
#include "suitesparse_status.h"

extern "C" {
#include <suitesparse/ldl.h>
}

namespace sba {
namespace {

using sslong = SuiteSparse_long;

// The factorization both solvers below share: AMD's ordering and LDL's symbolic analysis of a
// pattern fixed for the solve (the upper and the lower triangle, compressed by column, the
// row indices of each column sorted), then for each damping value the numeric factorization
// and the solve. The matrix is positive definite in exact arithmetic but where sba 1.6's
// retries leave an indefinite diagonal on the point blocks; a non-positive pivot means one of
// the two, and the step would not be a descent direction: the damped system has failed, as
// 1.6's Cholesky of S fails there.
class LdlFactor {
 public:
  // LDL's prototypes take the pattern by pointers to non-const; it is only read.
  LdlFactor(sslong n, sslong *Ap, sslong *Ai)
      : n_(n), P_(size_t(n)), Pinv_(size_t(n)), Lp_(size_t(n) + 1), parent_(size_t(n)), lnz_(size_t(n)),
        flag_(size_t(n)), pattern_(size_t(n)), D_(size_t(n)), Y_(size_t(n)) {
    // The pattern is valid by construction: only memory should fail.
    if (const int status = amd_l_order(n, Ap, Ai, P_.data(), nullptr, nullptr); status != AMD_OK)
      throw_amd_failure("amd_l_order", status);
    ldl_l_symbolic(n, Ap, Ai, Lp_.data(), parent_.data(), lnz_.data(), flag_.data(), P_.data(), Pinv_.data());
    Li_.resize(size_t(Lp_[size_t(n)]));
    Lx_.resize(Li_.size());
  }

  // Factors the matrix of values Ax over the pattern; false where a pivot is not positive.
  bool factor(sslong *Ap, sslong *Ai, double *Ax) {
    const sslong done = ldl_l_numeric(n_, Ap, Ai, Ax, Lp_.data(), parent_.data(), lnz_.data(), Li_.data(),
                                      Lx_.data(), D_.data(), Y_.data(), pattern_.data(), flag_.data(), P_.data(),
                                      Pinv_.data());
    if (done != n_) return false;
    for (sslong q = 0; q < n_; ++q)
      if (!(D_[size_t(q)] > 0.0)) return false;
    return true;
  }

  // x := A^-1 x; false where the solution is not finite.
  bool solve(double *x) {
    ldl_l_perm(n_, Y_.data(), x, P_.data());
    ldl_l_lsolve(n_, Y_.data(), Lp_.data(), Li_.data(), Lx_.data());
    ldl_l_dsolve(n_, Y_.data(), D_.data());
    ldl_l_ltsolve(n_, Y_.data(), Lp_.data(), Li_.data(), Lx_.data());
    ldl_l_permt(n_, x, Y_.data(), P_.data());
    for (sslong q = 0; q < n_; ++q)
      if (!std::isfinite(x[q])) return false;
    return true;
  }

 private:
  sslong n_;
  std::vector<sslong> P_, Pinv_, Lp_, parent_, lnz_, flag_, pattern_, Li_;
  std::vector<double> D_, Y_, Lx_;
};

class LdlAmdSolver final : public StepSolver {
 public:
  explicit LdlAmdSolver(const SolveContext &ctx) : lay_(ctx.lay) {
    const Layout &lay = lay_;
    const int cnp = lay.cnp, pnp = lay.pnp;
    nS_ = i64(lay.free_cams()) * cnp;
    N_ = nS_ + i64(lay.free_pts()) * pnp;
    pos_in_cam_.assign(size_t(lay.nvis), -1);
    pos_in_pt_.assign(size_t(lay.nvis), -1);
    std::vector<int> colrow, colk;  // freed once the pattern is built
    by_camera(lay, &colrow, &colk);
    // Position of each free-free projection's W block in its camera's and its point's column.
    std::vector<int> ncam_pts(size_t(lay.m), 0);
    for (int j = lay.mcon; j < lay.m; ++j)
      for (int s = lay.colptr[j]; s < lay.colptr[j + 1]; ++s)
        if (colrow[s] >= lay.ncon) pos_in_cam_[size_t(colk[s])] = ncam_pts[size_t(j)]++;
    std::vector<int> npt_cams(size_t(lay.n), 0);
    for (int i = lay.ncon; i < lay.n; ++i)
      for (int k = lay.rowptr[i]; k < lay.rowptr[i + 1]; ++k)
        if (lay.colidx[k] >= lay.mcon) pos_in_pt_[size_t(k)] = npt_cams[size_t(i)]++;

    Ap_.assign(size_t(N_) + 1, 0);
    for (int j = lay.mcon; j < lay.m; ++j)
      for (int b = 0; b < cnp; ++b)
        Ap_[size_t(cam_col(j, b)) + 1] = cnp + i64(ncam_pts[size_t(j)]) * pnp;
    for (int i = lay.ncon; i < lay.n; ++i)
      for (int b = 0; b < pnp; ++b)
        Ap_[size_t(pt_col(i, b)) + 1] = i64(npt_cams[size_t(i)]) * cnp + pnp;
    for (i64 c = 0; c < N_; ++c) Ap_[size_t(c) + 1] += Ap_[size_t(c)];
    Ai_.resize(size_t(Ap_[size_t(N_)]));
    Ax_.resize(Ai_.size());
    for (int j = lay.mcon; j < lay.m; ++j)
      for (int b = 0; b < cnp; ++b) {
        sslong q = Ap_[size_t(cam_col(j, b))];
        for (int a = 0; a < cnp; ++a) Ai_[size_t(q++)] = cam_col(j, a);
        for (int s = lay.colptr[j]; s < lay.colptr[j + 1]; ++s)
          if (colrow[s] >= lay.ncon)
            for (int c = 0; c < pnp; ++c) Ai_[size_t(q++)] = pt_col(colrow[s], c);
      }
    for (int i = lay.ncon; i < lay.n; ++i)
      for (int b = 0; b < pnp; ++b) {
        sslong q = Ap_[size_t(pt_col(i, b))];
        for (int k = lay.rowptr[i]; k < lay.rowptr[i + 1]; ++k)
          if (lay.colidx[k] >= lay.mcon)
            for (int a = 0; a < cnp; ++a) Ai_[size_t(q++)] = cam_col(lay.colidx[k], a);
        for (int c = 0; c < pnp; ++c) Ai_[size_t(q++)] = pt_col(i, c);
      }

    ldl_.emplace(N_, Ap_.data(), Ai_.data());
    x_.resize(size_t(N_));
    W_.resize(size_t(cnp) * size_t(pnp));
  }

  StepStatus solve(const NormalEquations &ne, double mu, double *dp) override {
    const Layout &lay = lay_;
    const int cnp = lay.cnp, pnp = lay.pnp;
    std::fill(dp, dp + lay.nvars(), 0.0);
    // Diagonal blocks U*_j, V*_i.
    for (int j = lay.mcon; j < lay.m; ++j)
      for (int b = 0; b < cnp; ++b) {
        double *col = Ax_.data() + Ap_[size_t(cam_col(j, b))];
        const double *U = ne.U + i64(j) * cnp * cnp;
        for (int a = 0; a < cnp; ++a) col[a] = U[a * cnp + b] + (a == b ? mu : 0.0);
      }
    for (int i = lay.ncon; i < lay.n; ++i)
      for (int b = 0; b < pnp; ++b) {
        const sslong c = pt_col(i, b);
        double *col = Ax_.data() + Ap_[size_t(c) + 1] - pnp;
        const double *V = ne.V + i64(i) * pnp * pnp;
        for (int a = 0; a < pnp; ++a) col[a] = V[a * pnp + b] + (a == b ? mu : 0.0);
      }
    // Off-diagonal W_ij in both triangles.
    double *W = W_.data();
    for (int i = lay.ncon; i < lay.n; ++i)
      for (int k = lay.rowptr[i]; k < lay.rowptr[i + 1]; ++k) {
        const int j = lay.colidx[k];
        if (j < lay.mcon) continue;
        form_W(lay, ne.jac, k, W);
        for (int b = 0; b < cnp; ++b) {
          double *col = Ax_.data() + Ap_[size_t(cam_col(j, b))] + cnp + i64(pos_in_cam_[size_t(k)]) * pnp;
          for (int c = 0; c < pnp; ++c) col[c] = W[b * pnp + c];
        }
        for (int b = 0; b < pnp; ++b) {
          double *col = Ax_.data() + Ap_[size_t(pt_col(i, b))] + i64(pos_in_pt_[size_t(k)]) * cnp;
          for (int a = 0; a < cnp; ++a) col[a] = W[a * pnp + b];
        }
      }
    if (!ldl_->factor(Ap_.data(), Ai_.data(), Ax_.data())) return StepStatus::Failed;
    for (int j = lay.mcon; j < lay.m; ++j)
      for (int a = 0; a < cnp; ++a) x_[size_t(cam_col(j, a))] = ne.ea[i64(j) * cnp + a];
    for (int i = lay.ncon; i < lay.n; ++i)
      for (int a = 0; a < pnp; ++a) x_[size_t(pt_col(i, a))] = ne.eb[i64(i) * pnp + a];
    const bool finite = ldl_->solve(x_.data());
    for (int j = lay.mcon; j < lay.m; ++j)
      for (int a = 0; a < cnp; ++a) dp[lay.a_off(j) + a] = x_[size_t(cam_col(j, a))];
    for (int i = lay.ncon; i < lay.n; ++i)
      for (int a = 0; a < pnp; ++a) dp[lay.b_off(i) + a] = x_[size_t(pt_col(i, a))];
    return finite ? StepStatus::Solved : StepStatus::Failed;
  }

 private:
  sslong cam_col(int j, int a) const { return sslong(j - lay_.mcon) * lay_.cnp + a; }
  sslong pt_col(int i, int a) const { return nS_ + sslong(i - lay_.ncon) * lay_.pnp + a; }

  const Layout &lay_;
  i64 nS_ = 0, N_ = 0;
  std::vector<int> pos_in_cam_, pos_in_pt_;
  std::vector<sslong> Ap_, Ai_;
  std::vector<double> Ax_, x_, W_;
  std::optional<LdlFactor> ldl_;
};

// The same over shared unknowns (camera_map.h): the columns are the unknowns, then the free
// points' parameters. An unknown's column holds the unknowns of the blocks its block shares a
// camera with (U's blocks over the unknowns) and the points that see its block (Z's); a
// point's, the unknowns of its blocks and itself. The values are put in place by looking
// each entry up in its column, which costs a logarithm per entry over LdlAmdSolver's fixed
// positions: this solver is the whole-system reference, not the fast one, and LdlAmdSolver
// stays a class of its own so that sba 1.6's layout keeps those fixed positions.
class MappedLdlAmdSolver final : public StepSolver {
 public:
  explicit MappedLdlAmdSolver(const SolveContext &ctx) : ctx_(ctx), lay_(ctx.lay), schur_(ctx.lay, 1) {
    const Layout &lay = lay_;
    const CameraMap &map = lay.cams;
    const int pnp = lay.pnp, nb = map.nblocks();
    nS_ = map.unknowns();
    N_ = nS_ + i64(lay.free_pts()) * pnp;
    // Per block, the blocks it shares a camera with and the points that see it.
    std::vector<std::vector<int>> coupled(static_cast<size_t>(nb)), points(static_cast<size_t>(nb));
    for (int j = lay.mcon; j < lay.m; ++j)
      for (const int *q = map.cam_blocks_begin(j); q != map.cam_blocks_end(j); ++q)
        coupled[size_t(*q)].insert(coupled[size_t(*q)].end(), map.cam_blocks_begin(j), map.cam_blocks_end(j));
    for (int i = lay.ncon; i < lay.n && pnp > 0; ++i)
      for (int s = 0; s < map.point_nblocks(i); ++s) points[size_t(map.point_blocks(i)[s])].push_back(i);
    std::vector<std::vector<sslong>> cols(static_cast<size_t>(N_));
    for (int B = 0; B < nb; ++B) {
      std::vector<int> &c = coupled[size_t(B)];
      std::sort(c.begin(), c.end());
      c.erase(std::unique(c.begin(), c.end()), c.end());
      std::vector<sslong> rows;
      for (int b : c)
        for (i64 u = map.block_start(b); u < map.block_start(b + 1); ++u) rows.push_back(sslong(u));
      for (int i : points[size_t(B)])
        for (int a = 0; a < pnp; ++a) rows.push_back(pt_col(i, a));
      for (i64 u = map.block_start(B); u < map.block_start(B + 1); ++u) cols[size_t(u)] = rows;
    }
    for (int i = lay.ncon; i < lay.n && pnp > 0; ++i) {
      std::vector<sslong> rows;
      for (int s = 0; s < map.point_nblocks(i); ++s) {
        const int b = map.point_blocks(i)[s];
        for (i64 u = map.block_start(b); u < map.block_start(b + 1); ++u) rows.push_back(sslong(u));
      }
      for (int a = 0; a < pnp; ++a) rows.push_back(pt_col(i, a));
      for (int a = 0; a < pnp; ++a) cols[size_t(pt_col(i, a))] = rows;
    }
    Ap_.assign(size_t(N_) + 1, 0);
    for (i64 c = 0; c < N_; ++c) Ap_[size_t(c) + 1] = Ap_[size_t(c)] + sslong(cols[size_t(c)].size());
    Ai_.resize(size_t(Ap_[size_t(N_)]));
    for (i64 c = 0; c < N_; ++c) std::copy(cols[size_t(c)].begin(), cols[size_t(c)].end(), Ai_.begin() + Ap_[size_t(c)]);
    cols.clear();
    Ax_.resize(Ai_.size());
    ldl_.emplace(N_, Ap_.data(), Ai_.data());
    x_.resize(size_t(N_));
    Zt_.resize(size_t(schur_.max_couplings()) + 1);
    W_.resize(size_t(pnp) * size_t(lay.cnp) + 1);
  }

  StepStatus solve(const NormalEquations &ne, double mu, double *dp) override {
    const Layout &lay = lay_;
    const CameraMap &map = lay.cams;
    const int cnp = lay.cnp, pnp = lay.pnp;
    std::fill(dp, dp + lay.nvars(), 0.0);
    std::fill(Ax_.begin(), Ax_.end(), 0.0);
    for (int j = lay.mcon; j < lay.m; ++j) {
      const double *U = ne.U + i64(j) * cnp * cnp;
      for (int a = 0; a < cnp; ++a) {
        const int ua = map.unknown(j, a);
        if (ua < 0) continue;
        for (int b = 0; b < cnp; ++b) {
          const int ub = map.unknown(j, b);
          if (ub >= 0) at(ua, ub) += U[a * cnp + b];
        }
      }
    }
    for (i64 u = 0; u < nS_; ++u) at(u, u) += mu;
    std::vector<i64> zoff;
    for (int i = lay.ncon; i < lay.n && pnp > 0; ++i) {
      const int nF = map.point_nblocks(i);
      zoff.assign(size_t(nF) + 1, 0);
      for (int s = 0; s < nF; ++s) zoff[size_t(s) + 1] = zoff[size_t(s)] + i64(map.block_size(map.point_blocks(i)[s])) * pnp;
      schur_.point_couplings(ne.jac, i, nF, zoff.data(), Zt_.data(), W_.data());
      for (int s = 0; s < nF; ++s) {
        const int b = map.point_blocks(i)[s], n = map.block_size(b);
        for (int d = 0; d < pnp; ++d)
          for (int o = 0; o < n; ++o) {
            const double z = Zt_[size_t(zoff[size_t(s)] + d * n + o)];
            at(map.block_start(b) + o, pt_col(i, d)) = z;
            at(pt_col(i, d), map.block_start(b) + o) = z;
          }
      }
      const double *V = ne.V + i64(i) * pnp * pnp;
      for (int a = 0; a < pnp; ++a)
        for (int b = 0; b < pnp; ++b) at(pt_col(i, a), pt_col(i, b)) = V[a * pnp + b] + (a == b ? mu : 0.0);
    }
    if (!ldl_->factor(Ap_.data(), Ai_.data(), Ax_.data())) return StepStatus::Failed;
    map.reduce(ne.ea, x_.data());
    for (int i = lay.ncon; i < lay.n; ++i)
      for (int a = 0; a < pnp; ++a) x_[size_t(pt_col(i, a))] = ne.eb[i64(i) * pnp + a];
    if (!ldl_->solve(x_.data())) return StepStatus::Failed;
    map.expand(x_.data(), -0.0, dp);
    for (int i = lay.ncon; i < lay.n; ++i)
      for (int a = 0; a < pnp; ++a) dp[lay.b_off(i) + a] = x_[size_t(pt_col(i, a))];
    return StepStatus::Solved;
  }

 private:
  sslong pt_col(int i, int a) const { return nS_ + sslong(i - lay_.ncon) * lay_.pnp + a; }
  // Entry (r, c) of the matrix, which the pattern holds.
  double &at(sslong r, sslong c) {
    const sslong *first = Ai_.data() + Ap_[size_t(c)], *last = Ai_.data() + Ap_[size_t(c) + 1];
    return Ax_[size_t(std::lower_bound(first, last, r) - Ai_.data())];
  }

  SolveContext ctx_;
  const Layout &lay_;
  MappedSchur schur_;
  i64 nS_ = 0, N_ = 0;
  std::vector<sslong> Ap_, Ai_;
  std::vector<double> Ax_, x_, Zt_, W_;
  std::optional<LdlFactor> ldl_;
};

}  // namespace

std::unique_ptr<StepSolver> make_ldl_amd_solver(const SolveContext &ctx) {
  if (!ctx.lay.cams.per_camera()) return std::make_unique<MappedLdlAmdSolver>(ctx);
  return std::make_unique<LdlAmdSolver>(ctx);
}

}  // namespace sba
