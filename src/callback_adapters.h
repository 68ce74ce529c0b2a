/* SPDX-License-Identifier: BSD-3-Clause */
// The callbacks an entry point was given, in one type whatever their shape, made into a Model
// once the problem is known to be valid. The simple drivers' three shapes of proj/projac
// (motion and structure, motion only, structure only) are bridged onto the one the simple
// model calls (model.h's SimpleCallbacks).
#ifndef SBA_SRC_CALLBACK_ADAPTERS_H
#define SBA_SRC_CALLBACK_ADAPTERS_H

#include <memory>

#include "layout.h"
#include "model.h"

namespace sba {

// sba.h's simple-driver callbacks.
using MotStrProj = void (*)(int, int, double *, double *, double *, void *);
using MotStrJac = void (*)(int, int, double *, double *, double *, double *, void *);
using OneBlockProj = void (*)(int, int, double *, double *, void *);  // mot: aj; str: bi
using OneBlockJac = void (*)(int, int, double *, double *, void *);

// An expert driver's func/fjac, or a simple driver's proj/projac with their adapters.
struct UserCallbacks {
  bool simple = false;  // per-projection callbacks (a simple driver's)
  ExpertFunc func = nullptr, fjac = nullptr;  // an expert driver's, with adata
  void *adata = nullptr;
  SimpleCallbacks per_projection{};  // a simple driver's, with their adapters and adata

  // The projection function (func or proj) is given.
  bool has_projection() const {
    return simple ? per_projection.user_proj != nullptr : func != nullptr;
  }
};

UserCallbacks expert_callbacks(ExpertFunc func, ExpertFunc fjac, void *adata);
UserCallbacks motstr_callbacks(MotStrProj proj, MotStrJac projac, void *adata);
UserCallbacks mot_callbacks(OneBlockProj proj, OneBlockJac projac, void *adata);
UserCallbacks str_callbacks(OneBlockProj proj, OneBlockJac projac, void *adata);

// The model of the callbacks over lay; concurrent: the caller allows concurrent calls.
std::unique_ptr<Model> make_model(const Layout &lay, const UserCallbacks &cb, bool concurrent);

}  // namespace sba

#endif
