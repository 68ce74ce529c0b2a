// Typed internals shared by the drivers: the problem layout, the callback models and the
// single Levenberg-Marquardt core that all six 1.6 drivers run on.
#ifndef SBA_SRC_CORE_H
#define SBA_SRC_CORE_H

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "log.h"
#include "loss.h"
#include "sba_export.h"

namespace sba {

using i64 = std::int64_t;

// What p holds: motion+structure, cameras only (sba_mot_*), or points only (sba_str_*).
enum class Mode { MotStr, Mot, Str };

// info[6] values. 1..7 are sba 1.6's; the rest are ours and documented in the README.
enum StopReason : int {
  kStopNone = 0,         // no iteration ran: bad arguments, invalid covariance, no memory
  kStopGradient = 1,     // ||J^T e||_inf <= eps1
  kStopStep = 2,         // ||dp||^2 <= eps2^2 ||p||^2
  kStopItmax = 3,        // itmax iterations
  kStopReduction = 4,    // relative RMS error reduction < eps4
  kStopError = 5,        // ||e||^2 <= eps3^2
  kStopDamping = 6,      // damping could not grow any more: too many failed attempts
  kStopNonFinite = 7,    // f(p) or the Jacobian has a NaN or Inf
  kStopSingular = 8,     // the augmented system is almost singular
  kStopUser = 9,         // the progress callback asked to stop
};

// Sizes and the visibility index in the forms the core and the callbacks need.
struct Layout {
  Mode mode = Mode::MotStr;
  int n = 0, m = 0;       // points, cameras
  int cnp = 0, pnp = 0;   // parameters per camera / point held in p (0 when not in p)
  int mnp = 0;            // coordinates per projection
  int mcon = 0, ncon = 0; // leading fixed cameras / points
  i64 nvis = 0;           // visible projections

  // Row-compressed by point (cameras ascending); val[k] == k is the measurement ordinal.
  std::vector<int> rowptr, colidx, val;
  // Where each camera's projections start in the camera-major order (see by_camera()).
  std::vector<int> colptr;
  sba_crsm idx{};  // views rowptr/colidx/val for the callbacks
  std::vector<int> rcidxs, rcsubs;  // callback scratch, max(n, m) each

  i64 nvars() const { return i64(m) * cnp + i64(n) * pnp; }
  i64 a_off(int j) const { return i64(j) * cnp; }
  i64 b_off(int i) const { return i64(m) * cnp + i64(i) * pnp; }
  // Doubles per projection in the Jacobian; build_layout refuses sizes where it exceeds an
  // int, so the narrowing is exact for every layout that exists.
  int jblk() const { return int(i64(mnp) * (i64(cnp) + pnp)); }
  bool cam_free(int j) const { return cnp > 0 && j >= mcon; }
  bool pt_free(int i) const { return pnp > 0 && i >= ncon; }
  int free_cams() const { return cnp > 0 ? m - mcon : 0; }
  int free_pts() const { return pnp > 0 ? n - ncon : 0; }
  i64 free_vars() const { return i64(free_cams()) * cnp + i64(free_pts()) * pnp; }
};

// The index column-compressed by camera (points ascending): for slot s of camera j's range
// [colptr[j], colptr[j+1]), the point (row) and the measurement ordinal (k, unless null).
// Built on demand by the solvers that need it, so that the others do not keep 8 bytes per
// projection alive through the solve.
void by_camera(const Layout &lay, std::vector<int> *row, std::vector<int> *k);

// Builds the index from vmask. Returns false (with msg, naming the product) on a problem too
// big for the int API: any block (mnp*(cnp+pnp), cnp*cnp, pnp*pnp, cnp*pnp, and mnp*mnp when
// with_covx) or any
// vector the callbacks index (p, x, the Jacobian, and covx when with_covx) beyond INT_MAX
// entries. Nothing is allocated before these checks.
bool build_layout(Layout &lay, Mode mode, int n, int m, int mcon, int ncon, int cnp, int pnp,
                  int mnp, const char *vmask, std::string *msg, bool with_covx = false);
// The same from a list of (point, camera) pairs sorted by point then camera (sba_ext.h's
// sba_visibility); only nvis and the single blocks must fit an int: the callbacks of this API
// index hx and the Jacobian with 64-bit offsets.
bool build_layout(Layout &lay, Mode mode, int n, int m, int mcon, int ncon, int cnp, int pnp,
                  int mnp, const sba_visibility &vis, std::string *msg, bool with_covx = false);

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
std::unique_ptr<Model> make_expert_model(Layout &lay, ExpertFunc func, ExpertFunc fjac,
                                         void *adata, bool concurrent);

// The simple drivers' per-projection proj/projac, normalized to the motion+structure shape;
// the adapters in drivers.cpp bridge the mot/str signatures onto it.
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


// How the damped normal equations are solved (see linsolve.h).
enum class LinSolver {
  Chol,        // dense S, Cholesky (sba 1.6's default): the library's own up to 2048 unknowns
  CholLapack,  // dense S, LAPACK's DPOTRF/DPOTRS at every size
  LDLt,        // dense S, unpivoted LDL^T
  BK,          // dense S, Bunch-Kaufman
  LU,          // dense S, LU
  QR,          // dense S, QR
  QRnoQ,       // dense S, QR without Q (R^T R x = S^T b)
  SVD,         // dense S, SVD
  CG,          // dense S, Jacobi-preconditioned conjugate gradients
  LdlAmd,      // no Schur complement: the whole system, AMD ordering + sparse LDL^T
  SparseChol,  // sparse S (cameras sharing points), CHOLMOD Cholesky
};

struct Options {
  LinSolver solver = LinSolver::Chol;
  double tau = SBA_INIT_MU;
  double eps1 = SBA_STOP_THRESH, eps2 = SBA_STOP_THRESH, eps3 = SBA_STOP_THRESH, eps4 = 0.0;
  int itmax = 0;
  int nthreads = 1;
  bool auto_threads = false;  // nthreads is the hardware's, not the caller's: see fit_threads
  bool parallel_callbacks = false;  // the caller's callbacks may run concurrently
  bool avoid_shared_cores = false;  // workers may narrow their own CPU mask (parallel.cpp)
  Loss loss;  // robust loss on each projection's squared residual (none: least squares)
  // Called after every outer iteration; nonzero stops with kStopUser.
  int (*progress)(void *ctx, const sba_progress *state) = nullptr;
  void *progress_ctx = nullptr;
};

struct Summary {
  // err0, err: the cost minimized (the robust cost with a loss); sq_err0, sq_err: the plain
  // sum of squared (covariance-weighted) residuals.
  double err0 = 0, err = 0, grad_inf = 0, dp2 = 0, mu_ratio = 0;
  double sq_err0 = 0, sq_err = 0;
  i64 outliers = 0;  // projections beyond the loss scale at the end
  int iterations = 0;
  int reason = kStopNone;
  i64 nfev = 0, njev = 0, nlinsys = 0;
  bool ok = false;

  void to_info(double *info) const;
};

// Runs LM on p (updated in place with the last accepted estimate). x: measurements;
// covx: null or per-measurement covariances. Returns false on failure (summary.ok too).
bool solve(const Layout &lay, Model &model, double *p, const double *x, const double *covx,
           const Options &opt, const Logger &log, Summary &sum);

// The stop-4 test after an accepted step: e and en are the cost before and after it.
bool reduction_stalled(double e, double en, double eps4);

class Kernels;

// The normal equations at p, without iterating: for the covariance of the solution.
struct Linearization {
  std::vector<double> jac, U, V, ea, eb;  // as in an LM iteration (weighted, reweighted)
  double sq_err = 0;                      // squared error of the (re)weighted residual
};
bool linearize(const Layout &lay, Model &model, double *p, const double *x, const double *covx,
               const Options &opt, const Logger &log, ThreadPool &pool, const Kernels &kernels,
               Linearization *out);

// What sba_motstr_covariance* computes (see sba_ext.h), with validated indices.
struct CovarianceRequest {
  int ncams = 0;
  const int *cams = nullptr;
  double *camcov = nullptr;
  int npts = 0;
  const int *pts = nullptr;
  double *ptcov = nullptr;
  double sigma2 = 0;
  int rank = 0, nfree = 0;
};
bool covariance(const Layout &lay, Model &model, double *p, const double *x, const double *covx,
                const Options &opt, const Logger &log, CovarianceRequest &req);

// The itmax == 0 check of an analytic Jacobian against central differences. Reports every
// suspicious entry and a one-line verdict through log. Returns the number of suspicious rows.
i64 check_jacobian(const Layout &lay, Model &model, double *p, const Logger &log);

}  // namespace sba

#endif
