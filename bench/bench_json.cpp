// SPDX-License-Identifier: BSD-3-Clause
#include "bench_json.h"

#include <cmath>
#include <cstdio>
#include <string>

namespace sbabench {
namespace {

std::string json_string(const std::string &s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", c);
      out += buf;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

std::string json_number(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

}  // namespace

std::string json_record(const std::string &stamp, const Problem &prob, const ProblemFacts &facts,
                        const Run &r, const Comparison &c, int itmax, double best) {
  const RunResult &x = r.r;
  const double nobs = static_cast<double>(prob.nobs());
  std::string j = "{";
  auto field = [&j](const char *k, const std::string &v) {
    if (j.size() > 1) j += ", ";
    j += json_string(k) + ": " + v;
  };
  field("time", json_string(stamp));
  field("problem", json_string(prob.name));
  field("description", json_string(prob.description));
  field("model", json_string(prob.model_kind == ModelKind::Bal ? "bal" : "eucsba"));
  field("cameras", std::to_string(prob.m));
  field("points", std::to_string(prob.n));
  field("observations", json_number(nobs));
  field("cnp", std::to_string(prob.cnp));
  field("variables", std::to_string(prob.nvars()));
  field("camera_pairs", std::to_string(facts.pairs));
  field("jacobian_bytes", json_number(facts.jac_bytes));
  field("dense_s_bytes", json_number(facts.s_dense_bytes));
  field("sparse_s_bytes", json_number(facts.s_sparse_bytes));
  field("input_bytes", json_number(facts.input_bytes));
  field("load_seconds", json_number(facts.load_seconds));
  field("hardware_threads", std::to_string(hardware_threads()));
  field("engine", json_string(r.spec.engine == Engine::Sba ? "sba" : "ceres"));
  field("solver", json_string(r.spec.solver));
  field("strategy", r.spec.engine == Engine::Sba ? json_string(r.spec.strategy) : "null");
  field("jacobian", r.spec.engine == Engine::Sba ? json_string(r.spec.jacobian) : "null");
  field("ceres_tolerances", r.spec.engine == Engine::Ceres ? json_string(r.spec.ceres_tight ? "1e-12" : "default") : "null");
  field("threads", std::to_string(r.spec.threads));
  field("threads_auto", r.spec.auto_threads ? "true" : "false");
  field("threads_used", std::to_string(r.r.threads_used));
  field("blas_threads", r.spec.blas_threads > 0 ? std::to_string(r.spec.blas_threads) : "null");
  field("avoid_shared_cores", r.spec.engine != Engine::Sba ? "null" : r.spec.avoid_shared_cores ? "true" : "false");
  field("itmax", std::to_string(itmax));
  field("ok", x.ok ? "true" : "false");
  field("status", json_string(x.status));
  field("message", json_string(x.message));
  field("reason", json_number(x.reason));
  field("iterations", std::to_string(x.iterations));
  field("linear_solves", std::to_string(x.linear_solves));
  field("func_evals", std::to_string(x.func_evals));
  field("jac_evals", std::to_string(x.jac_evals));
  field("seconds", json_number(x.ok ? x.seconds : NAN));
  std::string all = "[";
  for (std::size_t k = 0; k < r.all_seconds.size(); ++k) all += (k ? ", " : "") + json_number(r.all_seconds[k]);
  field("repeats", std::to_string(r.all_seconds.size()));
  field("seconds_all", all + "]");
  std::string rt = "[";
  for (std::size_t k = 0; k < r.all_core_rt.size(); ++k)
    rt += (k ? ", [" : "[") + json_number(r.all_core_rt[k][0]) + ", " + json_number(r.all_core_rt[k][1]) + "]";
  field("core_round_trip_ns_all", rt + "]");
  field("setup_seconds", json_number(x.setup_seconds));
  field("cpu_seconds", json_number(x.ok ? x.cpu_seconds : NAN));
  field("seconds_per_iteration", json_number(c.per_iter));
  field("seconds_per_linear_solve",
        json_number(x.ok && x.linear_solves > 0 ? x.seconds / x.linear_solves : NAN));
  field("initial_mse", json_number(x.ok ? x.init_err / nobs : NAN));
  field("final_mse", json_number(x.ok ? x.final_err / nobs : NAN));
  field("best_final_mse", json_number(best / nobs));
  field("peak_rss_bytes", json_number(c.peak));
  field("base_rss_bytes", json_number(static_cast<double>(x.base_rss)));
  field("child_maxrss_bytes", json_number(static_cast<double>(r.child_maxrss)));
  auto bytes = [](long long b) { return json_number(b >= 0 ? static_cast<double>(b) : NAN); };  // -1: unknown
  field("file_rss_start_bytes", bytes(x.file_rss_start));
  field("file_rss_end_bytes", bytes(x.file_rss_end));
  field("program_anon_bytes", bytes(facts.program_anon));
  // What the problem and the solve hold: the peak less the code pages resident when the
  // solve started and the program's own data (see file_rss and ProblemFacts::program_anon).
  // Code first run during the solve counts as data: never an under-count.
  const bool parts = x.hwm_reset && x.peak_rss > 0 && x.file_rss_start >= 0 && facts.program_anon >= 0;
  field("data_peak_bytes",
        json_number(parts ? static_cast<double>(x.peak_rss - x.file_rss_start - facts.program_anon) : NAN));
  field("peak_rss_reset", x.hwm_reset ? "true" : "false");
  field("ceres_best_solver", c.ceres ? json_string(c.ceres->spec.solver) : "null");
  field("ceres_best_final_mse", json_number(c.ceres ? c.ceres->r.final_err / nobs : NAN));
  field("ratio_time_vs_ceres_best", json_number(c.vs_ceres));
  field("worse_than_ceres_best", c.worse ? "true" : "false");
  field("time_to_best_seconds", json_number(r.ttb));
  field("ratio_time_to_best_vs_ceres_best", json_number(c.ttb_vs_ceres));
  field("ratio_per_iteration_vs_chol", json_number(c.it_vs_chol));
  std::string tr = "[";
  for (std::size_t k = 0; k < r.trace.size(); ++k)
    tr += (k ? ", [" : "[") + json_number(r.trace[k][0]) + ", " + json_number(r.trace[k][1] / nobs) + "]";
  field("trace", tr + "]");
  return j + "}";
}

}  // namespace sbabench
