// SPDX-License-Identifier: BSD-3-Clause
// Google Benchmark of the library's internal block kernels, one per step of an LM iteration,
// on real problems: the normal equations (the Jacobian products U, V, e_a, e_b), the damped
// point blocks V*^-1, the Schur complement S (dense), the back-substitution, and the dense
// Cholesky of S. Linked against the library's objects (not its exported API), so it sees
// src/. Both builds of the kernels are measured where the CPU has AVX2 (SBA_KERNELS).
//   block_kernels_benchmark --benchmark_out=bench/results/block_kernels.json --benchmark_out_format=json
#include <benchmark/benchmark.h>

#include <dlfcn.h>

#include <algorithm>
#include <cstdlib>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "bench_problem.h"
#include "layout.h"
#include "dense_factorization.h"
#include "kernels.h"
#include "lapack.h"
#include "step_solver.h"
#include "parallel.h"

namespace {

using sbabench::Problem;

const std::string kData = SBA_SHARED_DATA_DIR;

// A problem with its layout, Jacobian and residual at the start, and the normal equations.
struct Fixture {
  Problem prob;
  sba::Layout lay;
  std::vector<double> jac, e, U, V, ea, eb, Vinv, S, rhs, dp;
};

Fixture *fixture(const std::string &key) {
  static std::map<std::string, std::unique_ptr<Fixture>> cache;
  if (auto it = cache.find(key); it != cache.end()) return it->second.get();
  auto f = std::make_unique<Fixture>();
  std::string error;
  // 54cams: 6 parameters a camera; 54camsvarK: 11 (varying intrinsics); bal49: 9.
  bool ok = key == "bal49" ? sbabench::load_bal(kData + "/bal/problem-49-7776-pre.txt.bz2", &f->prob, &error)
            : key == "54cams"
                ? sbabench::load_eucsba(kData + "/sba-demo/54cams.txt", kData + "/sba-demo/54pts.txt",
                                        kData + "/sba-demo/calib.txt", &f->prob, &error)
                : sbabench::load_eucsba(kData + "/sba-demo/54camsvarK.txt", kData + "/sba-demo/54pts.txt", "",
                                        &f->prob, &error);
  std::string msg;
  Problem &p = f->prob;
  ok = ok && sba::build_layout(f->lay, sba::Mode::MotStr, p.n, p.m, 0, 0, p.cnp, 3, 2, p.vmask.data(), &msg);
  if (!ok) return (cache[key] = nullptr).get();
  const sba::Layout &lay = f->lay;
  std::vector<double> params = p.p0, hx(p.x.size());
  f->jac.resize(size_t(lay.nvis * lay.jblk()));
  // The callbacks' scratch arrays (max(n, m) ints each), as a driver hands them over.
  std::vector<int> rcidxs(size_t(std::max(p.n, p.m))), rcsubs(rcidxs.size());
  p.func()(params.data(), &f->lay.idx, rcidxs.data(), rcsubs.data(), hx.data(), p.adata());
  p.fjac()(params.data(), &f->lay.idx, rcidxs.data(), rcsubs.data(), f->jac.data(), p.adata());
  f->e.resize(hx.size());
  for (size_t q = 0; q < hx.size(); ++q) f->e[q] = p.x[q] - hx[q];
  f->U.resize(size_t(p.m) * p.cnp * p.cnp);
  f->ea.resize(size_t(p.m) * p.cnp);
  f->V.resize(size_t(p.n) * 9);
  f->eb.resize(size_t(p.n) * 3);
  f->Vinv.resize(f->V.size());
  const size_t nS = size_t(p.m) * p.cnp;
  f->S.resize(nS * nS);
  f->rhs.resize(nS);
  f->dp.resize(size_t(lay.nvars()));
  return (cache[key] = std::move(f)).get();
}

// The kernels of the build named by SBA_KERNELS ("portable"; unset: the CPU's best).
std::unique_ptr<sba::Kernels> kernels(const sba::Layout &lay, int threads, bool portable) {
  if (portable)
    setenv("SBA_KERNELS", "portable", 1);
  else
    unsetenv("SBA_KERNELS");
  auto k = sba::make_kernels(lay, threads);
  unsetenv("SBA_KERNELS");
  return k;
}

// The dense Cholesky of the same build.
sba::DenseCholesky dense_cholesky(bool portable) {
  if (portable)
    setenv("SBA_KERNELS", "portable", 1);
  else
    unsetenv("SBA_KERNELS");
  const sba::DenseCholesky chol = sba::own_dense_cholesky();
  unsetenv("SBA_KERNELS");
  return chol;
}

enum class Step { NormalEquations, InvertV, Assemble, BackSubstitute, DenseCholesky, LapackCholesky };

void BM_Step(benchmark::State &state, std::string key, Step step, bool portable) {
  Fixture *f = fixture(key);
  if (!f) {
    state.SkipWithError("shared data not found");
    return;
  }
  const int threads = static_cast<int>(state.range(0));
  sba::ThreadPool pool(threads);
  const auto k = kernels(f->lay, pool.size(), portable);
  const sba::DenseCholesky cholesky = dense_cholesky(portable);
  const sba::NormalEquations ne{f->jac.data(), f->U.data(), f->V.data(), f->ea.data(), f->eb.data()};
  k->normal_equations(pool, f->jac.data(), f->e.data(), f->U.data(), f->V.data(), f->ea.data(), f->eb.data());
  double maxdiag = 0;
  for (size_t q = 0; q < f->U.size(); q += f->lay.cnp + 1) maxdiag = std::max(maxdiag, f->U[q]);
  const double mu = 1e-3 * maxdiag;
  k->invert_damped_V(pool, f->V.data(), mu, f->Vinv.data());
  const int nS = f->lay.m * f->lay.cnp;
  sba::BlockMap map;
  map.base = f->S.data();
  map.ld = nS;
  map.cnp = f->lay.cnp;
  // As both Schur solvers run them: each point's (V_i + mu I)^-1 made where it is used
  // (InvertDampedV, the stored inverses, is what the covariance computation runs).
  auto assemble = [&] {
    std::fill(f->S.begin(), f->S.end(), 0.0);
    k->assemble(pool, ne, nullptr, mu, map, f->rhs.data());
  };
  assemble();
  std::vector<double> padded;
  for (auto _ : state) {
    switch (step) {
      case Step::NormalEquations:
        k->normal_equations(pool, f->jac.data(), f->e.data(), f->U.data(), f->V.data(), f->ea.data(),
                            f->eb.data());
        break;
      case Step::InvertV:
        k->invert_damped_V(pool, f->V.data(), mu, f->Vinv.data());
        break;
      case Step::Assemble:
        assemble();
        break;
      case Step::BackSubstitute:
        k->back_substitute(pool, ne, nullptr, mu, f->dp.data());
        break;
      case Step::DenseCholesky: {
        // As the `chol` solver lays S out: rows padded to whole cache lines (they then start
        // on one), the right-hand side and the padding as extra columns.
        state.PauseTiming();
        assemble();
        const int ld = (nS + 8) / 8 * 8;
        padded.assign(size_t(ld) * size_t(nS) + 8, 0.0);
        double *P = sba::align_to_line(padded.data());
        for (int r = 0; r < nS; ++r) {
          std::copy(f->S.begin() + size_t(r) * nS, f->S.begin() + size_t(r + 1) * nS, P + size_t(r) * ld);
          P[size_t(r) * ld + nS] = f->rhs[size_t(r)];
        }
        state.ResumeTiming();
        cholesky(pool, P, nS, ld, ld - nS);
        break;
      }
      case Step::LapackCholesky: {
        state.PauseTiming();
        assemble();
        state.ResumeTiming();
        int info = 0;
        SBA_F77(dpotrf, DPOTRF)("L", &nS, f->S.data(), &nS, &info, 1);
        break;
      }
    }
    benchmark::ClobberMemory();
  }
  state.counters["projections"] = double(f->lay.nvis);
}

extern "C" void SBA_F77(spotrf, SPOTRF)(const char *uplo, const int *n, float *a, const int *lda, int *info,
                                        size_t uplo_len);

enum class CholeskyKernel { Own, Lapack, LapackSingle };

// The dense Cholesky alone on an SPD matrix of order N (rows padded to 8 doubles, as the
// dense solver lays S out): the library's kernel on `threads` threads against LAPACK's DPOTRF
// with the BLAS's threads set to the same count (OpenBLAS; another BLAS as it is), and
// SPOTRF on the same matrix in single precision, the bound of any factorization that trades
// precision for speed. The matrix is symmetric with entries in [-1/2, 1/2] and n on the
// diagonal, positive definite by Gershgorin's theorem: made in O(n^2), since a factorization
// without pivoting costs the same whatever the entries are.
void BM_CholeskyOrder(benchmark::State &state, CholeskyKernel kernel) {
  const int n = static_cast<int>(state.range(0)), threads = static_cast<int>(state.range(1));
  const int ld = (n + 7) / 8 * 8;
  std::vector<double> A(size_t(ld) * n + 8), S;
  std::vector<float> F;
  unsigned seed = 12345;
  for (int i = 0; i < n; ++i)
    for (int j = i; j < n; ++j) {
      seed = seed * 1103515245u + 12345u;
      A[size_t(i) * ld + j] = i == j ? n : double(seed >> 8) / double(1u << 24) - 0.5;
    }
  sba::ThreadPool pool(threads);
  const sba::DenseCholesky cholesky = sba::own_dense_cholesky();
  using SetThreads = void (*)(int);
  if (auto set = reinterpret_cast<SetThreads>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"))) set(threads);
  for (auto _ : state) {
    state.PauseTiming();
    if (kernel == CholeskyKernel::LapackSingle)
      F.assign(A.begin(), A.end());
    else
      S = A;
    state.ResumeTiming();
    int info = 0;
    switch (kernel) {
      case CholeskyKernel::Own: cholesky(pool, S.data(), n, ld, 0); break;
      case CholeskyKernel::Lapack: SBA_F77(dpotrf, DPOTRF)("L", &n, S.data(), &ld, &info, 1); break;
      case CholeskyKernel::LapackSingle: SBA_F77(spotrf, SPOTRF)("L", &n, F.data(), &ld, &info, 1); break;
    }
    if (info != 0) state.SkipWithError("the factorization failed");
    benchmark::ClobberMemory();
  }
  state.counters["GFlops"] = benchmark::Counter(double(n) * n * n / 3.0, benchmark::Counter::kIsIterationInvariantRate);
}

void register_all() {
  // 6300: S of 1,000 images with 50 shared OPENCV cameras (bench/colmap_ba.py, --sharing
  // groups:20), whose factor is dense.
  const struct {
    const char *name;
    CholeskyKernel kernel;
    std::vector<int> orders;
  } factorizations[] = {
      {"CholeskyOrder/sba", CholeskyKernel::Own, {96, 324, 640, 1000, 1600, 3000, 6300}},
      {"CholeskyOrder/lapack", CholeskyKernel::Lapack, {96, 324, 640, 1000, 1600, 3000, 6300}},
      {"CholeskyOrder/lapack-single", CholeskyKernel::LapackSingle, {3000, 6300}},
  };
  for (const auto &f : factorizations) {
    auto *b = benchmark::RegisterBenchmark(f.name, BM_CholeskyOrder, f.kernel);
    for (int n : f.orders)
      for (int t : {1, 2}) b->Args({n, t});
    b->Unit(benchmark::kMicrosecond);
  }

  const struct {
    const char *name;
    Step step;
  } steps[] = {{"NormalEquations", Step::NormalEquations},
               {"InvertDampedV", Step::InvertV},
               {"AssembleS", Step::Assemble},
               {"BackSubstitute", Step::BackSubstitute},
               {"DenseCholeskyOfS", Step::DenseCholesky},
               {"LapackCholeskyOfS", Step::LapackCholesky}};
  const bool avx2 = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  for (const char *key : {"54cams", "54camsvarK", "bal49"})
    for (const auto &s : steps)
      for (bool portable : {true, false}) {
        if (!portable && !avx2) continue;
        if (s.step == Step::LapackCholesky && !portable) continue;  // LAPACK: no kernel build
        const std::string name = std::string(s.name) + "/" + key + (portable ? "/portable" : "/avx2");
        benchmark::RegisterBenchmark(name.c_str(), BM_Step, std::string(key), s.step, portable)
            ->Arg(1)
            ->Arg(2)
            ->Unit(benchmark::kMicrosecond);
      }
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
