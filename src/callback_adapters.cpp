// SPDX-License-Identifier: BSD-3-Clause
#include "callback_adapters.h"

namespace sba {
namespace {

void motstr_proj(const SimpleCallbacks &cb, int j, int i, double *aj, double *bi, double *xij) {
  reinterpret_cast<MotStrProj>(cb.user_proj)(j, i, aj, bi, xij, cb.adata);
}
void motstr_jac(const SimpleCallbacks &cb, int j, int i, double *aj, double *bi, double *A,
                double *B) {
  reinterpret_cast<MotStrJac>(cb.user_projac)(j, i, aj, bi, A, B, cb.adata);
}
void mot_proj(const SimpleCallbacks &cb, int j, int i, double *aj, double *, double *xij) {
  reinterpret_cast<OneBlockProj>(cb.user_proj)(j, i, aj, xij, cb.adata);
}
void mot_jac(const SimpleCallbacks &cb, int j, int i, double *aj, double *, double *A, double *) {
  reinterpret_cast<OneBlockJac>(cb.user_projac)(j, i, aj, A, cb.adata);
}
void str_proj(const SimpleCallbacks &cb, int j, int i, double *, double *bi, double *xij) {
  reinterpret_cast<OneBlockProj>(cb.user_proj)(j, i, bi, xij, cb.adata);
}
void str_jac(const SimpleCallbacks &cb, int j, int i, double *, double *bi, double *, double *B) {
  reinterpret_cast<OneBlockJac>(cb.user_projac)(j, i, bi, B, cb.adata);
}

// proj and projac of one of the three simple shapes, called through tproj and tjac (the
// adapters above).
template <class Proj, class Jac>
UserCallbacks simple_callbacks(Proj proj, Jac projac, void *adata,
                               decltype(SimpleCallbacks::proj) tproj,
                               decltype(SimpleCallbacks::projac) tjac) {
  UserCallbacks cb;
  cb.simple = true;
  cb.per_projection = {tproj, projac ? tjac : nullptr, reinterpret_cast<AnyFn>(proj),
                       reinterpret_cast<AnyFn>(projac), adata};
  return cb;
}

}  // namespace

UserCallbacks expert_callbacks(ExpertFunc func, ExpertFunc fjac, void *adata) {
  UserCallbacks cb;
  cb.func = func;
  cb.fjac = fjac;
  cb.adata = adata;
  return cb;
}

UserCallbacks motstr_callbacks(MotStrProj proj, MotStrJac projac, void *adata) {
  return simple_callbacks(proj, projac, adata, motstr_proj, motstr_jac);
}

UserCallbacks mot_callbacks(OneBlockProj proj, OneBlockJac projac, void *adata) {
  return simple_callbacks(proj, projac, adata, mot_proj, mot_jac);
}

UserCallbacks str_callbacks(OneBlockProj proj, OneBlockJac projac, void *adata) {
  return simple_callbacks(proj, projac, adata, str_proj, str_jac);
}

std::unique_ptr<Model> make_model(const Layout &lay, const UserCallbacks &cb, bool concurrent) {
  if (cb.simple) return make_simple_model(lay, cb.per_projection, concurrent);
  return make_expert_model(lay, cb.func, cb.fjac, cb.adata, concurrent);
}

}  // namespace sba
