// SPDX-License-Identifier: BSD-3-Clause
// The callback models: the caller's func/fjac or proj/projac behind Model, called on one
// thread or, when the caller allows it, on several, and the finite-difference Jacobians.
#include "model.h"

#include <algorithm>
#include <vector>

#include "parallel.h"

namespace sba {

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
      : lay_(lay), cb_(cb), concurrent_(concurrent), maxtrack_(longest_track(lay)) {}

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
    points([&](int, int i) {
      for (int k = lay_.rowptr[i]; k < lay_.rowptr[i + 1]; ++k) analytic_block(p, k, i, jac + i64(k) * lay_.jblk());
    });
  }
  // A projection depends only on its own camera and point, so each is differenced against
  // those blocks alone: cnp + pnp proj calls per projection. The perturbations are made in
  // copies of a_j and b_i: other threads may be reading the same camera.
  void fd_jacobian(double *p, const double *hx, double *jac) override {
    const size_t T = rows_.size() - 1;
    std::vector<std::vector<double>> scratch(T, std::vector<double>(size_t(lay_.mnp + lay_.cnp + lay_.pnp)));
    points([&](int t, int i) {
      for (int k = lay_.rowptr[i]; k < lay_.rowptr[i + 1]; ++k)
        fd_block(p, hx, k, i, jac + i64(k) * lay_.jblk(), scratch[size_t(t)].data());
    });
  }
  bool single() const override { return true; }
  void point_jacobians(double *p, const double *hx, const i64 *chunks, int nchunks, PointSink sink) override {
    by_points(p, hx, chunks, nchunks, sink, true);
  }
  void point_projections(double *p, const i64 *chunks, int nchunks, PointSink sink) override {
    by_points(p, nullptr, chunks, nchunks, sink, false);
  }

 private:
  // point_jacobians (blocks) or point_projections: a point's blocks and, without hx, its
  // projections, made in one thread's scratch and handed to sink.
  void by_points(double *p, const double *hx, const i64 *chunks, int nchunks, PointSink sink, bool blocks) {
    const int jb = blocks ? lay_.jblk() : 0, mnp = lay_.mnp;
    const int fd = lay_.mnp + lay_.cnp + lay_.pnp;
    const size_t per = size_t(maxtrack_) * size_t(jb + (hx ? 0 : mnp)) + size_t(fd);
    const size_t T = pool_ ? size_t(pool_->size()) : 1;
    std::vector<std::vector<double>> scratch(T, std::vector<double>(per));
    const auto run = [&](int t, i64 c0, i64 c1) {
      double *blk = scratch[size_t(t)].data(), *f = hx ? nullptr : blk + i64(maxtrack_) * jb;
      double *xp = blk + i64(maxtrack_) * (jb + (hx ? 0 : mnp));
      for (i64 c = c0; c < c1; ++c)
        for (i64 i = chunks[c]; i < chunks[c + 1]; ++i) {
          const int r0 = lay_.rowptr[size_t(i)];
          for (int k = r0; k < lay_.rowptr[size_t(i) + 1]; ++k) {
            if (f) {
              const int j = lay_.colidx[size_t(k)];
              cb_.proj(cb_, j, int(i), aj(p, j), bi(p, int(i)), f + i64(k - r0) * mnp);
            }
            if (!blocks) continue;
            if (cb_.projac)
              analytic_block(p, k, int(i), blk + i64(k - r0) * jb);
            else
              fd_block(p, hx, k, int(i), blk + i64(k - r0) * jb, xp);
          }
          sink.fn(sink.ctx, int(c), int(i), blocks ? blk : nullptr, f);
        }
    };
    if (pool_)
      pool_->for_range_t(nchunks, run);
    else
      run(0, 0, nchunks);
  }

  // Projection k's blocks (of point i) into blk, from the callback.
  void analytic_block(double *p, int k, int i, double *blk) {
    const int j = lay_.colidx[size_t(k)];
    cb_.projac(cb_, j, i, aj(p, j), bi(p, i), blk, blk + lay_.mnp * lay_.cnp);
  }
  // The same by forward differences from f(p) in hx (xp: mnp + cnp + pnp scratch).
  void fd_block(double *p, const double *hx, int k, int i, double *blk, double *xp) {
    const int mnp = lay_.mnp, cnp = lay_.cnp, pnp = lay_.pnp, j = lay_.colidx[size_t(k)];
    double *a = xp + mnp, *b = a + cnp;
    if (cnp) std::copy_n(p + lay_.a_off(j), cnp, a);
    if (pnp) std::copy_n(p + lay_.b_off(i), pnp, b);
    const double *x0 = hx + i64(k) * mnp;
    std::fill(blk, blk + lay_.jblk(), 0.0);
    if (lay_.cam_free(j))
      for (int l = 0; l < cnp; ++l) diff_column(j, i, a, b, a + l, x0, xp, blk + l, cnp);
    if (lay_.pt_free(i))
      for (int l = 0; l < pnp; ++l) diff_column(j, i, a, b, b + l, x0, xp, blk + mnp * cnp + l, pnp);
  }

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

  // The most projections of one point: the size of by_points' scratch.
  static int longest_track(const Layout &lay) {
    int t = 0;
    for (int i = 0; i < lay.n; ++i) t = std::max(t, lay.rowptr[size_t(i) + 1] - lay.rowptr[size_t(i)]);
    return t;
  }

  const Layout &lay_;
  SimpleCallbacks cb_;
  bool concurrent_;
  int maxtrack_;
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
