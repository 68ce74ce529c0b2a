/* SPDX-License-Identifier: BSD-3-Clause */
// The caller's callbacks behind one interface: the expert drivers' whole-vector func/fjac and
// the simple drivers' per-projection proj/projac, with finite differences where no Jacobian
// is given.
#ifndef SBA_SRC_MODEL_H
#define SBA_SRC_MODEL_H

#include <algorithm>
#include <cmath>
#include <memory>

#include "layout.h"

namespace sba {

// sba 1.6's finite-difference step for a parameter of value v: the drivers' forward
// differences and the Jacobian check's central ones.
inline double fd_step(double v) { return std::max(SBA_DELTA_SCALE * std::fabs(v), SBA_MIN_DELTA); }

// The caller's projection function and (optionally) its Jacobian, over the whole vector.
class ThreadPool;

class Model {
 public:
  virtual ~Model() = default;
  // The pool of the solve; callbacks are called from several of its threads at once only if
  // the caller allowed it (sba_ext_options.parallel_callbacks). Null: the calling thread only.
  virtual void use_threads(ThreadPool *pool) = 0;
  // hx = f(p), every visible projection in measurement order.
  virtual void eval(double *p, double *hx) = 0;
  virtual bool has_jacobian() const = 0;
  // jac = df/dp in the callback layout (per projection: A_ij then B_ij, row-major).
  virtual void jacobian(double *p, double *jac) = 0;
  // Forward-difference Jacobian at p, given hx = f(p); p is not modified. Its evaluations
  // of f are not counted in info[7]: sba 1.6 counts only those of the LM loop.
  virtual void fd_jacobian(double *p, const double *hx, double *jac) = 0;
  // Single precision (Options::single_jacobian) is for a model that makes the Jacobian
  // projection by projection, so that no double copy of the whole Jacobian is ever made.
  virtual bool single() const { return false; }
  // For such a model: the Jacobian at p point by point in double, by the callback or (without
  // one) by differences from f(p) in hx (then not null). Chunk c is the points
  // [chunks[c], chunks[c + 1]), taken in order on one thread; each point's blocks (its
  // projections' A_ij then B_ij, in measurement order, writable) go to sink.fn(sink.ctx, c, i,
  // blocks, f), which may run on several threads at once for different chunks. f is the
  // point's projections f(p) in measurement order, made there by the callback when hx is null
  // (so that f(p) need not be kept between an evaluation and the linearization), else null.
  struct PointSink {
    void (*fn)(void *ctx, int chunk, int i, double *blocks, const double *f);
    void *ctx;
  };
  virtual void point_jacobians(double *p, const double *hx, const i64 *chunks, int nchunks, PointSink sink) {
    (void)p, (void)hx, (void)chunks, (void)nchunks, (void)sink;
  }
  // f(p) by the same chunks, for a solve that does not keep it: each point's projections go
  // to sink.fn(sink.ctx, c, i, nullptr, f).
  virtual void point_projections(double *p, const i64 *chunks, int nchunks, PointSink sink) {
    (void)p, (void)chunks, (void)nchunks, (void)sink;
  }
};

// Lends the solve's pool to the model for the scope of a solve: the model must not keep a
// pointer to a pool that is about to be destroyed.
class ModelThreads {
 public:
  ModelThreads(Model &model, ThreadPool *pool) : model_(model) { model_.use_threads(pool); }
  ~ModelThreads() { model_.use_threads(nullptr); }
  ModelThreads(const ModelThreads &) = delete;
  ModelThreads &operator=(const ModelThreads &) = delete;

 private:
  Model &model_;
};

// The expert drivers' func/fjac.
using ExpertFunc = void (*)(double *p, sba_crsm *idxij, int *rcidxs, int *rcsubs, double *hx,
                            void *adata);
std::unique_ptr<Model> make_expert_model(const Layout &lay, ExpertFunc func, ExpertFunc fjac,
                                         void *adata, bool concurrent);

// The simple drivers' per-projection proj/projac, normalized to the motion+structure shape;
// the adapters in callback_adapters.cpp bridge the mot/str signatures onto it.
using AnyFn = void (*)();  // a user callback of one of the three shapes, cast back to call
struct SimpleCallbacks {
  void (*proj)(const SimpleCallbacks &cb, int j, int i, double *aj, double *bi, double *xij);
  void (*projac)(const SimpleCallbacks &cb, int j, int i, double *aj, double *bi, double *Aij,
                 double *Bij);  // null: finite differences
  AnyFn user_proj;
  AnyFn user_projac;
  void *adata;
};
std::unique_ptr<Model> make_simple_model(const Layout &lay, const SimpleCallbacks &cb,
                                         bool concurrent);

}  // namespace sba

#endif
