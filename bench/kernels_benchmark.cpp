// SPDX-License-Identifier: BSD-3-Clause
// Micro-benchmarks of what the public API reaches: one LM iteration per linear solver
// (itmax 1, so setup + one Jacobian + the normal equations + at least one solve), the
// Jacobian and projection callbacks of the demo's and BAL's camera models and of sbarefine's
// COLMAP models, and the dense factorization of a matrix the size of S. Record results with
//   kernels_benchmark --benchmark_out=bench/results/kernels.json --benchmark_out_format=json
#include <benchmark/benchmark.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "bench_problem.h"
#include "cameras/colmap_camera.h"
#include "sba.h"
#include "sba_ext.h"

namespace {

using sbabench::Problem;

const std::string kData = SBA_SHARED_DATA_DIR;

// Problems are loaded once per process, on first use.
const Problem *problem(const std::string &key) {
  static std::map<std::string, std::unique_ptr<Problem>> cache;
  auto it = cache.find(key);
  if (it != cache.end()) return it->second.get();
  auto p = std::make_unique<Problem>();
  std::string error;
  bool ok = false;
  if (key == "54cams")
    ok = sbabench::load_eucsba(kData + "/sba-demo/54cams.txt", kData + "/sba-demo/54pts.txt",
                               kData + "/sba-demo/calib.txt", p.get(), &error);
  else if (key == "54camsvarKD")
    ok = sbabench::load_eucsba(kData + "/sba-demo/54camsvarKD.txt", kData + "/sba-demo/54pts.txt", "", p.get(),
                               &error);
  else if (key == "bal49")
    ok = sbabench::load_bal(kData + "/bal/problem-49-7776-pre.txt.bz2", p.get(), &error);
  if (!ok) p.reset();
  return (cache[key] = std::move(p)).get();
}

// sba's index of visible projections (row = point, column = camera, value = ordinal).
struct Index {
  std::vector<int> val, colidx, rowptr;
  sba_crsm crsm{};
  explicit Index(const Problem &p) {
    rowptr.push_back(0);
    for (int i = 0; i < p.n; ++i) {
      for (int j = 0; j < p.m; ++j)
        if (p.vmask[static_cast<std::size_t>(i) * p.m + j]) {
          val.push_back(static_cast<int>(val.size()));
          colidx.push_back(j);
        }
      rowptr.push_back(static_cast<int>(val.size()));
    }
    crsm = {p.n, p.m, static_cast<int>(val.size()), val.data(), colidx.data(), rowptr.data()};
  }
};

void BM_Solve1(benchmark::State &state, std::string key, std::string solver, int threads) {
  const Problem *prob = problem(key);
  if (!prob) {
    state.SkipWithError("shared data not found");
    return;
  }
  Problem &p = const_cast<Problem &>(*prob);  // sba takes non-const vmask and x; it writes neither
  sba_ext_options ext;
  sba_ext_options_init(&ext);
  ext.linsolver = solver.c_str();
  ext.nthreads = threads;
  // The demo and BAL models' callbacks are re-entrant and walk the index by rows.
  ext.parallel_callbacks = 1;
  ext.quiet = 1;
  std::array<double, SBA_INFOSZ> info{};
  for (auto _ : state) {
    std::vector<double> params = p.p0;
    const int ret = sba_motstr_levmar_x_ext(p.n, 0, p.m, 0, p.vmask.data(), params.data(), p.cnp, 3, p.x.data(),
                                            nullptr, 2, p.func(), p.fjac(), p.adata(), 1, 0, nullptr, info.data(),
                                            &ext);
    if (ret == SBA_ERROR) {
      state.SkipWithError("sba returned SBA_ERROR");
      return;
    }
    benchmark::DoNotOptimize(params.data());
  }
  state.counters["linear_solves"] = info[9];
}

void BM_Callback(benchmark::State &state, std::string key, bool jacobian) {
  const Problem *prob = problem(key);
  if (!prob) {
    state.SkipWithError("shared data not found");
    return;
  }
  const Problem &p = *prob;
  Index idx(p);
  std::vector<double> params = p.p0;
  const std::size_t block = jacobian ? 2 * static_cast<std::size_t>(p.cnp + 3) : 2;
  std::vector<double> out(p.nobs() * block);
  const auto fn = jacobian ? p.fjac() : p.func();
  for (auto _ : state) {
    fn(params.data(), &idx.crsm, nullptr, nullptr, out.data(), p.adata());
    benchmark::DoNotOptimize(out.data());
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()) * static_cast<int64_t>(p.nobs()));
}

// A scene of problem-49's size for sbarefine's callbacks of one COLMAP model: 49 cameras on a
// circle around the points, looking at them, each point seen by four cameras in a row; the
// principal point held, as sbarefine holds it by default.
struct ColmapScene {
  std::unique_ptr<sbacameras::colmap_camera::CameraModel> model;
  std::vector<double> p;
  std::vector<int> val, colidx, rowptr{0};
  sba_crsm crsm{};
  explicit ColmapScene(int id) {
    namespace cc = sbacameras::colmap_camera;
    constexpr int m = 49, n = 7776, track = 4;
    const double pinhole[] = {1000, 1000, 500, 400}, extra[] = {-0.05, 0.01, 0.001, -0.002};
    std::vector<cc::Camera> cams(m);
    std::vector<std::vector<int>> kept(m);
    for (int j = 0; j < m; ++j) {
      cc::Camera &c = cams[static_cast<std::size_t>(j)];
      c.model = id;
      const int nf = cc::focal_count(id), np = cc::param_count(id);
      for (int k = 0; k < np; ++k) {
        c.params.push_back(k < nf ? pinhole[0] : k < nf + 2 ? pinhole[2 + k - nf] : extra[k - nf - 2]);
        if (k < nf || k >= nf + 2) kept[static_cast<std::size_t>(j)].push_back(k);
      }
      // R = rotation about y by phi, whose optical axis (R's third row) points from the centre
      // C = 10 (sin phi, 0, -cos phi) to the origin; t = -R C.
      const double phi = 6.283185307179586 * j / m;
      c.q = {std::cos(phi / 2), 0, std::sin(phi / 2), 0};
      double R[9];
      sbacameras::euclidean::rotation_matrix(c.q, R);
      const double C[3] = {10 * std::sin(phi), 0, -10 * std::cos(phi)};
      for (int r = 0; r < 3; ++r)
        c.t[static_cast<std::size_t>(r)] = -(R[3 * r] * C[0] + R[3 * r + 1] * C[1] + R[3 * r + 2] * C[2]);
    }
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(-1, 1);
    std::vector<double> points(3 * static_cast<std::size_t>(n));
    for (double &x : points) x = u(rng);
    model = std::make_unique<cc::CameraModel>(cams, points, std::vector<char>{}, kept);
    p = model->initial_camera_params();
    p.insert(p.end(), points.begin(), points.end());
    for (int i = 0; i < n; ++i) {
      std::vector<int> seen;
      for (int k = 0; k < track; ++k) seen.push_back((i + k) % m);
      std::sort(seen.begin(), seen.end());  // a row's cameras ascending, as sba's index has them
      for (int j : seen) {
        colidx.push_back(j);
        val.push_back(static_cast<int>(val.size()));
      }
      rowptr.push_back(static_cast<int>(val.size()));
    }
    crsm = {n, m, static_cast<int>(val.size()), val.data(), colidx.data(), rowptr.data()};
  }
};

void BM_ColmapCallback(benchmark::State &state, int id, bool jacobian) {
  namespace cc = sbacameras::colmap_camera;
  ColmapScene scene(id);
  const std::size_t block = jacobian ? 2 * static_cast<std::size_t>(scene.model->cnp() + 3) : 2;
  std::vector<double> out(static_cast<std::size_t>(scene.crsm.nnz) * block);
  const auto fn = jacobian ? cc::motstr_fjac : cc::motstr_func;
  for (auto _ : state) {
    fn(scene.p.data(), &scene.crsm, nullptr, nullptr, out.data(), cc::as_adata(*scene.model));
    benchmark::DoNotOptimize(out.data());
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()) * scene.crsm.nnz);
}

// sba_Axb_Chol on an SPD matrix of the size of S (m * cnp).
void BM_AxbChol(benchmark::State &state) {
  const int size = static_cast<int>(state.range(0));
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  // Symmetric with a dominant diagonal, hence SPD.
  std::vector<double> A(static_cast<std::size_t>(size) * size), b(size), x(size);
  for (int r = 0; r < size; ++r)
    for (int c = 0; c <= r; ++c)
      A[static_cast<std::size_t>(r) * size + c] = A[static_cast<std::size_t>(c) * size + r] =
          r == c ? size + 1.0 : u(rng);
  for (double &v : b) v = u(rng);
  for (auto _ : state) {
    if (!sba_Axb_Chol(A.data(), b.data(), x.data(), size, 0)) {
      state.SkipWithError("sba_Axb_Chol failed");
      return;
    }
    benchmark::DoNotOptimize(x.data());
  }
  state.counters["flops"] = benchmark::Counter(std::pow(static_cast<double>(size), 3) / 3.0,
                                               benchmark::Counter::kIsIterationInvariantRate);
}

void register_all() {
  const int all = std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  std::vector<int> threads{1};
  if (all > 1) threads.push_back(all);
  for (const char *key : {"54cams", "54camsvarKD", "bal49"})
    for (const char *solver : {"chol", "ldl-amd", "sparse-chol"})
      for (int t : threads)
        benchmark::RegisterBenchmark((std::string("Solve1/") + key + "/" + solver + "/threads:" + std::to_string(t)).c_str(),
                                     BM_Solve1, std::string(key), std::string(solver), t)
            ->Unit(benchmark::kMillisecond);
  for (const char *key : {"54cams", "54camsvarKD", "bal49"}) {
    benchmark::RegisterBenchmark((std::string("Func/") + key).c_str(), BM_Callback, std::string(key), false)
        ->Unit(benchmark::kMicrosecond);
    benchmark::RegisterBenchmark((std::string("Fjac/") + key).c_str(), BM_Callback, std::string(key), true)
        ->Unit(benchmark::kMicrosecond);
  }
  namespace cc = sbacameras::colmap_camera;
  for (int id : {cc::kSimplePinhole, cc::kPinhole, cc::kSimpleRadial, cc::kRadial, cc::kOpenCV, cc::kOpenCVFisheye}) {
    const std::string name = std::string("colmap-") + cc::model_name(id);
    benchmark::RegisterBenchmark(("Func/" + name).c_str(), BM_ColmapCallback, id, false)
        ->Unit(benchmark::kMicrosecond);
    benchmark::RegisterBenchmark(("Fjac/" + name).c_str(), BM_ColmapCallback, id, true)
        ->Unit(benchmark::kMicrosecond);
  }
  // S sizes: 54 cameras x 6 (54cams), 49 x 9 (problem-49), 73 x 9, 54 x 16 (54camsvarKD), 500 x 6.
  benchmark::RegisterBenchmark("AxbChol", BM_AxbChol)
      ->Arg(324)->Arg(441)->Arg(657)->Arg(864)->Arg(3000)->Unit(benchmark::kMillisecond);
}

}  // namespace

int main(int argc, char **argv) {
  register_all();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
