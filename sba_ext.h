/* SPDX-License-Identifier: BSD-3-Clause */
/*
 * sba_ext.h: what this library offers beyond the sba 1.6 API. Everything here is additive:
 * the 1.6 entry points of sba.h behave as in 1.6 (plus the documented improvements), and a
 * program opts in by calling the _ext variants with an options struct.
 *
 *   struct sba_ext_options ext;
 *   sba_ext_options_init(&ext);          (always: fills the defaults and the struct size)
 *   ext.linsolver = "sparse-chol";
 *   ret = sba_motstr_levmar_x_ext(..same arguments as sba_motstr_levmar_x.., &ext);
 *
 * A NULL ext is exactly the 1.6 entry point. An ext from sba_ext_options_init with nothing
 * set differs from it in one thing: the linear solver, "auto" rather than 1.6's "chol" (see
 * linsolver below).
 */
#ifndef SBA_EXT_H
#define SBA_EXT_H

#include <stddef.h>

#include "sba.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Why a solve stopped: the values of info[6]. 1..7 are sba 1.6's, with its meaning; 0, 8 and 9
 * are this library's. sba_stop_reason_text gives each in words. */
#define SBA_STOP_NONE 0      /* nothing ran: bad arguments, invalid covariance, no memory */
#define SBA_STOP_GRADIENT 1  /* small gradient: ||J^T e||_inf <= eps1 */
#define SBA_STOP_STEP 2      /* small step: ||dp||^2 <= eps2^2 ||p||^2 */
#define SBA_STOP_ITMAX 3     /* itmax iterations */
#define SBA_STOP_REDUCTION 4 /* small relative reduction of the error (eps4; see strategy below) */
#define SBA_STOP_ERROR 5     /* small error: ||e||^2 <= eps3^2 */
#define SBA_STOP_DAMPING 6   /* the damping could not grow any more: too many failed attempts */
#define SBA_STOP_NONFINITE 7 /* the projections or the Jacobian had a NaN or Inf (SBA_ERROR) */
#define SBA_STOP_SINGULAR 8  /* the augmented normal equations are almost singular (SBA_ERROR) */
#define SBA_STOP_USER 9      /* the progress callback asked to stop; p is the last accepted */

/* reason (an info[6] value, SBA_STOP_*) in words, e.g. "small step: ||dp|| <= eps2 ||p||": a
 * static string, "unknown" for a value that is not a stop reason (never NULL). */
extern const char *sba_stop_reason_text(int reason);

/* opts[0] = tau (sba.h): as in 1.6 its magnitude is used, and tau = 0 is a bad argument
 * (SBA_ERROR): the initial damping mu = |tau| max diag(J^T J) would be 0, which no failed
 * step can grow. mu is also kept at no less than 2^-400 max diag(J^T J) (only a tau below
 * that notices) and the smallest normal number, so that a tau * max diag(J^T J) that
 * underflows cannot end the solve at once with nothing refined.
 * The environment variables SBA_LINSOLVER and SBA_NUM_THREADS (for unmodified 1.6
 * programs): an invalid value is ignored, with a warning (level SBA_LOG_WARNING, shown
 * verbose or not), and does not make the call fail. */

/* log levels passed to the log sink */
#define SBA_LOG_ERROR 0   /* why a call returns SBA_ERROR */
#define SBA_LOG_WARNING 1 /* diagnostics (1.6 printed some unconditionally; we need verbose),
                           * and ignored environment settings (shown verbose or not) */
#define SBA_LOG_INFO 2    /* progress, when verbose */

/* The state after each outer iteration, for the progress callback. */
struct sba_progress {
  int iteration;   /* iterations done so far (1, 2, ...) */
  double error;    /* ||e||^2 at the current (last accepted) estimate */
  double mu;       /* the damping that the next iteration starts from */
  double dp_norm;  /* ||dp|| of the last step tried */
  double elapsed;  /* seconds since the driver was called */
};

/* What a solve did, beyond info[]: filled when sba_ext_options.result points to one. */
struct sba_ext_result {
  /* sizeof(struct sba_ext_result) as the caller was compiled; set by the caller (or by
   * sba_ext_result_init). */
  size_t size;
  /* Sum of the projections' squared (covariance-weighted) residuals, never robustified: at the
   * start and at the end. With a robust loss, info[0] and info[1] hold the robust cost instead,
   * and with priors the cost plus the priors' (see below). */
  double sq_error_initial, sq_error_final;
  /* The robust cost sum_k rho(||e_k||^2) at the start and at the end (the plain squared
   * error when no loss is used). */
  double cost_initial, cost_final;
  /* Projections whose squared residual is beyond the loss scale squared at the end (0 without
   * a loss): the ones the loss treats as outliers. */
  long long outliers_final;
  int nthreads;           /* threads used (after the caps, see sba_ext_options.nthreads) */
  /* linear solver used (a static string): the one "auto" chose, never "auto"; "block-diagonal"
   * where the system is block diagonal (no free points, or no free cameras, and no shared
   * camera parameters), which one small Cholesky per camera or point solves whatever was asked */
  const char *linsolver;
  int robust;             /* nonzero if a robust loss was used */
  const char *strategy;   /* LM strategy used (a static string) */
  /* The cost apart, at the start and at the end: the projections' (sum_k rho(||e_k||^2), the
   * loss of sba_ext_options) and the priors' (sum over the priors of each one's
   * rho(||L r||^2), see sba_camera_prior below; 0 without priors). cost_initial and
   * cost_final, info[0] and info[1] are their sums: the cost the solve minimizes. */
  double projection_cost_initial, projection_cost_final;
  double prior_cost_initial, prior_cost_final;
};

/* ---- priors: residual blocks beside the projections ----
 * A prior is a residual r of a few entries that depends on one camera's parameters, or on one
 * point's, weighted by a square-root information L (L^T L = the inverse of r's covariance):
 * the solve minimizes the projections' cost plus, for each prior, rho(||L r||^2), with the
 * prior's own robust loss rho. Priors are given through sba_ext_options (the fields after
 * memory_budget); the library reads the arrays below during the call only and keeps no
 * pointer to them. A prior is refused (SBA_ERROR, reason 0, a message naming it, e.g.
 * "point prior 3 (point 17): mean[1] is not finite") when its camera or point does not exist
 * or is fixed (mcon, ncon), when it constrains a held camera parameter (cam_fixed), or when its
 * mean, weight or loss cannot be used. A prior on a shared camera parameter (cam_group,
 * cam_param_group) applies once per camera it names, as written: two priors on two cameras
 * that share the parameter count twice. See docs/priors.md.
 * The three structs below have no size field: their layout is fixed, and a later version that
 * needs more adds a kind of prior (new fields at the end of sba_ext_options) rather than
 * changing them. Initialize them with memset or = {0}: every pointer the caller does not set
 * must be NULL. */

/* How a prior's residual r of k entries is weighted: at most one of the three (all NULL: L =
 * I, r is taken as already weighted). Units: those of r. */
struct sba_prior_weight {
  /* k standard deviations, each finite and > 0: L = diag(1 / sigma). */
  const double *sigma;
  /* k x k covariance of r, row-major, finite, symmetric and positive definite: L is the
   * upper-triangular factor with L^T L = covariance^-1. */
  const double *covariance;
  /* k x k square-root information L itself, row-major, upper triangular (every entry below the
   * diagonal 0), finite, with a positive diagonal. */
  const double *sqrt_info;
};

/* A prior on camera camera's parameters given by a callback: r = func(a_j) of dim entries
 * (say the camera centre, a nonlinear function of most parametrizations, minus a GPS
 * position: docs/priors.md), weighted by weight (k = dim). func writes r (dim doubles); jacf
 * writes dr/da_j (dim x cnp, row-major); jacf NULL: forward differences. aj is the camera's
 * full parameter vector (cnp doubles; held and shared parameters included): read only. The
 * callbacks are called from the thread that called the driver, with data, and must return
 * normally (sba.h). The itmax == 0 Jacobian check also checks jacf against central
 * differences of func. The columns of held parameters are not used. A residual that is not
 * finite where the solve evaluates it ends the solve as a projection's would (SBA_ERROR,
 * info[6] = SBA_STOP_NONFINITE, a message naming the prior). */
struct sba_camera_prior {
  int camera; /* 0..m-1, not below mcon, with at least one parameter not held */
  int dim;    /* entries of r, 1..64 */
  void (*func)(int j, const double *aj, double *r, void *data);
  void (*jacf)(int j, const double *aj, double *jac, void *data);
  void *data;
  struct sba_prior_weight weight;
  /* this prior's robust loss on ||L r||^2, as sba_ext_options.loss (NULL: none), and its
   * scale (0 means 1; the same range as loss_scale) */
  const char *loss;
  double loss_scale;
};

/* A prior on chosen parameters of one camera, linear: r = a_j[params] - mean (intrinsics, a
 * known position in a parametrization that has it as parameters). k entries; params names k
 * distinct parameters in 0..cnp-1, none held; mean in the units of those parameters. */
struct sba_camera_linear_prior {
  int camera; /* 0..m-1, not below mcon */
  int k;      /* 1..cnp */
  const int *params;
  const double *mean;
  struct sba_prior_weight weight;
  const char *loss;
  double loss_scale;
};

/* A prior on one point: r = b_i - mean (pnp entries; a ground control point, a point known
 * softly). */
struct sba_point_prior {
  int point; /* 0..n-1, not below ncon */
  const double *mean;
  struct sba_prior_weight weight;
  const char *loss;
  double loss_scale;
};

struct sba_ext_options {
  /* sizeof(struct sba_ext_options) as the caller was compiled: lets later versions add
   * fields at the end without breaking programs built against this one. */
  size_t size;
  /* Linear solver of the augmented normal equations, by name (see README, docs/solvers.md):
   * "auto" (one of chol, sparse-chol and iterative-schur, chosen from the problem's shape:
   * the unknowns of the reduced camera system S after holding and sharing, how many of S's
   * blocks and of its Cholesky factor's are nonzero, the observations, and the memory each
   * would need against a budget (memory_budget below); result->linsolver names the one chosen, and
   * verbose says why), "chol" (dense S by Cholesky as in 1.6: the library's own, the same bits for
   * any thread count, up to 2048 unknowns; LAPACK's DPOTRF/DPOTRS beyond), "chol-lapack"
   * (dense S by DPOTRF/DPOTRS at every size), "ldlt", "bk", "lu", "qr", "qrnoq", "svd",
   * "cg" (dense S), "ldl-amd" (whole system, AMD + sparse LDL^T), "sparse-chol" (sparse S,
   * CHOLMOD), "iterative-schur" (S never formed: preconditioned conjugate gradients on
   * products S x made from the Jacobian blocks, an inexact step whose accuracy tightens as
   * the gradient falls; memory proportional to the observations; for many cameras that share
   * points with many others, where a dense or sparse S is too large to factor).
   * NULL: the environment variable SBA_LINSOLVER if set, else "auto". The entry points of
   * sba.h, and those here given a NULL ext, are sba 1.6's: for them the default is 1.6's
   * "chol" (SBA_LINSOLVER still applies). An unknown name here is a bad argument
   * (SBA_ERROR); in SBA_LINSOLVER it is ignored, with a warning, for the default. */
  const char *linsolver;
  /* Threads for the normal equations and the Schur complement; 0: the environment variable
   * SBA_NUM_THREADS if set, else every hardware thread but at most one per 10,000
   * projections (a smaller problem runs faster on fewer). A count asked for (here or in
   * SBA_NUM_THREADS) is capped at 4 per hardware thread and at one per 64 projections:
   * more only cost time and memory. SBA_NUM_THREADS must be a positive decimal integer (the
   * whole value); anything else is ignored, with a warning (verbose or not). The count actually
   * used is reported in sba_ext_result.nthreads. Results do not depend on it. */
  int nthreads;
  /* Where messages go: log(log_ctx, level, line) with one line and no newline. NULL:
   * errors and warnings to stderr, progress to stdout, as 1.6. */
  void (*log)(void *log_ctx, int level, const char *line);
  void *log_ctx;
  /* Nonzero: print nothing at all, not even errors (info[6] still tells what happened). */
  int quiet;
  /* Called after every outer iteration, including the last one (whatever ended it). Like
   * every callback it must return normally (see sba.h: no longjmp; a C++ exception is
   * caught and makes the call fail with SBA_ERROR); this is the way to stop a solve. A
   * nonzero return stops the solve cleanly with info[6] = SBA_STOP_USER and p at the last
   * accepted estimate, except after the last iteration, where it changes nothing (the solve
   * keeps the reason it stopped for). NULL: not called. */
  int (*progress)(void *progress_ctx, const struct sba_progress *state);
  void *progress_ctx;
  /* Robust loss applied to every projection's squared residual s = ||e_ij||^2 (after the
   * covariance weighting): NULL or "none" (plain least squares, as 1.6), "huber", "cauchy",
   * "soft-l1", "tukey", with scale loss_scale (residuals beyond about loss_scale count
   * less; 0 means 1). loss_scale must lie within [2^-511, 2^511] (about 1.5e-154 to 6.7e153),
   * where its square and inverse square are normal numbers; anything else (negative, NaN,
   * Inf, or beyond that range) is a bad argument: SBA_ERROR before iterating, with a message
   * naming loss_scale. Solved by iteratively reweighted least squares inside the same LM:
   * info[0], info[1] and the progress error are then the robust cost sum rho(s). The stop
   * tests of opts are absolute: with a scale far below the residuals the robust gradient
   * shrinks with the scale, and eps1 must shrink with it. */
  const char *loss;
  double loss_scale;
  /* Where to report what the solve did (NULL: nowhere). */
  struct sba_ext_result *result;
  /* Nonzero: the callbacks may be called from several threads at once (the nthreads of the
   * solve), which also spreads their work over the threads. Only for callbacks that are
   * re-entrant, keep no shared mutable state, and, for func/fjac, walk the index by rows
   * (rowptr), writing only the projections of the rows it lists: each thread is handed an
   * index whose other rows are empty. The finite-difference Jacobian then also evaluates
   * its cnp + pnp perturbed vectors concurrently. 0 (default): callbacks are only ever
   * called from the thread that called the driver, one at a time. */
  int parallel_callbacks;
  /* Nonzero (Linux only; default 0, off): a worker thread of the solve's pool that finds
   * itself, when a job starts, on the CPU of the calling thread or of another of the pool's
   * workers moves to a CPU none of them is on, if its mask allows one: it narrows its own
   * affinity mask for a moment, so that the kernel moves it, and then puts its mask back.
   * Only the library's own worker threads are touched, and only for that moment; the
   * calling thread's mask is never changed, and workers keep the mask they inherited from
   * it. "Free" means free of this pool only: a CPU the host keeps for other work is not
   * known to it. It helps where the scheduler puts a woken thread on its waker's CPU and
   * leaves the two sharing it for milliseconds (seen on small virtual machines). 0: the
   * environment variable SBA_AVOID_SHARED_CORES=1 turns it on (0 or unset: off; anything
   * else is ignored, with a warning). Off, the library never changes a thread's affinity. */
  int avoid_shared_cores;
  /* How the Levenberg-Marquardt iteration damps, accepts steps and stops, by name:
   * "sba" (default): sba 1.6's algorithm, step for step (damping mu I with mu starting at
   * tau max diag(J^T J), Nielsen's update, 1.6's stop tests and reasons), and 1.6's retries:
   * a rejected attempt's damping stays on the blocks the next attempt damps (see
   * docs/strategies.md), which after a rejection usually restarts the damping high.
   * "sba-clean-retry": the same, but every attempt damps the undamped J^T J, as the sba paper
   * writes it: the same steps where none is rejected, fewer iterations where some are.
   * "trust-region": the damping is mu diag(J^T J) (Marquardt's, the diagonal kept within
   * [1e-6, 1e32]) with mu starting at tau/10 (on the scaled system), a trial point is taken only when it achieves at
   * least 1e-3 of the predicted reduction, and a step whose relative cost change
   * |||e||^2 - ||e_new||^2| / ||e||^2 is at most eps4 ends the solve with reason 4, taken if it
   * lowers the cost enough, left otherwise (eps4 = 0, the default of opts, means 1e-6). It
   * usually needs several times fewer iterations from the same start. Stop reasons 1, 2, 3, 5 and 6 keep their meaning (6 also when mu would
   * exceed 1e32); info[4] is mu relative to the scaled system.
   * NULL: the environment variable SBA_STRATEGY if set (an unknown name there is ignored
   * with a warning), else "sba". An unknown name here is a bad argument (SBA_ERROR). */
  const char *strategy;
  /* Polled by the covariance entry points (sba_motstr_covariance[_x]), from the calling
   * thread, between the stages of their work and about every 10 ms within the long ones:
   * a nonzero return abandons the computation, which returns SBA_ERROR with the message
   * "...: stopped by the cancel callback" (req's outputs are then unspecified). A covariance
   * has no iterations for the progress callback to stop, and can take far longer than the
   * solve before it; this is how a host lets its user interrupt it (pysba: Ctrl-C). The
   * LAPACK calls that invert the reduced camera system (its Cholesky factorization, or its
   * eigendecomposition when it is singular: O((cameras*cnp)^3)) cannot be interrupted. Like
   * every callback it must return normally. NULL: never polled; the drivers never call it. */
  int (*cancel)(void *cancel_ctx);
  void *cancel_ctx;
  /* Camera parameters held at their initial values, beyond 1.6's leading mcon cameras (the
   * drivers with cameras; the structure-only ones ignore it): NULL (none), or flags, nonzero
   * for a held parameter: cnp of them applied to every camera (cam_fixed_per_camera 0), or m*cnp,
   * camera j's at j*cnp (cam_fixed_per_camera nonzero). A held parameter comes back
   * bit-identical; it is not an unknown (a camera with all of them held is as a camera below
   * mcon) and has zero covariance. */
  const char *cam_fixed;
  int cam_fixed_per_camera;
  /* Camera parameters shared by groups of cameras, solved as one set of unknowns per group
   * (say one intrinsic calibration for the images of one physical camera): NULL (none), or m
   * group numbers, camera j's in cam_group[j]: -1 for a camera in no group, else a number in
   * 0..m-1 (the numbers need not be contiguous). cam_shared: cnp flags, nonzero for the
   * parameters the cameras of a group share (the same for every group). The callbacks keep
   * seeing every camera's full parameter vector. A group's shared values start as its first
   * camera's (the one of least index) and every camera of the group holds them, bit for bit,
   * on return; a call that fails before its first step, or that only checks the Jacobian
   * (itmax 0), returns p as given. A shared parameter must be held (cam_fixed) in all of a
   * group's cameras, with the same value, or in none; a camera below mcon is in no group;
   * cam_shared needs cam_group; anything else is a bad argument (SBA_ERROR). A shared
   * parameter is one unknown of the reduced camera system (counted once against the
   * measurements), coupled to the cameras that share it as they are to each other. */
  const int *cam_group;
  const char *cam_shared;
  /* Camera parameters shared per parameter, for groupings that differ from one parameter to
   * the next (COLMAP's rigs: an image's intrinsics shared by the images of its camera, its
   * frame's pose by the images taken at one instant, its sensor's pose in the rig by every
   * frame of the rig): NULL (none), or m*cnp group numbers, camera j's parameter c at
   * j*cnp+c, -1 for a parameter of its own. Cameras j and j' share parameter c, as one
   * unknown, when their numbers for c are equal and not -1; the numbers of different
   * parameters are unrelated. The same rules as for cam_group apply per parameter: a shared
   * parameter starts as its first camera's, comes back bit-identical in all of them, is held
   * in all or none of them (with one value), and cameras below mcon have -1 throughout.
   * Exclusive with cam_group/cam_shared (which mean cam_param_group[j*cnp+c] = cam_group[j]
   * where cam_shared[c] is nonzero, else -1). */
  const int *cam_param_group;
  /* The memory, in bytes, that linsolver "auto" plans a solve within: it takes the first of
   * chol, sparse-chol and iterative-schur that its rule prefers and whose memory (what every
   * solve holds, the Jacobian and the normal equations' blocks, plus the solver's own) fits,
   * and when even the one that needs least does not fit, the call fails (SBA_ERROR, reason 0)
   * with a message giving what it needs. 0: the machine's physical memory, or the
   * address-space limit (RLIMIT_AS) where that is lower. The budget is a setting, not a
   * reading of the memory free at the moment: the same problem and options choose the same
   * solver, and give the same result, whatever else the machine is doing. A solver named in
   * linsolver is run whatever it needs. */
  size_t memory_budget;
  /* Priors (see struct sba_camera_prior above): counts and arrays, NULL with a count of 0.
   * Camera priors need a driver with cameras and point priors one with points. With priors,
   * info[0], info[1], the progress error and sba_ext_result's cost_* are the projections' cost
   * plus the priors'; the covariance entry points include the priors' information in J^T J
   * and their rows among the measurements of the residual variance. */
  int ncamera_priors;
  const struct sba_camera_prior *camera_priors;
  int ncamera_linear_priors;
  const struct sba_camera_linear_prior *camera_linear_priors;
  int npoint_priors;
  const struct sba_point_prior *point_priors;
  /* Nonzero: the Jacobian is stored in single precision, half its memory (8 bytes per
   * projection and parameter instead of 16 with mnp 2) and half of what each iteration reads
   * of it. The callback's blocks are weighted and reweighted in double, give the gradient
   * J^T e in double, and only then are rounded to float; everything computed from the stored
   * blocks is computed in double. The solve thus ends where the gradient is small, at the
   * same minimum, but its steps come from rounded blocks: iterations and stop reasons may
   * differ from a solve in double, and on an ill-conditioned problem (intrinsics refined
   * with the poses) 1.6's strategy may stall above the minimum where the trust region does
   * not (docs/solvers.md). With projac given, the residual is not kept either: each error
   * is summed point by point, and proj is called again beside projac when the Jacobian is
   * made (calls that info[7] does not count). Only with the simple drivers (an expert
   * driver's fjac fills a whole double Jacobian, which would then exist twice), one block of
   * parameters per camera (no cam_group, cam_shared or cam_param_group) and a solver other
   * than ldl-amd; otherwise the call fails (SBA_ERROR). 0 (the default): double, as in 1.6. */
  int single_precision_jacobian;
};

/* Fills *opt with the defaults (every field zero/NULL) and opt->size. */
extern void sba_ext_options_init(struct sba_ext_options *opt);
/* Zeroes *res and sets res->size. */
extern void sba_ext_result_init(struct sba_ext_result *res);
/* The known linear solver names, space-separated ("auto" among them). */
extern const char *sba_linsolver_names(void);
/* 1 if name (NULL allowed) is one of them, else 0. */
extern int sba_linsolver_valid(const char *name);
/* The known LM strategy names (sba_ext_options.strategy), space-separated. */
extern const char *sba_strategy_names(void);
/* 1 if name (NULL allowed) is one of them, else 0. */
extern int sba_strategy_valid(const char *name);
/* The known robust loss names (sba_ext_options.loss), space-separated; "none" is least squares. */
extern const char *sba_loss_names(void);
/* 1 if name (NULL allowed) is one of them, else 0. */
extern int sba_loss_valid(const char *name);

/* The six drivers of sba.h with one more argument. */
extern int sba_motstr_levmar_x_ext(
    const int n, const int ncon, const int m, const int mcon, char *vmask, double *p, const int cnp,
    const int pnp, double *x, double *covx, const int mnp,
    void (*func)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *hx, void *adata),
    void (*fjac)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *jac, void *adata),
    void *adata, const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
    double info[SBA_INFOSZ], const struct sba_ext_options *ext);

extern int sba_mot_levmar_x_ext(
    const int n, const int m, const int mcon, char *vmask, double *p, const int cnp, double *x,
    double *covx, const int mnp,
    void (*func)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *hx, void *adata),
    void (*fjac)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *jac, void *adata),
    void *adata, const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
    double info[SBA_INFOSZ], const struct sba_ext_options *ext);

extern int sba_str_levmar_x_ext(
    const int n, const int ncon, const int m, char *vmask, double *p, const int pnp, double *x,
    double *covx, const int mnp,
    void (*func)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *hx, void *adata),
    void (*fjac)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *jac, void *adata),
    void *adata, const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
    double info[SBA_INFOSZ], const struct sba_ext_options *ext);

extern int sba_motstr_levmar_ext(
    const int n, const int ncon, const int m, const int mcon, char *vmask, double *p, const int cnp,
    const int pnp, double *x, double *covx, const int mnp,
    void (*proj)(int j, int i, double *aj, double *bi, double *xij, void *adata),
    void (*projac)(int j, int i, double *aj, double *bi, double *Aij, double *Bij, void *adata),
    void *adata, const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
    double info[SBA_INFOSZ], const struct sba_ext_options *ext);

extern int sba_mot_levmar_ext(
    const int n, const int m, const int mcon, char *vmask, double *p, const int cnp, double *x,
    double *covx, const int mnp, void (*proj)(int j, int i, double *aj, double *xij, void *adata),
    void (*projac)(int j, int i, double *aj, double *Aij, void *adata), void *adata,
    const int itmax, const int verbose, const double opts[SBA_OPTSSZ], double info[SBA_INFOSZ],
    const struct sba_ext_options *ext);

extern int sba_str_levmar_ext(
    const int n, const int ncon, const int m, char *vmask, double *p, const int pnp, double *x,
    double *covx, const int mnp, void (*proj)(int j, int i, double *bi, double *xij, void *adata),
    void (*projac)(int j, int i, double *bi, double *Bij, void *adata), void *adata,
    const int itmax, const int verbose, const double opts[SBA_OPTSSZ], double info[SBA_INFOSZ],
    const struct sba_ext_options *ext);

/* ---- visibility as a list: problems whose dense n*m vmask would not fit ----
 * A 20000-camera, 2-million-point problem needs a 40 GB vmask; these entry points take the
 * visible (point, camera) pairs instead, in the order of x: sorted by point, then by camera,
 * each pair once. Memory then grows with the number of observations only (with a solver that
 * fits: the default linear solver of these entry points, with or without ext, is "auto",
 * which never picks a dense S that the memory cannot hold; SBA_LINSOLVER applies). Callbacks receive the same struct sba_crsm
 * index as with a vmask, but hx and the Jacobian may exceed 2^31 entries here: callbacks must
 * compute their offsets in 64-bit arithmetic, e.g. (size_t)idxij->val[k] * blocksize. */
struct sba_visibility {
  long long nvis;     /* number of visible projections (at most INT_MAX) */
  const int *point;   /* nvis point indices, ascending */
  const int *camera;  /* nvis camera indices, ascending within a point */
};

extern int sba_motstr_levmar_x_vis(
    const int n, const int ncon, const int m, const int mcon, const struct sba_visibility *vis,
    double *p, const int cnp, const int pnp, double *x, double *covx, const int mnp,
    void (*func)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *hx, void *adata),
    void (*fjac)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *jac, void *adata),
    void *adata, const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
    double info[SBA_INFOSZ], const struct sba_ext_options *ext);

extern int sba_motstr_levmar_vis(
    const int n, const int ncon, const int m, const int mcon, const struct sba_visibility *vis,
    double *p, const int cnp, const int pnp, double *x, double *covx, const int mnp,
    void (*proj)(int j, int i, double *aj, double *bi, double *xij, void *adata),
    void (*projac)(int j, int i, double *aj, double *bi, double *Aij, double *Bij, void *adata),
    void *adata, const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
    double info[SBA_INFOSZ], const struct sba_ext_options *ext);

/* Motion only and structure only (sba_mot_levmar_x_ext, sba_str_levmar_x_ext) with the pairs:
 * they solve one small system per camera (point), so no linear solver is involved. */
extern int sba_mot_levmar_x_vis(
    const int n, const int m, const int mcon, const struct sba_visibility *vis, double *p,
    const int cnp, double *x, double *covx, const int mnp,
    void (*func)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *hx, void *adata),
    void (*fjac)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *jac, void *adata),
    void *adata, const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
    double info[SBA_INFOSZ], const struct sba_ext_options *ext);

extern int sba_str_levmar_x_vis(
    const int n, const int ncon, const int m, const struct sba_visibility *vis, double *p,
    const int pnp, double *x, double *covx, const int mnp,
    void (*func)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *hx, void *adata),
    void (*fjac)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *jac, void *adata),
    void *adata, const int itmax, const int verbose, const double opts[SBA_OPTSSZ],
    double info[SBA_INFOSZ], const struct sba_ext_options *ext);

/* ---- covariance of the solution ----
 * At p (normally the minimum a motion-and-structure driver returned), the covariance of
 * chosen cameras and points: sigma^2 (J^T J)^-1 restricted to their blocks, computed through
 * the Schur complement (cameras: S^-1; points: V^-1 + V^-1 W^T S^-1 W V^-1), with
 * sigma^2 = ||e||^2 / (measurements - rank), the residual variance. Fixed cameras and points
 * (mcon, ncon) have zero covariance and fix the gauge; when they do not fix it completely, S
 * is singular and its pseudo-inverse is used: the covariance is then the one of the
 * minimum-norm camera update, and `rank` says how many directions are determined.
 * Points are different: every free point's block V_i must have full rank (pnp), tested with a
 * tolerance relative to its largest eigenvalue. A point that its projections do not determine
 * (seen by one camera only when mnp < pnp, or only from one camera centre, or with its
 * projections given zero weight by the loss) makes the call fail with SBA_ERROR and a
 * message naming it, e.g. "point 465 is seen by one camera only: its 3 parameters are not
 * determined by 2 measurements (V_i has rank 2 < pnp = 3)". No pseudo-inverse is offered
 * for it: its missing direction would couple into S and change the other blocks, and an
 * inverse of a rounding-level pivot is noise. Remove such points (or their projections) and
 * ask again.
 * With a robust loss in ext, J and e are reweighted as in the last iteration of the solve.
 * With shared camera parameters in ext (cam_group/cam_shared, cam_param_group), the covariance
 * is taken where a solve would start from p: every copy of a shared parameter at its first
 * camera's value (the one of least index), as a solve returns them. p itself is not
 * changed.
 * When the cameras' reduced system S has full rank (the gauge fixed by held cameras or
 * parameters), it is inverted by Cholesky factorization; otherwise, or when a pivot falls to
 * the rounding level of the largest diagonal entry, by the eigendecomposition above. */
struct sba_covariance_request {
  size_t size;           /* sizeof(struct sba_covariance_request); sba_covariance_request_init */
  int ncams;             /* cameras wanted ... */
  const int *cams;       /* ... their indices */
  double *camcov;        /* out: ncams blocks cnp x cnp, row-major */
  int npts;              /* points wanted ... */
  const int *pts;        /* ... their indices */
  double *ptcov;         /* out: npts blocks pnp x pnp, row-major */
  double sigma2;         /* out: the residual variance the blocks are scaled by */
  int rank;              /* out: rank of J^T J over the free parameters */
  int nfree;             /* out: number of free parameters (full rank: rank == nfree) */
  /* Nonzero: the blocks of (J^T J)^-1 itself, the covariance for measurements of unit
   * variance (COLMAP's and Ceres's convention), not scaled by sigma2 (still computed and
   * returned). A request of a size without this field (an older caller) is scaled. */
  int unscaled;
  /* Added to the diagonal of every free point's block V_i of J^T J before the cameras' system
   * is formed, as pycolmap's estimate_ba_covariance does with its BACovarianceOptions.damping
   * (1e-8 there by default): the blocks are then those of (J^T J + diag(0, d I))^-1. 0 (the
   * default, and for a request without this field): none, the covariance of J^T J itself.
   * Must be finite and >= 0. */
  double point_damping;
};
extern void sba_covariance_request_init(struct sba_covariance_request *req);

/* Expert callbacks as sba_motstr_levmar_x (fjac NULL: finite differences). Returns 0 on
 * success, SBA_ERROR on bad arguments or when a point is not determined by its projections
 * (see above: the message names the first such point). */
extern int sba_motstr_covariance_x(
    const int n, const int ncon, const int m, const int mcon, char *vmask, double *p, const int cnp,
    const int pnp, double *x, double *covx, const int mnp,
    void (*func)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *hx, void *adata),
    void (*fjac)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *jac, void *adata),
    void *adata, struct sba_covariance_request *req, const struct sba_ext_options *ext);
/* The same with the visible pairs instead of vmask (see sba_motstr_levmar_x_vis). */
extern int sba_motstr_covariance_x_vis(
    const int n, const int ncon, const int m, const int mcon, const struct sba_visibility *vis,
    double *p, const int cnp, const int pnp, double *x, double *covx, const int mnp,
    void (*func)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *hx, void *adata),
    void (*fjac)(double *p, struct sba_crsm *idxij, int *rcidxs, int *rcsubs, double *jac, void *adata),
    void *adata, struct sba_covariance_request *req, const struct sba_ext_options *ext);
/* Simple callbacks as sba_motstr_levmar (projac NULL: finite differences). */
extern int sba_motstr_covariance(
    const int n, const int ncon, const int m, const int mcon, char *vmask, double *p, const int cnp,
    const int pnp, double *x, double *covx, const int mnp,
    void (*proj)(int j, int i, double *aj, double *bi, double *xij, void *adata),
    void (*projac)(int j, int i, double *aj, double *bi, double *Aij, double *Bij, void *adata),
    void *adata, struct sba_covariance_request *req, const struct sba_ext_options *ext);

#ifdef __cplusplus
}
#endif

#endif /* SBA_EXT_H */
