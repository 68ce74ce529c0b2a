// SPDX-License-Identifier: BSD-3-Clause
// What the extensions of sba_ext.h cost, on a series of generated problems (sbagen orbit
// scenes, fixed K): time per LM iteration with and without each robust loss, and the time of
// the covariance of the solution (every camera and point) against the problem size.
// Prints a Markdown table; --out FILE appends one JSON object per problem.
//   features_bench [--sizes CAMERASxPOINTS,...] [--threads N] [--out FILE]
#include <chrono>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "bench_problem.h"
#include "sba_ext.h"

namespace {

using sbabench::Problem;
using Clock = std::chrono::steady_clock;

struct Timing {
  double seconds = 0;
  int iterations = 0, solves = 0;
  bool ok = false;
};

Timing solve(Problem &prob, std::vector<double> &p, const char *loss, int threads, int itmax) {
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.linsolver = "chol";
  ext.nthreads = threads;
  ext.parallel_callbacks = 1;
  ext.quiet = 1;
  ext.loss = loss;
  ext.loss_scale = 2.0;
  const sba_visibility vis{static_cast<long long>(prob.obs_point.size()), prob.obs_point.data(),
                           prob.obs_camera.data()};
  double info[SBA_INFOSZ];
  const auto t0 = Clock::now();
  const int ret = sba_motstr_levmar_x_vis(prob.n, 0, prob.m, 2, &vis, p.data(), prob.cnp, Problem::pnp,
                                          prob.x.data(), nullptr, Problem::mnp, prob.func(), prob.fjac(),
                                          prob.adata(), itmax, 0, nullptr, info, &ext);
  Timing t;
  t.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  t.iterations = static_cast<int>(info[5]);
  t.solves = static_cast<int>(info[9]);
  t.ok = ret != SBA_ERROR;
  return t;
}

}  // namespace

int main(int argc, char **argv) {
  std::string sizes = "10x1000,30x4000,60x10000,120x20000,240x40000";
  std::string out;
  int threads = 0;
  for (int k = 1; k < argc; ++k) {
    const std::string a = argv[k];
    if (a == "--sizes" && k + 1 < argc) sizes = argv[++k];
    else if (a == "--threads" && k + 1 < argc) threads = std::atoi(argv[++k]);
    else if (a == "--out" && k + 1 < argc) out = argv[++k];
    else {
      std::fprintf(stderr, "usage: features_bench [--sizes CxP,...] [--threads N] [--out FILE]\n");
      return 2;
    }
  }
  std::FILE *json = out.empty() ? nullptr : std::fopen(out.c_str(), "a");
  if (!out.empty() && !json) {
    std::fprintf(stderr, "features_bench: cannot open %s\n", out.c_str());
    return 1;
  }
  const int kIters = 10;
  std::printf("| cameras | points | observations | LS ms/solve | huber | cauchy | soft-l1 | tukey | "
              "covariance [s] (all cameras and points) |\n|---|---|---|---|---|---|---|---|---|\n");
  for (std::size_t start = 0; start < sizes.size();) {
    std::size_t comma = sizes.find(',', start);
    if (comma == std::string::npos) comma = sizes.size();
    const std::string item = sizes.substr(start, comma - start);
    start = comma + 1;
    int cams = 0, pts = 0;
    if (std::sscanf(item.c_str(), "%dx%d", &cams, &pts) != 2) continue;
    Problem prob;
    std::string error;
    const std::string spec = "cameras=" + std::to_string(cams) + ",points=" + std::to_string(pts) +
                             ",track=2..8,trajectory=orbit,seed=3";
    if (!sbabench::generate(spec, &prob, &error)) {
      std::fprintf(stderr, "features_bench: %s\n", error.c_str());
      return 1;
    }
    double ms[5] = {};
    const char *losses[5] = {nullptr, "huber", "cauchy", "soft-l1", "tukey"};
    std::vector<double> solved;
    for (int l = 0; l < 5; ++l) {
      std::vector<double> p = prob.p0;
      const Timing t = solve(prob, p, losses[l], threads, kIters);
      // Per linear system tried: the losses change how many steps LM rejects, and that is
      // not a cost of the loss itself.
      ms[l] = t.ok && t.solves > 0 ? 1e3 * t.seconds / t.solves : -1;
      if (l == 0) solved = p;
    }
    // The covariance at the least-squares solution, two cameras fixing the gauge.
    std::vector<int> cidx(static_cast<std::size_t>(prob.m)), pidx(static_cast<std::size_t>(prob.n));
    for (int j = 0; j < prob.m; ++j) cidx[size_t(j)] = j;
    for (int i = 0; i < prob.n; ++i) pidx[size_t(i)] = i;
    std::vector<double> camcov(size_t(prob.m) * prob.cnp * prob.cnp), ptcov(size_t(prob.n) * 9);
    std::vector<char> vmask(size_t(prob.n) * size_t(prob.m), 0);  // the covariance takes a vmask
    for (std::size_t k = 0; k < prob.obs_point.size(); ++k)
      vmask[size_t(prob.obs_point[k]) * prob.m + size_t(prob.obs_camera[k])] = 1;
    sba_covariance_request req;
    sba_covariance_request_init(&req);
    req.ncams = prob.m;
    req.cams = cidx.data();
    req.camcov = camcov.data();
    req.npts = prob.n;
    req.pts = pidx.data();
    req.ptcov = ptcov.data();
    sba_ext_options ext;
    sba_ext_options_init(&ext);
    ext.nthreads = threads;
    ext.parallel_callbacks = 1;
    ext.quiet = 1;
    const auto t0 = Clock::now();
    const int cret = sba_motstr_covariance_x(prob.n, 0, prob.m, 2, vmask.data(),
                                             solved.data(), prob.cnp, Problem::pnp, prob.x.data(), nullptr,
                                             Problem::mnp, prob.func(), prob.fjac(), prob.adata(), &req, &ext);
    const double cov_s = std::chrono::duration<double>(Clock::now() - t0).count();
    auto cell = [](double v, double base) {
      char buf[64];
      if (v < 0) return std::string("-");
      if (base > 0) std::snprintf(buf, sizeof buf, "%.1f (%.2fx)", v, v / base);
      else std::snprintf(buf, sizeof buf, "%.1f", v);
      return std::string(buf);
    };
    std::printf("| %d | %d | %zu | %s | %s | %s | %s | %s | %s |\n", prob.m, prob.n, prob.nobs(),
                cell(ms[0], 0).c_str(), cell(ms[1], ms[0]).c_str(), cell(ms[2], ms[0]).c_str(),
                cell(ms[3], ms[0]).c_str(), cell(ms[4], ms[0]).c_str(),
                cret == 0 ? std::to_string(cov_s).c_str() : "failed");
    std::fflush(stdout);
    if (json)
      std::fprintf(json,
                   "{\"cameras\": %d, \"points\": %d, \"observations\": %zu, \"ms_per_solve\": {\"none\": %g, "
                   "\"huber\": %g, \"cauchy\": %g, \"soft-l1\": %g, \"tukey\": %g}, \"covariance_s\": %g}\n",
                   prob.m, prob.n, prob.nobs(), ms[0], ms[1], ms[2], ms[3], ms[4], cret == 0 ? cov_s : -1.0);
  }
  if (json) std::fclose(json);
  return 0;
}
