// SPDX-License-Identifier: BSD-3-Clause
// The visibility index, the callback models and the finite-difference Jacobians.
#include <algorithm>
#include <climits>
#include <cmath>
#include <string>

#include "core.h"
#include "parallel.h"

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

// The camera counts and the callbacks' view, once rowptr/colidx/val are filled.
void finish_layout(Layout &lay) {
  const int n = lay.n, m = lay.m;
  lay.colptr.assign(size_t(m) + 1, 0);
  for (i64 k = 0; k < lay.nvis; ++k) ++lay.colptr[size_t(lay.colidx[size_t(k)]) + 1];
  for (int j = 0; j < m; ++j) lay.colptr[size_t(j) + 1] += lay.colptr[size_t(j)];
  lay.idx.nr = n;
  lay.idx.nc = m;
  lay.idx.nnz = int(lay.nvis);
  lay.idx.val = lay.val.data();
  lay.idx.colidx = lay.colidx.data();
  lay.idx.rowptr = lay.rowptr.data();
}

}  // namespace

void by_camera(const Layout &lay, std::vector<int> *row, std::vector<int> *k) {
  row->resize(size_t(lay.nvis));
  if (k) k->resize(size_t(lay.nvis));
  std::vector<int> fill(lay.colptr.begin(), lay.colptr.end() - 1);
  for (int i = 0; i < lay.n; ++i)
    for (int kk = lay.rowptr[i]; kk < lay.rowptr[i + 1]; ++kk) {
      const int slot = fill[size_t(lay.colidx[size_t(kk)])]++;
      (*row)[size_t(slot)] = i;
      if (k) (*k)[size_t(slot)] = kk;
    }
}

namespace {

// a * b for non-negative sizes, saturating instead of wrapping: a count of visible cells can
// approach 2^62, so even 64-bit products of three sizes could wrap.
i64 mul(i64 a, i64 b) {
  i64 r;
  return __builtin_mul_overflow(a, b, &r) ? INT64_MAX : r;
}
i64 add(i64 a, i64 b) {
  i64 r;
  return __builtin_add_overflow(a, b, &r) ? INT64_MAX : r;
}

// One product of sizes and what it sizes, for the message.
struct Extent {
  const char *what;  // e.g. "the Jacobian"
  const char *expr;  // e.g. "nvis*mnp*(cnp+pnp)"
  i64 value;
};

std::string too_large(const Extent &e, const char *advice) {
  return std::string("problem too large for the int-sized sba 1.6 API: ") + e.what + " (" +
         e.expr + " = " + std::to_string(e.value) + ") exceeds INT_MAX = " +
         std::to_string(INT_MAX) + advice;
}

// Sizes of single blocks: the library and every callback API index within a block (and
// form block strides such as mnp*cnp) with int arithmetic, whichever entry point is used.
// Checked from the arguments alone, before the index is built or anything is allocated.
std::string check_block_sizes(const Layout &lay, bool covx) {
  const i64 cnp = lay.cnp, pnp = lay.pnp, mnp = lay.mnp;
  const Extent blocks[] = {
      {"a projection's Jacobian block", "mnp*(cnp+pnp)", mul(mnp, cnp + pnp)},
      {"a camera block U_j", "cnp*cnp", mul(cnp, cnp)},
      {"a point block V_i", "pnp*pnp", mul(pnp, pnp)},
      {"a block W_ij", "cnp*pnp", mul(cnp, pnp)},
      {"a measurement covariance block", "mnp*mnp", covx ? mul(mnp, mnp) : 0},
  };
  for (const Extent &e : blocks)
    if (e.value > INT_MAX) return too_large(e, "");
  return {};
}

// Whole-vector sizes for the vmask entry points: 1.6-style callbacks index p, x, hx, covx
// and the Jacobian with int offsets, so each of them must have at most INT_MAX entries.
std::string check_vector_sizes(const Layout &lay, i64 nvis, bool covx) {
  const i64 n = lay.n, m = lay.m, cnp = lay.cnp, pnp = lay.pnp, mnp = lay.mnp;
  const Extent vectors[] = {
      {"the camera parameters", "m*cnp", mul(m, cnp)},
      {"the point parameters", "n*pnp", mul(n, pnp)},
      {"p", "m*cnp+n*pnp", add(mul(m, cnp), mul(n, pnp))},
      {"the visible projections", "nvis", nvis},
      {"the measurements x", "nvis*mnp", mul(nvis, mnp)},
      {"the Jacobian", "nvis*mnp*(cnp+pnp)", mul(mul(nvis, mnp), cnp + pnp)},
      {"covx", "nvis*mnp*mnp", covx ? mul(mul(nvis, mnp), mnp) : 0},
  };
  for (const Extent &e : vectors)
    if (e.value > INT_MAX) return too_large(e, ": use the sba_*_vis entry points of sba_ext.h");
  return {};
}

}  // namespace

bool build_layout(Layout &lay, Mode mode, int n, int m, int mcon, int ncon, int cnp, int pnp,
                  int mnp, const char *vmask, std::string *msg, bool covx) {
  set_sizes(lay, mode, n, m, mcon, ncon, cnp, pnp, mnp);
  // Refuse what would overflow an int offset (in the callbacks or in our own block
  // arithmetic) before anything of that size is read, allocated or handed to a callback.
  *msg = check_block_sizes(lay, covx);
  if (!msg->empty()) return false;
  const i64 cells = i64(n) * m;
  i64 nvis = 0;
  for (i64 c = 0; c < cells; ++c) nvis += vmask[c] != 0;
  lay.nvis = nvis;
  if (nvis == 0) {
    *msg = "vmask has no visible projection (nvis == 0)";
    return false;
  }
  *msg = check_vector_sizes(lay, nvis, covx);
  if (!msg->empty()) return false;
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
                  int mnp, const sba_visibility &vis, std::string *msg, bool covx) {
  set_sizes(lay, mode, n, m, mcon, ncon, cnp, pnp, mnp);
  *msg = check_block_sizes(lay, covx);
  if (!msg->empty()) return false;
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

// Rows [rows[t], rows[t+1]) of the index for thread slot t: equal numbers of projections.
std::vector<int> split_rows(const Layout &lay, int parts) {
  std::vector<int> rows(size_t(parts) + 1, lay.n);
  rows[0] = 0;
  int t = 1;
  for (int i = 0; i < lay.n && t < parts; ++i)
    while (t < parts && lay.rowptr[size_t(i) + 1] >= lay.nvis * t / parts) rows[size_t(t++)] = i + 1;
  return rows;
}

class ExpertModel final : public Model {
 public:
  // The callbacks get the layout's index (a copy of its view: they take non-const pointers
  // but only read) and scratch arrays of their own, max(n, m) ints each.
  ExpertModel(const Layout &lay, ExpertFunc func, ExpertFunc fjac, void *adata, bool concurrent)
      : lay_(lay), idx_(lay.idx), func_(func), fjac_(fjac), adata_(adata), concurrent_(concurrent),
        rcidxs_(size_t(std::max(lay.n, lay.m)), 0), rcsubs_(rcidxs_.size(), 0) {}

  void use_threads(ThreadPool *pool) override {
    pool_ = concurrent_ && pool && pool->size() > 1 ? pool : nullptr;
    if (!pool_) {
      parts_.clear();
      return;
    }
    // One index per thread that shows only its rows (the others are empty rows), so that a
    // callback walking the index by rows computes exactly its share; plus its own scratch,
    // but for the calling thread (the pool's last), which has the layout's.
    const int T = pool_->size();
    const std::vector<int> rows = split_rows(lay_, T);
    parts_.assign(size_t(T), Part{});
    for (int t = 0; t < T; ++t) {
      Part &part = parts_[size_t(t)];
      part.rowptr.resize(size_t(lay_.n) + 1);
      const int lo = lay_.rowptr[size_t(rows[size_t(t)])], hi = lay_.rowptr[size_t(rows[size_t(t) + 1])];
      for (int i = 0; i <= lay_.n; ++i) part.rowptr[size_t(i)] = std::min(std::max(lay_.rowptr[size_t(i)], lo), hi);
      part.idx = idx_;
      part.idx.rowptr = part.rowptr.data();
      if (t == T - 1) continue;
      part.rcidxs.assign(rcidxs_.size(), 0);
      part.rcsubs.assign(rcsubs_.size(), 0);
    }
  }

  void eval(double *p, double *hx) override { call(func_, p, hx); }
  bool has_jacobian() const override { return fjac_ != nullptr; }
  void jacobian(double *p, double *jac) override { call(fjac_, p, jac); }
  // Grouped forward differences: perturbing parameter l of every free camera at once is exact
  // for that column group because projection (i,j) depends on camera j alone; likewise for
  // points. So cnp + pnp evaluations give the whole Jacobian. Each is made on a private copy
  // of p (the caller's is never touched), and with concurrent calls allowed the groups are
  // spread over the threads.
  void fd_jacobian(double *p, const double *hx, double *jac) override {
    const Layout &lay = lay_;
    const int mnp = lay.mnp, cnp = lay.cnp, pnp = lay.pnp, jblk = lay.jblk();
    std::fill(jac, jac + lay.nvis * jblk, 0.0);
    const int ncam = lay.free_cams() > 0 ? cnp : 0, npt = lay.free_pts() > 0 ? pnp : 0;
    const int groups = ncam + npt, T = pool_ ? pool_->size() : 1;
    auto work = [&](int t) {
      std::vector<double> pg(p, p + lay.nvars()), hxp(size_t(lay.nvis * mnp));
      for (int g = t; g < groups; g += T) {
        const bool cams = g < ncam;
        const int l = cams ? g : g - ncam;
        const int first = cams ? lay.mcon : lay.ncon, last = cams ? lay.m : lay.n;
        auto at = [&](int o) { return cams ? lay.a_off(o) + l : lay.b_off(o) + l; };
        for (int o = first; o < last; ++o) pg[size_t(at(o))] += fd_step(p[at(o)]);
        func_(pg.data(), &idx_, scratch(t).rcidxs.data(), scratch(t).rcsubs.data(),
              hxp.data(), adata_);
        for (int o = first; o < last; ++o) pg[size_t(at(o))] = p[at(o)];
        for (int i = 0; i < lay.n; ++i)
          for (int k = lay.rowptr[i]; k < lay.rowptr[i + 1]; ++k) {
            const int o = cams ? lay.colidx[k] : i;
            if (o < first) continue;
            const double d = fd_step(p[at(o)]);
            double *col = jac + i64(k) * jblk + (cams ? l : mnp * cnp + l);
            const int stride = cams ? cnp : pnp;
            for (int r = 0; r < mnp; ++r)
              col[r * stride] = (hxp[size_t(i64(k) * mnp + r)] - hx[i64(k) * mnp + r]) / d;
          }
      }
    };
    if (pool_)
      pool_->run(work);
    else
      work(0);
  }

 private:
  struct Part {
    std::vector<int> rowptr, rcidxs, rcsubs;
    sba_crsm idx{};
  };
  struct Scratch {
    std::vector<int> &rcidxs, &rcsubs;
  };
  Scratch scratch(int t) {
    if (!pool_ || t == pool_->size() - 1) return Scratch{rcidxs_, rcsubs_};
    return Scratch{parts_[size_t(t)].rcidxs, parts_[size_t(t)].rcsubs};
  }

  void call(ExpertFunc f, double *p, double *out) {
    if (!pool_) {
      f(p, &idx_, rcidxs_.data(), rcsubs_.data(), out, adata_);
      return;
    }
    pool_->run([&](int t) {
      const Scratch s = scratch(t);
      f(p, &parts_[size_t(t)].idx, s.rcidxs.data(), s.rcsubs.data(), out, adata_);
    });
  }

  const Layout &lay_;
  sba_crsm idx_;
  ExpertFunc func_, fjac_;
  void *adata_;
  bool concurrent_;
  std::vector<int> rcidxs_, rcsubs_;  // the calling thread's scratch
  ThreadPool *pool_ = nullptr;
  std::vector<Part> parts_;
};

class SimpleModel final : public Model {
 public:
  SimpleModel(const Layout &lay, const SimpleCallbacks &cb, bool concurrent)
      : lay_(lay), cb_(cb), concurrent_(concurrent) {}

  void use_threads(ThreadPool *pool) override {
    pool_ = concurrent_ && pool && pool->size() > 1 ? pool : nullptr;
    if (pool_) {
      rows_ = split_rows(lay_, pool_->size());
      return;
    }
    rows_.assign(2, 0);  // within the capacity rows_ was made with: never throws
    rows_[1] = lay_.n;
  }

  void eval(double *p, double *hx) override {
    points([&](int, int i) {
      for (int k = lay_.rowptr[i]; k < lay_.rowptr[i + 1]; ++k) {
        const int j = lay_.colidx[k];
        cb_.proj(cb_, j, i, aj(p, j), bi(p, i), hx + i64(k) * lay_.mnp);
      }
    });
  }
  bool has_jacobian() const override { return cb_.projac != nullptr; }
  void jacobian(double *p, double *jac) override {
    const int asz = lay_.mnp * lay_.cnp;
    points([&](int, int i) {
      for (int k = lay_.rowptr[i]; k < lay_.rowptr[i + 1]; ++k) {
        const int j = lay_.colidx[k];
        double *blk = jac + i64(k) * lay_.jblk();
        cb_.projac(cb_, j, i, aj(p, j), bi(p, i), blk, blk + asz);
      }
    });
  }
  // A projection depends only on its own camera and point, so each is differenced against
  // those blocks alone: cnp + pnp proj calls per projection. The perturbations are made in
  // copies of a_j and b_i: other threads may be reading the same camera.
  void fd_jacobian(double *p, const double *hx, double *jac) override {
    const int mnp = lay_.mnp, cnp = lay_.cnp, pnp = lay_.pnp;
    const size_t T = rows_.size() - 1;
    std::vector<std::vector<double>> scratch(T, std::vector<double>(size_t(mnp + cnp + pnp)));
    points([&](int t, int i) {
      double *xp = scratch[size_t(t)].data(), *a = xp + mnp, *b = a + cnp;
      for (int k = lay_.rowptr[i]; k < lay_.rowptr[i + 1]; ++k) {
        const int j = lay_.colidx[k];
        if (cnp) std::copy_n(p + lay_.a_off(j), cnp, a);
        if (pnp) std::copy_n(p + lay_.b_off(i), pnp, b);
        const double *x0 = hx + i64(k) * mnp;
        double *blk = jac + i64(k) * lay_.jblk();
        std::fill(blk, blk + lay_.jblk(), 0.0);
        if (lay_.cam_free(j))
          for (int l = 0; l < cnp; ++l) diff_column(j, i, a, b, a + l, x0, xp, blk + l, cnp);
        if (lay_.pt_free(i))
          for (int l = 0; l < pnp; ++l)
            diff_column(j, i, a, b, b + l, x0, xp, blk + mnp * cnp + l, pnp);
      }
    });
  }

 private:
  double *aj(double *p, int j) const { return lay_.cnp ? p + lay_.a_off(j) : nullptr; }
  double *bi(double *p, int i) const { return lay_.pnp ? p + lay_.b_off(i) : nullptr; }

  // fn(t, i) for every point, over the threads when the caller allowed concurrent calls.
  template <class Fn>
  void points(Fn fn) {
    if (!pool_) {
      for (int i = 0; i < lay_.n; ++i) fn(0, i);
      return;
    }
    pool_->run([&](int t) {
      for (int i = rows_[size_t(t)]; i < rows_[size_t(t) + 1]; ++i) fn(t, i);
    });
  }

  // One Jacobian column of one projection by a forward difference in *v (a copy).
  void diff_column(int j, int i, double *a, double *b, double *v, const double *x0, double *xp,
                   double *col, int stride) {
    const double saved = *v, d = fd_step(saved);
    *v = saved + d;
    cb_.proj(cb_, j, i, lay_.cnp ? a : nullptr, lay_.pnp ? b : nullptr, xp);
    *v = saved;
    for (int r = 0; r < lay_.mnp; ++r) col[r * stride] = (xp[r] - x0[r]) / d;
  }

  const Layout &lay_;
  SimpleCallbacks cb_;
  bool concurrent_;
  ThreadPool *pool_ = nullptr;
  std::vector<int> rows_{0, 0};
};

}  // namespace

std::unique_ptr<Model> make_expert_model(const Layout &lay, ExpertFunc func, ExpertFunc fjac,
                                         void *adata, bool concurrent) {
  return std::make_unique<ExpertModel>(lay, func, fjac, adata, concurrent);
}

std::unique_ptr<Model> make_simple_model(const Layout &lay, const SimpleCallbacks &cb,
                                         bool concurrent) {
  return std::make_unique<SimpleModel>(lay, cb, concurrent);
}

}  // namespace sba
