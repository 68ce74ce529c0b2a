// SPDX-License-Identifier: BSD-3-Clause
// libFuzzer target: held and shared camera parameters through the public C API
// (sba_ext_options.cam_fixed, cam_fixed_per_camera, cam_group, cam_shared, cam_param_group),
// on tiny problems (1 to 4 cameras and points, a smooth model with its Jacobian), with any
// flags, any group numbers, mcon, and the motion-and-structure or the motion-only driver.
//
// Judged against the rules of sba_ext.h and docs/camera_parameters.md, written out here
// afresh: cam_param_group goes without cam_group and cam_shared; a cam_group number is -1 or
// in [0, m-1] and a cam_param_group number -1 or at least 0; cam_group and cam_shared go
// together; a camera below mcon shares nothing; and a shared parameter (cameras with one
// group number for it) is held in all of its cameras, with one value, or in none. Options
// that break a rule must be refused before anything runs (SBA_ERROR, info[6] =
// SBA_STOP_NONE, one error line); options that keep them are refused only when the problem
// has nothing to refine (the motion-only driver with every camera parameter held) or fewer
// measurements than unknowns, and a solve must return every held parameter (and every camera
// below mcon) with its bits, and every camera sharing a parameter with the same bits in it.
// The covariance (sba_motstr_covariance) at the start, whose copies of a shared parameter
// differ, must be the covariance where a solve starts, every copy at its first camera's
// value, to the bit, and leave p as given.
#include <fuzzer/FuzzedDataProvider.h>

#include <climits>
#include <cstdint>
#include <cstring>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "fuzz_common.h"
#include "sba_ext.h"

namespace {

using sbafuzz::require;

struct Problem {
  int m = 0, n = 0, cnp = 0, pnp = 0, mcon = 0;
  std::vector<double> points;  // for the motion-only driver, which does not refine them
};

constexpr int kMnp = 2;

// x_ij[k] = sum_c w(c, k, j) a_j[c] + sum_q v(q, k) b_i[q] + a_j[0] b_i[0] / 8: smooth, cheap,
// and every parameter in sight.
double w(int c, int k, int j) { return 0.5 + 0.25 * ((c + 2 * k + j) % 3); }
double v(int q, int k) { return 1.0 + 0.5 * ((q + k) % 2); }

void project(const Problem &p, int j, const double *aj, const double *bi, double *xij) {
  for (int k = 0; k < kMnp; ++k) {
    double s = aj[0] * bi[0] / 8;
    for (int c = 0; c < p.cnp; ++c) s += w(c, k, j) * aj[c];
    for (int q = 0; q < p.pnp; ++q) s += v(q, k) * bi[q];
    xij[k] = s;
  }
}

void jacobian_a(const Problem &p, int j, const double *bi, double *A) {
  for (int k = 0; k < kMnp; ++k)
    for (int c = 0; c < p.cnp; ++c) A[k * p.cnp + c] = w(c, k, j) + (c == 0 ? bi[0] / 8 : 0.0);
}

void motstr_proj(int j, int, double *aj, double *bi, double *xij, void *adata) {
  project(*static_cast<Problem *>(adata), j, aj, bi, xij);
}

void motstr_projac(int j, int, double *aj, double *bi, double *A, double *B, void *adata) {
  const Problem &p = *static_cast<Problem *>(adata);
  jacobian_a(p, j, bi, A);
  for (int k = 0; k < kMnp; ++k)
    for (int q = 0; q < p.pnp; ++q) B[k * p.pnp + q] = v(q, k) + (q == 0 ? aj[0] / 8 : 0.0);
}

void mot_proj(int j, int i, double *aj, double *xij, void *adata) {
  Problem &p = *static_cast<Problem *>(adata);
  project(p, j, aj, p.points.data() + i * p.pnp, xij);
}

void mot_projac(int j, int i, double *, double *A, void *adata) {
  Problem &p = *static_cast<Problem *>(adata);
  jacobian_a(p, j, p.points.data() + i * p.pnp, A);
}

struct Log {
  std::vector<std::string> errors;
};

void log_sink(void *ctx, int level, const char *line) {
  if (level == SBA_LOG_ERROR) static_cast<Log *>(ctx)->errors.emplace_back(line);
}

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// Camera j's group number for parameter a, whichever way the options give it: -1 for none.
int group_of(const Problem &p, const int *group, const char *shared, const int *param_group, int j, int a) {
  if (param_group) return param_group[j * p.cnp + a];
  return group && shared[a] ? group[j] : -1;
}

// Camera j's parameter a (at j * cnp + a): the first camera of its group, whose value the
// group's copies take, or -1 for a parameter of its own.
std::vector<int> first_cameras(const Problem &p, const int *group, const char *shared, const int *param_group) {
  std::vector<int> out(size_t(p.m) * p.cnp, -1);
  std::map<std::pair<int, int>, int> first;  // (parameter, group number) -> its first camera
  for (int j = 0; j < p.m; ++j)
    for (int a = 0; a < p.cnp; ++a) {
      const int g = group_of(p, group, shared, param_group, j, a);
      if (g != -1) out[size_t(j) * p.cnp + a] = first.emplace(std::make_pair(a, g), j).first->second;
    }
  return out;
}

// The rules, as sba_ext.h states them: empty when the options keep them, else which one is broken.
std::string broken_rule(const Problem &p, const double *x0, const char *fixed, bool per_camera, const int *group,
                        const char *shared, const int *param_group) {
  if (param_group && (group || shared)) return "cam_param_group with cam_group or cam_shared";
  if (shared && !group) return "cam_shared without cam_group";
  if (group && !shared) return "cam_group without cam_shared";
  if (!group && !param_group) return {};
  for (int j = 0; j < p.m; ++j)
    for (int a = 0; a < (group ? 1 : p.cnp); ++a) {
      const int g = group ? group[j] : param_group[j * p.cnp + a];
      if (g == -1) continue;
      if (g < -1 || (group && g >= p.m)) return "a group number out of range";
      if (j < p.mcon) return "a camera below mcon in a group";
    }
  auto held = [&](int j, int a) { return fixed && fixed[per_camera ? j * p.cnp + a : a] != 0; };
  const std::vector<int> first = first_cameras(p, group, shared, param_group);
  for (int j = 0; j < p.m; ++j)
    for (int a = 0; a < p.cnp; ++a) {
      const int f = first[size_t(j) * p.cnp + a];
      if (f == -1) continue;
      if (held(j, a) != held(f, a)) return "a shared parameter held in only some of its cameras";
      if (held(j, a) && !same_bits(x0[j * p.cnp + a], x0[f * p.cnp + a]))
        return "a shared parameter held with different values";
    }
  return {};
}

char next_flag(FuzzedDataProvider &in) {
  static const char kFlags[] = {0, 0, 1, 2, -1};
  return kFlags[in.ConsumeIntegralInRange<size_t>(0, sizeof kFlags - 1)];
}

int next_group(FuzzedDataProvider &in, int m) {
  switch (in.ConsumeIntegralInRange<int>(0, 7)) {
    case 0:
      return -1;
    case 1:
      return in.ConsumeIntegral<int>();
    case 2:
      return in.ConsumeIntegralInRange<int>(-3, m + 1);
    case 3:
      return in.ConsumeBool() ? INT_MAX : INT_MIN;
    default:
      return in.ConsumeIntegralInRange<int>(0, 1);
  }
}

// The covariance of every camera and point at p, as sba_motstr_covariance gives it.
struct Covariance {
  int ret = 0, rank = 0, nfree = 0;
  double sigma2 = 0;
  std::vector<double> camcov, ptcov;
  bool operator==(const Covariance &o) const {
    return ret == o.ret && rank == o.rank && nfree == o.nfree && same_bits(sigma2, o.sigma2) &&
           camcov.size() == o.camcov.size() && ptcov.size() == o.ptcov.size() &&
           std::memcmp(camcov.data(), o.camcov.data(), camcov.size() * sizeof(double)) == 0 &&
           std::memcmp(ptcov.data(), o.ptcov.data(), ptcov.size() * sizeof(double)) == 0;
  }
};

Covariance covariance(Problem &p, std::vector<double> &at, std::vector<char> &vmask, std::vector<double> &x,
                      const sba_ext_options &ext) {
  Covariance c;
  std::vector<int> cams(size_t(p.m)), pts(size_t(p.n));
  for (int j = 0; j < p.m; ++j) cams[size_t(j)] = j;
  for (int i = 0; i < p.n; ++i) pts[size_t(i)] = i;
  c.camcov.assign(size_t(p.m) * p.cnp * p.cnp, 0.0);
  c.ptcov.assign(size_t(p.n) * p.pnp * p.pnp, 0.0);
  sba_covariance_request req;
  sba_covariance_request_init(&req);
  req.ncams = p.m;
  req.cams = cams.data();
  req.camcov = c.camcov.data();
  req.npts = p.n;
  req.pts = pts.data();
  req.ptcov = c.ptcov.data();
  Log log;  // the solve's log left to the solve
  sba_ext_options own = ext;
  own.log_ctx = &log;
  c.ret = sba_motstr_covariance(p.n, 0, p.m, p.mcon, vmask.data(), at.data(), p.cnp, p.pnp, x.data(), nullptr,
                                kMnp, motstr_proj, motstr_projac, &p, &req, &own);
  for (const std::string &e : log.errors)
    require(!e.empty() && e.find('\n') == std::string::npos, "a covariance error of more than one line: " + e);
  c.rank = req.rank;
  c.nfree = req.nfree;
  c.sigma2 = req.sigma2;
  return c;
}

// At x0 (whose shared copies differ) the covariance is the one at x0 with each copy at its
// first camera's value, and x0 is left as given.
void check_covariance(Problem &p, const std::vector<double> &x0, std::vector<char> &vmask, std::vector<double> &x,
                      const sba_ext_options &ext) {
  std::vector<double> tied = x0, given = x0;
  const std::vector<int> first = first_cameras(p, ext.cam_group, ext.cam_shared, ext.cam_param_group);
  for (size_t k = 0; k < first.size(); ++k)
    if (first[k] != -1) tied[k] = x0[size_t(first[k]) * p.cnp + k % size_t(p.cnp)];
  const Covariance want = covariance(p, tied, vmask, x, ext);
  const Covariance got = covariance(p, given, vmask, x, ext);
  require(std::memcmp(given.data(), x0.data(), x0.size() * sizeof(double)) == 0, "the covariance changed p");
  require(got == want, "the covariance at p is not the one where the shared copies are tied");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
  FuzzedDataProvider in(data, size);
  Problem p;
  const bool motion_only = in.ConsumeBool();
  p.m = in.ConsumeIntegralInRange<int>(1, 4);
  p.n = in.ConsumeIntegralInRange<int>(1, 4);
  p.cnp = in.ConsumeIntegralInRange<int>(1, 4);
  p.pnp = in.ConsumeIntegralInRange<int>(1, 3);
  p.mcon = in.ConsumeIntegralInRange<int>(0, p.m);
  const bool per_camera = in.ConsumeBool();
  std::vector<char> fixed, shared;
  std::vector<int> group, param_group;
  if (in.ConsumeBool())
    for (int k = 0; k < (per_camera ? p.m : 1) * p.cnp; ++k) fixed.push_back(next_flag(in));
  if (in.ConsumeBool())
    for (int j = 0; j < p.m; ++j) group.push_back(next_group(in, p.m));
  if (in.ConsumeBool())
    for (int a = 0; a < p.cnp; ++a) shared.push_back(next_flag(in));
  if (in.ConsumeBool())
    for (int k = 0; k < p.m * p.cnp; ++k) param_group.push_back(next_group(in, p.m));

  // Parameters and measurements: the model at slightly other parameters.
  std::vector<double> x0(size_t(p.m) * p.cnp + size_t(p.n) * p.pnp);
  for (double &q : x0) q = in.ConsumeIntegralInRange<int>(-4, 4) * 0.25 + 1.0;
  p.points.assign(x0.begin() + p.m * p.cnp, x0.end());
  std::vector<double> x;
  for (int i = 0; i < p.n; ++i)
    for (int j = 0; j < p.m; ++j) {
      double xij[kMnp];
      project(p, j, x0.data() + j * p.cnp, x0.data() + p.m * p.cnp + i * p.pnp, xij);
      for (double q : xij) x.push_back(q + in.ConsumeIntegralInRange<int>(-2, 2) * 0.01);
    }
  std::vector<char> vmask(size_t(p.n) * p.m, 1);

  Log log;
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.nthreads = 1;
  ext.log = log_sink;
  ext.log_ctx = &log;
  ext.cam_fixed = fixed.empty() ? nullptr : fixed.data();
  ext.cam_fixed_per_camera = per_camera ? 1 : 0;
  ext.cam_group = group.empty() ? nullptr : group.data();
  ext.cam_shared = shared.empty() ? nullptr : shared.data();
  ext.cam_param_group = param_group.empty() ? nullptr : param_group.data();
  double info[SBA_INFOSZ];
  std::vector<double> sol = x0;
  const int ret =
      motion_only
          ? sba_mot_levmar_ext(p.n, p.m, p.mcon, vmask.data(), sol.data(), p.cnp, x.data(), nullptr, kMnp,
                               mot_proj, mot_projac, &p, 5, 0, nullptr, info, &ext)
          : sba_motstr_levmar_ext(p.n, 0, p.m, p.mcon, vmask.data(), sol.data(), p.cnp, p.pnp, x.data(),
                                  nullptr, kMnp, motstr_proj, motstr_projac, &p, 5, 0, nullptr, info, &ext);

  const std::string rule =
      broken_rule(p, x0.data(), ext.cam_fixed, per_camera, ext.cam_group, ext.cam_shared, ext.cam_param_group);
  const bool refused = ret == SBA_ERROR && info[6] == SBA_STOP_NONE;
  for (const std::string &e : log.errors)
    require(!e.empty() && e.find('\n') == std::string::npos, "an error of more than one line: " + e);
  if (!rule.empty()) {
    require(refused, "options with " + rule + " were taken");
    require(log.errors.size() == 1, "a refusal with " + std::to_string(log.errors.size()) + " error lines");
    return 0;
  }
  if (!motion_only) check_covariance(p, x0, vmask, x, ext);
  auto held = [&](int j, int a) {
    return j < p.mcon || (!fixed.empty() && fixed[per_camera ? j * p.cnp + a : a] != 0);
  };
  // The unknowns: the points' (motion and structure), and each camera parameter neither held
  // nor below mcon, those that cameras share counted once.
  std::set<std::pair<int, int>> shared_unknowns;  // (parameter, group number)
  long long unknowns = motion_only ? 0 : static_cast<long long>(p.n) * p.pnp;
  for (int j = 0; j < p.m; ++j)
    for (int a = 0; a < p.cnp; ++a) {
      if (held(j, a)) continue;
      const int g = group_of(p, ext.cam_group, ext.cam_shared, ext.cam_param_group, j, a);
      if (g == -1) ++unknowns;
      else shared_unknowns.emplace(a, g);
    }
  unknowns += static_cast<long long>(shared_unknowns.size());
  const std::string why = log.errors.empty() ? std::string("(no error line)") : log.errors.front();
  // The problem itself is good (every point seen by every camera, finite values), but all of
  // it may be held, or more unknowns left than measurements.
  const long long nobs = static_cast<long long>(p.n) * p.m * kMnp;
  if (unknowns == 0 || nobs < unknowns) {
    const char *due = unknowns == 0 ? "nothing to refine" : "fewer measurements";
    require(refused && why.find(due) != std::string::npos,
            std::to_string(unknowns) + " unknowns for " + std::to_string(nobs) + " measurements, and " + why);
    return 0;
  }
  require(!refused, "good options refused: " + why);
  if (ret < 0) return 0;  // a numerical failure: what p holds then is not promised
  for (int j = 0; j < p.m; ++j)
    for (int a = 0; a < p.cnp; ++a)
      if (held(j, a)) require(same_bits(sol[j * p.cnp + a], x0[j * p.cnp + a]), "a held parameter moved");
  if (motion_only)
    for (size_t q = size_t(p.m) * p.cnp; q < sol.size(); ++q)
      require(same_bits(sol[q], x0[q]), "the motion-only driver moved a point");
  const std::vector<int> first = first_cameras(p, ext.cam_group, ext.cam_shared, ext.cam_param_group);
  for (size_t k = 0; k < first.size(); ++k)
    if (first[k] != -1)
      require(same_bits(sol[k], sol[size_t(first[k]) * p.cnp + k % size_t(p.cnp)]),
              "the cameras sharing a parameter differ in it");
  return 0;
}
