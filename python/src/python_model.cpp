// SPDX-License-Identifier: BSD-3-Clause
#include "python_model.h"

#include <limits>
#include <string>
#include <vector>

#include "run.h"
#include "session.h"

namespace pysba {
namespace {

// What the C callbacks receive as adata.
struct PythonModel {
  Refine refine = Refine::MotStr;
  int m = 0, n = 0, cnp = 0, pnp = 0, mnp = 0;
  py::handle project, jacobian;  // the caller holds them
  // The part that is not refined: the points for motion only, the cameras for structure only.
  std::vector<double> cameras0, points0;
  Session *session = nullptr;

  const double *cameras_in(const double *p) const { return refine == Refine::Str ? cameras0.data() : p; }
  const double *points_in(const double *p) const {
    if (refine == Refine::Mot) return points0.data();
    return refine == Refine::Str ? p : p + size_t(m) * cnp;
  }
  // The values the Jacobian callback writes per observation.
  int jacobian_block() const {
    return mnp * ((refine != Refine::Str ? cnp : 0) + (refine != Refine::Mot ? pnp : 0));
  }
};

// The observations an index lists, in its row order, and their measurement ordinals.
struct Listed {
  PyRef cam, pt;
  std::vector<int> ordinal;
};

Listed listed(const sba_crsm *idx) {
  Listed l;
  py::array_t<long long> cams(idx->nnz), pts(idx->nnz);
  l.ordinal.resize(size_t(idx->nnz));
  long long *cam = cams.mutable_data(), *pt = pts.mutable_data();
  int q = 0;
  for (int i = 0; i < idx->nr; ++i)
    for (int k = idx->rowptr[i]; k < idx->rowptr[i + 1]; ++k, ++q) {
      cam[q] = idx->colidx[k];
      pt[q] = i;
      l.ordinal[size_t(q)] = idx->val[k];
    }
  l.cam = PyRef(std::move(cams));
  l.pt = PyRef(std::move(pts));
  return l;
}

// A NaN in every block of the output: the driver stops at once (SBA_ERROR, reason 7), and
// the kept exception is raised when it has returned.
void poison(const sba_crsm *idx, int block, double *out) {
  for (int k = 0; k < idx->nnz; ++k)
    std::fill_n(out + size_t(idx->val[k]) * block, block, std::numeric_limits<double>::quiet_NaN());
}

// callback(cameras, points, cam_idx, pt_idx) of the observations idx lists, and their ordinals.
PyRef call_model(const PythonModel &pm, py::handle callback, double *p, const Listed &l) {
  const PyRef cams(copy_of(pm.cameras_in(p), {pm.m, pm.cnp})), pts(copy_of(pm.points_in(p), {pm.n, pm.pnp}));
  return call_python(callback, {cams.handle(), pts.handle(), l.cam.handle(), l.pt.handle()});
}

void python_func(double *p, sba_crsm *idx, int *, int *, double *hx, void *adata) {
  PythonModel *pm = static_cast<PythonModel *>(adata);
  if (pm->session->failed()) return poison(idx, pm->mnp, hx);
  with_gil(pm->session->released_thread(), [&] {
    try {
      const Listed l = listed(idx);
      const PyRef r = call_model(*pm, pm->project, p, l);
      const Doubles a = result_array(r.handle(), "project's result", {idx->nnz, pm->mnp});
      for (int q = 0; q < idx->nnz; ++q)
        std::copy_n(a.data() + size_t(q) * pm->mnp, pm->mnp, hx + size_t(l.ordinal[size_t(q)]) * pm->mnp);
    }
    PYSBA_FORCED_UNWIND_PASSES_THROUGH
    catch (...) {
      pm->session->keep_current_exception();
      poison(idx, pm->mnp, hx);
    }
  });
}

void python_fjac(double *p, sba_crsm *idx, int *, int *, double *jac, void *adata) {
  PythonModel *pm = static_cast<PythonModel *>(adata);
  const int block = pm->jacobian_block();
  if (pm->session->failed()) return poison(idx, block, jac);
  with_gil(pm->session->released_thread(), [&] {
    try {
      const Listed l = listed(idx);
      const PyRef r = call_model(*pm, pm->jacobian, p, l);
      const PyRef ab(PySequence_Tuple(r.get()));
      if (!ab) throw py::error_already_set();
      if (PyTuple_GET_SIZE(ab.get()) != 2) throw py::value_error("jacobian must return a pair (A, B)");
      const int asz = pm->mnp * pm->cnp, bsz = pm->mnp * pm->pnp;
      // Only the blocks of what is refined are read (and written: block counts only them).
      const bool has_a = pm->refine != Refine::Str, has_b = pm->refine != Refine::Mot;
      Doubles A, B;
      if (has_a) A = result_array(PyTuple_GET_ITEM(ab.get(), 0), "jacobian's A", {idx->nnz, pm->mnp, pm->cnp});
      if (has_b) B = result_array(PyTuple_GET_ITEM(ab.get(), 1), "jacobian's B", {idx->nnz, pm->mnp, pm->pnp});
      for (int q = 0; q < idx->nnz; ++q) {
        double *out = jac + size_t(l.ordinal[size_t(q)]) * block;
        if (has_a) out = std::copy_n(A.data() + size_t(q) * asz, asz, out);
        if (has_b) std::copy_n(B.data() + size_t(q) * bsz, bsz, out);
      }
    }
    PYSBA_FORCED_UNWIND_PASSES_THROUGH
    catch (...) {
      pm->session->keep_current_exception();
      poison(idx, block, jac);
    }
  });
}

}  // namespace

py::dict solve_python(const std::string &refine, py::handle project, py::handle jacobian, py::handle cameras,
                      py::handle points, py::handle camera_index, py::handle point_index, py::handle observations,
                      py::handle covariances, const py::kwargs &kw) {
  const SolveOptions o = solve_options(kw);
  if (!PyCallable_Check(project.ptr())) throw py::type_error("project must be callable");
  if (!jacobian.is_none() && !PyCallable_Check(jacobian.ptr()))
    throw py::type_error("jacobian must be callable or None");
  std::vector<double> cams, pts;
  std::vector<py::ssize_t> cs, ps;
  {
    // Copied and let go before the solve (gil.h).
    const Doubles c = parameter_rows(cameras, "cameras", -1), b = parameter_rows(points, "points", -1);
    cs = {c.shape(0), c.shape(1)};
    ps = {b.shape(0), b.shape(1)};
    cams.assign(c.data(), c.data() + c.size());
    pts.assign(b.data(), b.data() + b.size());
  }
  if (cs[0] == 0 || ps[0] == 0) throw py::value_error("a problem needs at least one camera and one point");
  if (cs[1] == 0 || ps[1] == 0) throw py::value_error("cameras and points need at least one parameter each");

  PythonModel pm;
  if (refine == "motstr") pm.refine = Refine::MotStr;
  else if (refine == "mot") pm.refine = Refine::Mot;
  else if (refine == "str") pm.refine = Refine::Str;
  else throw py::value_error("refine must be motstr, mot or str");
  pm.m = static_cast<int>(cs[0]);
  pm.n = static_cast<int>(ps[0]);
  pm.cnp = static_cast<int>(cs[1]);
  pm.pnp = static_cast<int>(ps[1]);
  pm.project = project;
  pm.jacobian = jacobian;

  Run run;
  run.refine = pm.refine;
  run.obs = sorted_observations(pm.n, pm.m, camera_index, point_index, observations, covariances);
  pm.mnp = run.obs.mnp;
  if (pm.refine != Refine::Str) run.p = cams;
  else pm.cameras0 = cams;
  if (pm.refine != Refine::Mot) run.p.insert(run.p.end(), pts.begin(), pts.end());
  else pm.points0 = pts;
  run.cnp = pm.cnp;
  run.pnp = pm.pnp;
  run.func = python_func;
  run.fjac = jacobian.is_none() ? nullptr : python_fjac;
  run.adata = &pm;
  run.parallel = false;  // one at a time, on the calling thread: they need the GIL anyway

  Session session(o);
  pm.session = &session;
  py::dict d = run_driver(run, session, o);
  d["cameras"] = copy_of(pm.cameras_in(run.p.data()), {pm.m, pm.cnp});
  d["points"] = copy_of(pm.points_in(run.p.data()), {pm.n, pm.pnp});
  d["nobs"] = run.obs.nobs();
  return d;
}

}  // namespace pysba
