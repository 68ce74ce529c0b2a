// The visibility index, the callback models and the finite-difference Jacobians.
#include <algorithm>
#include <climits>
#include <cmath>
#include <string>

#include "core.h"

namespace sba {

namespace {

void set_sizes(Layout &lay, Mode mode, int n, int m, int mcon, int ncon, int cnp, int pnp,
               int mnp) {
  lay.mode = mode;
  lay.n = n;
  lay.m = m;
  lay.mcon = mcon;
  lay.ncon = ncon;
  lay.cnp = cnp;
  lay.pnp = pnp;
  lay.mnp = mnp;
}

// The column (camera) index and the callbacks' view, once rowptr/colidx/val are filled.
void finish_layout(Layout &lay) {
  const int n = lay.n, m = lay.m;
  lay.colptr.assign(size_t(m) + 1, 0);
  for (i64 k = 0; k < lay.nvis; ++k) ++lay.colptr[size_t(lay.colidx[size_t(k)]) + 1];
  for (int j = 0; j < m; ++j) lay.colptr[size_t(j) + 1] += lay.colptr[size_t(j)];
  lay.colrow.resize(size_t(lay.nvis));
  lay.colk.resize(size_t(lay.nvis));
  std::vector<int> fill(lay.colptr.begin(), lay.colptr.end() - 1);
  for (int i = 0; i < n; ++i)
    for (int kk = lay.rowptr[i]; kk < lay.rowptr[i + 1]; ++kk) {
      const int slot = fill[size_t(lay.colidx[size_t(kk)])]++;
      lay.colrow[size_t(slot)] = i;
      lay.colk[size_t(slot)] = kk;
    }
  lay.idx.nr = n;
  lay.idx.nc = m;
  lay.idx.nnz = int(lay.nvis);
  lay.idx.val = lay.val.data();
  lay.idx.colidx = lay.colidx.data();
  lay.idx.rowptr = lay.rowptr.data();
  lay.rcidxs.assign(size_t(std::max(n, m)), 0);
  lay.rcsubs.assign(size_t(std::max(n, m)), 0);
}

}  // namespace

bool build_layout(Layout &lay, Mode mode, int n, int m, int mcon, int ncon, int cnp, int pnp,
                  int mnp, const char *vmask, std::string *msg) {
  set_sizes(lay, mode, n, m, mcon, ncon, cnp, pnp, mnp);
  const i64 cells = i64(n) * m;
  i64 nvis = 0;
  for (i64 c = 0; c < cells; ++c) nvis += vmask[c] != 0;
  lay.nvis = nvis;
  if (nvis == 0) {
    *msg = "vmask has no visible projection (nvis == 0)";
    return false;
  }
  // Callbacks written against the int API index x, hx, p and the Jacobian with int
  // arithmetic; refuse what would overflow there instead of letting them corrupt memory.
  const i64 jac_len = nvis * lay.jblk();
  if (nvis * mnp > INT_MAX || jac_len > INT_MAX || lay.nvars() > INT_MAX) {
    *msg = "problem too large for the int-sized sba 1.6 API (" + std::to_string(nvis) +
           " projections, " + std::to_string(lay.nvars()) +
           " parameters): use the sba_*_vis entry points of sba_ext.h";
    return false;
  }
  lay.rowptr.assign(size_t(n) + 1, 0);
  lay.colidx.resize(size_t(nvis));
  lay.val.resize(size_t(nvis));
  int k = 0;
  for (int i = 0; i < n; ++i) {
    lay.rowptr[size_t(i)] = k;
    const char *row = vmask + i64(i) * m;
    for (int j = 0; j < m; ++j) {
      if (!row[j]) continue;
      lay.colidx[size_t(k)] = j;
      lay.val[size_t(k)] = k;
      ++k;
    }
  }
  lay.rowptr[size_t(n)] = k;
  finish_layout(lay);
  return true;
}

bool build_layout(Layout &lay, Mode mode, int n, int m, int mcon, int ncon, int cnp, int pnp,
                  int mnp, const sba_visibility &vis, std::string *msg) {
  set_sizes(lay, mode, n, m, mcon, ncon, cnp, pnp, mnp);
  if (vis.nvis <= 0 || vis.nvis > INT_MAX || !vis.point || !vis.camera) {
    *msg = "vis must list between 1 and INT_MAX pairs (got " + std::to_string(vis.nvis) +
           ") with non-NULL point and camera arrays";
    return false;
  }
  const i64 nvis = vis.nvis;
  lay.nvis = nvis;
  lay.rowptr.assign(size_t(n) + 1, 0);
  lay.colidx.resize(size_t(nvis));
  lay.val.resize(size_t(nvis));
  for (i64 k = 0; k < nvis; ++k) {
    const int i = vis.point[k], j = vis.camera[k];
    if (i < 0 || i >= n || j < 0 || j >= m) {
      *msg = "vis pair " + std::to_string(k) + " (point " + std::to_string(i) + ", camera " +
             std::to_string(j) + ") is out of range";
      return false;
    }
    if (k > 0 && (i < vis.point[k - 1] || (i == vis.point[k - 1] && j <= vis.camera[k - 1]))) {
      *msg = "vis pair " + std::to_string(k) +
             " is out of order: pairs must be sorted by point, then camera, each once";
      return false;
    }
    ++lay.rowptr[size_t(i) + 1];
    lay.colidx[size_t(k)] = j;
    lay.val[size_t(k)] = int(k);
  }
  for (int i = 0; i < n; ++i) lay.rowptr[size_t(i) + 1] += lay.rowptr[size_t(i)];
  finish_layout(lay);
  return true;
}

namespace {

double fd_step(double v) { return std::max(SBA_DELTA_SCALE * std::fabs(v), SBA_MIN_DELTA); }

class ExpertModel final : public Model {
 public:
  ExpertModel(Layout &lay, ExpertFunc func, ExpertFunc fjac, void *adata)
      : lay_(lay), func_(func), fjac_(fjac), adata_(adata) {}

  void eval(double *p, double *hx) override {
    func_(p, &lay_.idx, lay_.rcidxs.data(), lay_.rcsubs.data(), hx, adata_);
  }
  bool has_jacobian() const override { return fjac_ != nullptr; }
  void jacobian(double *p, double *jac) override {
    fjac_(p, &lay_.idx, lay_.rcidxs.data(), lay_.rcsubs.data(), jac, adata_);
  }
  i64 fd_jacobian(double *p, const double *hx, double *jac) override {
    return fd_jacobian_grouped(lay_, *this, p, hx, jac);
  }

 private:
  Layout &lay_;
  ExpertFunc func_, fjac_;
  void *adata_;
};

class SimpleModel final : public Model {
 public:
  SimpleModel(const Layout &lay, const SimpleCallbacks &cb) : lay_(lay), cb_(cb) {}

  void eval(double *p, double *hx) override {
    for (int i = 0; i < lay_.n; ++i)
      for (int k = lay_.rowptr[i]; k < lay_.rowptr[i + 1]; ++k) {
        const int j = lay_.colidx[k];
        cb_.proj(cb_, j, i, aj(p, j), bi(p, i), hx + i64(k) * lay_.mnp);
      }
  }
  bool has_jacobian() const override { return cb_.projac != nullptr; }
  void jacobian(double *p, double *jac) override {
    const int asz = lay_.mnp * lay_.cnp;
    for (int i = 0; i < lay_.n; ++i)
      for (int k = lay_.rowptr[i]; k < lay_.rowptr[i + 1]; ++k) {
        const int j = lay_.colidx[k];
        double *blk = jac + i64(k) * lay_.jblk();
        cb_.projac(cb_, j, i, aj(p, j), bi(p, i), blk, blk + asz);
      }
  }
  // A projection depends only on its own camera and point, so each is differenced against
  // those blocks alone: cnp + pnp proj calls per projection.
  i64 fd_jacobian(double *p, const double *hx, double *jac) override {
    const int mnp = lay_.mnp, cnp = lay_.cnp, pnp = lay_.pnp;
    std::vector<double> xp(static_cast<size_t>(mnp));
    for (int i = 0; i < lay_.n; ++i)
      for (int k = lay_.rowptr[i]; k < lay_.rowptr[i + 1]; ++k) {
        const int j = lay_.colidx[k];
        double *a = aj(p, j), *b = bi(p, i);
        const double *x0 = hx + i64(k) * mnp;
        double *blk = jac + i64(k) * lay_.jblk();
        std::fill(blk, blk + lay_.jblk(), 0.0);
        if (lay_.cam_free(j))
          for (int l = 0; l < cnp; ++l)
            diff_column(j, i, a, b, a + l, x0, xp.data(), blk + l, cnp);
        if (lay_.pt_free(i))
          for (int l = 0; l < pnp; ++l)
            diff_column(j, i, a, b, b + l, x0, xp.data(), blk + mnp * cnp + l, pnp);
      }
    return i64(lay_.free_cams() > 0 ? cnp : 0) + (lay_.free_pts() > 0 ? pnp : 0);
  }

 private:
  double *aj(double *p, int j) const { return lay_.cnp ? p + lay_.a_off(j) : nullptr; }
  double *bi(double *p, int i) const { return lay_.pnp ? p + lay_.b_off(i) : nullptr; }

  // One Jacobian column of one projection by a forward difference in *v.
  void diff_column(int j, int i, double *a, double *b, double *v, const double *x0, double *xp,
                   double *col, int stride) {
    const double saved = *v, d = fd_step(saved);
    *v = saved + d;
    cb_.proj(cb_, j, i, a, b, xp);
    *v = saved;
    for (int r = 0; r < lay_.mnp; ++r) col[r * stride] = (xp[r] - x0[r]) / d;
  }

  const Layout &lay_;
  SimpleCallbacks cb_;
};

}  // namespace

std::unique_ptr<Model> make_expert_model(Layout &lay, ExpertFunc func, ExpertFunc fjac,
                                         void *adata) {
  return std::make_unique<ExpertModel>(lay, func, fjac, adata);
}

std::unique_ptr<Model> make_simple_model(const Layout &lay, const SimpleCallbacks &cb) {
  return std::make_unique<SimpleModel>(lay, cb);
}

i64 fd_jacobian_grouped(const Layout &lay, Model &model, double *p, const double *hx,
                        double *jac) {
  const int mnp = lay.mnp, cnp = lay.cnp, pnp = lay.pnp, jblk = lay.jblk();
  std::fill(jac, jac + lay.nvis * jblk, 0.0);
  std::vector<double> hxp(size_t(lay.nvis * mnp));
  std::vector<double> saved(size_t(std::max(lay.n, lay.m))), delta(saved.size());
  i64 evals = 0;

  // Perturbing parameter l of every free camera at once is exact for a Jacobian column
  // group because projection (i,j) depends on camera j alone; likewise for points.
  for (int l = 0; l < cnp && lay.free_cams() > 0; ++l) {
    for (int j = lay.mcon; j < lay.m; ++j) {
      double &v = p[lay.a_off(j) + l];
      saved[j] = v;
      delta[j] = fd_step(v);
      v += delta[j];
    }
    model.eval(p, hxp.data());
    ++evals;
    for (int j = lay.mcon; j < lay.m; ++j) p[lay.a_off(j) + l] = saved[j];
    for (i64 k = 0; k < lay.nvis; ++k) {
      const int j = lay.colidx[k];
      if (j < lay.mcon) continue;
      double *col = jac + k * jblk + l;
      for (int r = 0; r < mnp; ++r)
        col[r * cnp] = (hxp[k * mnp + r] - hx[k * mnp + r]) / delta[j];
    }
  }
  for (int l = 0; l < pnp && lay.free_pts() > 0; ++l) {
    for (int i = lay.ncon; i < lay.n; ++i) {
      double &v = p[lay.b_off(i) + l];
      saved[i] = v;
      delta[i] = fd_step(v);
      v += delta[i];
    }
    model.eval(p, hxp.data());
    ++evals;
    for (int i = lay.ncon; i < lay.n; ++i) p[lay.b_off(i) + l] = saved[i];
    for (int i = lay.ncon; i < lay.n; ++i)
      for (int k = lay.rowptr[i]; k < lay.rowptr[i + 1]; ++k) {
        double *col = jac + i64(k) * jblk + mnp * cnp + l;
        for (int r = 0; r < mnp; ++r)
          col[r * pnp] = (hxp[i64(k) * mnp + r] - hx[i64(k) * mnp + r]) / delta[i];
      }
  }
  return evals;
}

void Summary::to_info(double *info) const {
  if (!info) return;
  info[0] = err0;
  info[1] = err;
  info[2] = grad_inf;
  info[3] = dp2;
  info[4] = mu_ratio;
  info[5] = iterations;
  info[6] = reason;
  info[7] = double(nfev);
  info[8] = double(njev);
  info[9] = double(nlinsys);
}

}  // namespace sba
