// SPDX-License-Identifier: BSD-3-Clause
// libFuzzer target: held and shared camera parameters through the public C API
// (sba_ext_options.cam_fixed, cam_fixed_per_camera, cam_group, cam_shared), on tiny problems
// (1 to 4 cameras and points, a smooth model with its Jacobian), with any flags, any group
// numbers, mcon, and the motion-and-structure or the motion-only driver.
//
// Judged against the rules of sba_ext.h and docs/camera_parameters.md, written out here
// afresh: a group number is -1 or in [0, m-1], cam_group needs cam_shared, a camera below mcon
// is in no group, and a shared parameter is held in all of its group's cameras or in none.
// Options that break a rule must be refused before anything runs (SBA_ERROR, info[6] =
// SBA_STOP_NONE, one error line); options that keep them must not be refused for them, and a
// solve must return every held parameter (and every camera below mcon) with its bits, and
// every camera of a group with the same bits in its shared parameters.
#include <fuzzer/FuzzedDataProvider.h>

#include <cstdint>
#include <cstring>
#include <map>
#include <string>
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

// The rules, as sba_ext.h states them: empty when the options keep them, else which one is broken.
bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

std::string broken_rule(const Problem &p, const double *x0, const char *fixed, bool per_camera, const int *group,
                        const char *shared) {
  if (shared && !group) return "cam_shared without cam_group";
  if (!group) return {};
  if (!shared) return "cam_group without cam_shared";
  auto held = [&](int j, int a) { return fixed && fixed[per_camera ? j * p.cnp + a : a] != 0; };
  std::map<int, int> first;
  for (int j = 0; j < p.m; ++j) {
    if (group[j] == -1) continue;
    if (group[j] < 0 || group[j] >= p.m) return "a group number out of range";
    if (j < p.mcon) return "a camera below mcon in a group";
    const int f = first.emplace(group[j], j).first->second;
    for (int a = 0; a < p.cnp; ++a) {
      if (shared[a] && held(j, a) != held(f, a)) return "a shared parameter held in only some cameras of a group";
      if (shared[a] && held(j, a) && !same_bits(x0[j * p.cnp + a], x0[f * p.cnp + a]))
        return "a shared parameter held with different values in a group";
    }
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
    default:
      return in.ConsumeIntegralInRange<int>(0, 1);
  }
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
  std::vector<int> group;
  if (in.ConsumeBool())
    for (int k = 0; k < (per_camera ? p.m : 1) * p.cnp; ++k) fixed.push_back(next_flag(in));
  if (in.ConsumeBool())
    for (int j = 0; j < p.m; ++j) group.push_back(next_group(in, p.m));
  if (in.ConsumeBool())
    for (int a = 0; a < p.cnp; ++a) shared.push_back(next_flag(in));

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
  double info[SBA_INFOSZ];
  std::vector<double> sol = x0;
  const int ret =
      motion_only
          ? sba_mot_levmar_ext(p.n, p.m, p.mcon, vmask.data(), sol.data(), p.cnp, x.data(), nullptr, kMnp,
                               mot_proj, mot_projac, &p, 5, 0, nullptr, info, &ext)
          : sba_motstr_levmar_ext(p.n, 0, p.m, p.mcon, vmask.data(), sol.data(), p.cnp, p.pnp, x.data(),
                                  nullptr, kMnp, motstr_proj, motstr_projac, &p, 5, 0, nullptr, info, &ext);

  const std::string rule =
      broken_rule(p, x0.data(), ext.cam_fixed, per_camera, ext.cam_group, ext.cam_shared);
  const bool refused = ret == SBA_ERROR && info[6] == SBA_STOP_NONE;
  for (const std::string &e : log.errors)
    require(!e.empty() && e.find('\n') == std::string::npos, "an error of more than one line: " + e);
  if (!rule.empty()) {
    require(refused, "options with " + rule + " were taken");
    require(log.errors.size() == 1, "a refusal with " + std::to_string(log.errors.size()) + " error lines");
    return 0;
  }
  if (refused) {
    const std::string why = log.errors.empty() ? std::string("(no error line)") : log.errors.front();
    // The problem itself is good (every point seen by every camera, finite values), but all of
    // it may be held, or so little left free that the measurements fall short of it: not the
    // options' fault.
    const bool too_little = why.find("nothing to refine") != std::string::npos ||
                            why.find("fewer measurements") != std::string::npos;
    require(too_little || (why.find("cam_") == std::string::npos && why.find("group") == std::string::npos &&
                           why.find("held") == std::string::npos),
            "good options refused: " + why);
    return 0;
  }
  if (ret < 0) return 0;  // a numerical failure: what p holds then is not promised
  auto held = [&](int j, int a) {
    return j < p.mcon || (!fixed.empty() && fixed[per_camera ? j * p.cnp + a : a] != 0);
  };
  for (int j = 0; j < p.m; ++j)
    for (int a = 0; a < p.cnp; ++a)
      if (held(j, a)) require(same_bits(sol[j * p.cnp + a], x0[j * p.cnp + a]), "a held parameter moved");
  if (motion_only)
    for (size_t q = size_t(p.m) * p.cnp; q < sol.size(); ++q)
      require(same_bits(sol[q], x0[q]), "the motion-only driver moved a point");
  if (group.empty()) return 0;
  std::map<int, int> first;
  for (int j = 0; j < p.m; ++j) {
    if (group[j] == -1) continue;
    const int f = first.emplace(group[j], j).first->second;
    for (int a = 0; a < p.cnp; ++a)
      if (shared[a] && !held(j, a))
        require(same_bits(sol[j * p.cnp + a], sol[f * p.cnp + a]),
                "the cameras of a group differ in a shared parameter");
  }
  return 0;
}
