// SPDX-License-Identifier: BSD-3-Clause
// sba_bench's JSON output: one record (one line) per run, appended to --out.
#ifndef SBA_BENCH_BENCH_JSON_H
#define SBA_BENCH_BENCH_JSON_H

#include <string>

#include "bench_problem.h"
#include "bench_run.h"

namespace sbabench {

// What sba_bench measured of the problem itself, before any run.
struct ProblemFacts {
  long long pairs = 0;
  double jac_bytes = 0, s_dense_bytes = 0, s_sparse_bytes = 0, input_bytes = 0;
  // RssAnon of this program before it read the problem: the C++ runtime's, the libraries'
  // and the BLAS's own data, the same for every problem.
  long long program_anon = -1;
  double load_seconds = 0;
};

// How a run compares with the others on its problem: the figures of its table row and of its
// record.
struct Comparison {
  double per_iter = NAN;      // seconds per iteration
  double peak = 0;            // peak RSS, bytes
  const Run *ceres = nullptr;  // the fastest Ceres run with the same threads, if any
  double vs_ceres = NAN, ttb_vs_ceres = NAN;
  bool worse = false;         // ended at a worse error than that Ceres run
  double it_vs_chol = NAN;    // time per iteration against sba chol's
};

// The run's record, without the newline. stamp: the time of the report (UTC, ISO 8601); best:
// the best final sum of squares over every run.
std::string json_record(const std::string &stamp, const Problem &prob, const ProblemFacts &facts,
                        const Run &r, const Comparison &c, int itmax, double best);

}  // namespace sbabench

#endif
