// SPDX-License-Identifier: BSD-3-Clause
#include "cli/report.h"

#include <cmath>
#include <cstring>
#include <cstdlib>
#include <string>

#include "formats/output_file.h"

namespace sbacli {

namespace {

double rms(double sum_sq, long long count) {
  return count > 0 && sum_sq >= 0 ? std::sqrt(sum_sq / static_cast<double>(count)) : NAN;
}

// JSON has no NaN or Inf: such a value is null.
std::string number(double v) {
  if (!std::isfinite(v)) return "null";
  // The shortest of %.15g and %.17g that reads back as the same double.
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.15g", v);
  if (std::strtod(buf, nullptr) != v) std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

// The length of the well-formed UTF-8 sequence that starts s[k] (RFC 3629: no overlong form,
// no surrogate, nothing beyond U+10FFFF), 0 when none does.
std::size_t utf8_length(const std::string &s, std::size_t k) {
  const unsigned char c = static_cast<unsigned char>(s[k]);
  if (c < 0x80) return 1;
  std::size_t n = 0;
  unsigned char lo = 0x80, hi = 0xbf;  // the second byte's range
  if (c >= 0xc2 && c <= 0xdf) {
    n = 2;
  } else if (c >= 0xe0 && c <= 0xef) {
    n = 3;
    if (c == 0xe0) lo = 0xa0;  // below: overlong
    if (c == 0xed) hi = 0x9f;  // above: the UTF-16 surrogates
  } else if (c >= 0xf0 && c <= 0xf4) {
    n = 4;
    if (c == 0xf0) lo = 0x90;  // below: overlong
    if (c == 0xf4) hi = 0x8f;  // above: beyond U+10FFFF
  }
  if (n == 0 || k + n > s.size()) return 0;
  for (std::size_t i = 1; i < n; ++i) {
    const unsigned char d = static_cast<unsigned char>(s[k + i]);
    if (d < (i == 1 ? lo : 0x80) || d > (i == 1 ? hi : 0xbf)) return 0;
  }
  return n;
}

// A JSON string. Paths and image names are bytes: a byte that is not UTF-8 becomes \udcXX,
// as Python's surrogateescape reads it, so that the JSON is valid and the bytes come back.
std::string quoted(const std::string &s) {
  std::string q = "\"";
  char buf[8];
  for (std::size_t k = 0; k < s.size();) {
    const unsigned char c = static_cast<unsigned char>(s[k]);
    const std::size_t n = utf8_length(s, k);
    if (c == '"' || c == '\\') {
      q += '\\';
      q += static_cast<char>(c);
    } else if (c < 0x20 || n == 0) {
      std::snprintf(buf, sizeof buf, c < 0x20 ? "\\u%04x" : "\\udc%02x", c);
      q += buf;
    } else {
      q.append(s, k, n);
      k += n;
      continue;
    }
    ++k;
  }
  return q + "\"";
}

// info[] by the names sba.h gives its entries.
const char *const kInfoNames[SBA_INFOSZ] = {"initial_error", "final_error", "gradient_inf_norm", "step_norm_sq",
                                            "mu_ratio", "iterations", "stop_reason", "function_evals",
                                            "jacobian_evals", "linear_systems"};

}  // namespace

double Report::rms_initial() const { return rms(result.sq_error_initial, observations); }
double Report::rms_final() const { return rms(result.sq_error_final, observations); }

std::string stop_reason_text(int reason) {
  std::string text = sba_stop_reason_text(reason);
  // What asks these programs to stop: the library knows only that something did.
  if (reason == SBA_STOP_USER) text += " (a signal or --max-time)";
  return text;
}

void print_report(std::FILE *out, const Report &r) {
  const int reason = static_cast<int>(r.info[6]);
  std::fprintf(out, "RMS reprojection error: initial %.6g px, final %.6g px\n", r.rms_initial(), r.rms_final());
  if (!std::isnan(r.mean_final))
    std::fprintf(out, "Mean reprojection error (COLMAP's): initial %.6g px, final %.6g px\n", r.mean_initial,
                 r.mean_final);
  if (r.priors > 0)
    std::fprintf(out, "Cost with %d prior%s: projections %.9g -> %.9g, priors %.9g -> %.9g\n", r.priors,
                 r.priors == 1 ? "" : "s", r.result.projection_cost_initial, r.result.projection_cost_final,
                 r.result.prior_cost_initial, r.result.prior_cost_final);
  std::fprintf(out, "Stop reason %d: %s\n", reason, stop_reason_text(reason).c_str());
  // The strategy is named when it is not 1.6's, the one a legacy user expects.
  const bool named = r.result.strategy && std::strcmp(r.result.strategy, "sba") != 0;
  // A solver the library chose says so.
  const bool chosen = r.result.linsolver && r.solver_requested == "auto";
  std::fprintf(out, "Solver %s%s on %d thread%s%s%s, %.3f s\n", r.result.linsolver ? r.result.linsolver : "none",
               chosen ? " (auto)" : "", r.result.nthreads, r.result.nthreads == 1 ? "" : "s",
               named ? ", strategy " : "", named ? r.result.strategy : "", r.seconds);
}

void print_removed(std::FILE *out, const sbaformats::OutputSet &outputs) {
  const std::vector<sbaformats::OutputSet::Removal> &removed = outputs.removed();
  for (std::size_t k = 0; k < removed.size();) {
    std::string paths = removed[k].path;
    std::size_t next = k + 1;
    for (; next < removed.size() && removed[next].what == removed[k].what && removed[next].why == removed[k].why;
         ++next)
      paths += ", " + removed[next].path;
    std::fprintf(out, "Removed %s (%s): %s\n", removed[k].what.c_str(), paths.c_str(), removed[k].why.c_str());
    k = next;
  }
}

bool write_json(const std::string &path, const Report &r, std::string *error,
                sbaformats::OutputSet *outputs) {
  std::string j = "{\n";
  auto field = [&j](const char *name, const std::string &value, bool last = false) {
    j += "  " + quoted(name) + ": " + value + (last ? "\n" : ",\n");
  };
  field("program", quoted(r.program));
  field("version", quoted(SBA_VERSION));
  std::string inputs = "[";
  for (std::size_t k = 0; k < r.inputs.size(); ++k) inputs += (k ? ", " : "") + quoted(r.inputs[k]);
  field("inputs", inputs + "]");
  if (!r.model.empty()) field("model", quoted(r.model));
  field("sizes", "{\"cameras\": " + std::to_string(r.cameras) + ", \"points\": " + std::to_string(r.points) +
                     ", \"observations\": " + std::to_string(r.observations) +
                     ", \"variables\": " + std::to_string(r.variables) +
                     (r.unknowns >= 0 ? ", \"unknowns\": " + std::to_string(r.unknowns) : "") + "}");
  std::string opts = "[";
  for (std::size_t k = 0; k < r.opts.size(); ++k) opts += (k ? ", " : "") + number(r.opts[k]);
  field("options", "{\"solver\": " + (r.solver_requested.empty() ? "null" : quoted(r.solver_requested)) +
                       ", \"strategy\": " + (r.strategy_requested.empty() ? "null" : quoted(r.strategy_requested)) +
                       ", \"threads\": " + std::to_string(r.threads_requested) +
                       ", \"avoid_shared_cores\": " + (r.avoid_shared_cores ? "true" : "false") +
                       ", \"itmax\": " + std::to_string(r.itmax) + ", \"opts\": " + opts + "]" +
                       ", \"loss\": " + quoted(r.loss.empty() ? "none" : r.loss) +
                       ", \"loss_scale\": " + number(r.loss_scale) + ", \"mcon\": " + std::to_string(r.mcon) +
                       ", \"ncon\": " + std::to_string(r.ncon) +
                       ", \"max_time\": " + (r.max_time > 0 ? number(r.max_time) : "null") +
                       ", \"jacobian\": " + quoted(r.single_jacobian ? "single" : "double") + "}");
  field("ret", std::to_string(r.ret));
  std::string info = "{";
  for (int k = 0; k < SBA_INFOSZ; ++k) info += std::string(k ? ", " : "") + quoted(kInfoNames[k]) + ": " + number(r.info[k]);
  field("info", info + "}");
  field("stop_reason", quoted(stop_reason_text(static_cast<int>(r.info[6]))));
  field("solver", r.result.linsolver ? quoted(r.result.linsolver) : "null");
  field("strategy", r.result.strategy ? quoted(r.result.strategy) : "null");
  field("threads", std::to_string(r.result.nthreads));
  field("seconds", number(r.seconds));
  field("squared_error", "{\"initial\": " + number(r.result.sq_error_initial) +
                             ", \"final\": " + number(r.result.sq_error_final) + "}");
  field("rms_px", "{\"initial\": " + number(r.rms_initial()) + ", \"final\": " + number(r.rms_final()) + "}");
  if (r.priors > 0) {
    // The objective is the projections' cost plus the priors': sums of squares (robust where a
    // loss is given), as sba_ext_result has them.
    field("priors", std::to_string(r.priors));
    field("cost", "{\"initial\": " + number(r.result.cost_initial) + ", \"final\": " + number(r.result.cost_final) + "}");
    field("projection_cost", "{\"initial\": " + number(r.result.projection_cost_initial) +
                                 ", \"final\": " + number(r.result.projection_cost_final) + "}");
    field("prior_cost", "{\"initial\": " + number(r.result.prior_cost_initial) +
                            ", \"final\": " + number(r.result.prior_cost_final) + "}");
  }
  if (!std::isnan(r.mean_final))
    field("mean_px", "{\"initial\": " + number(r.mean_initial) + ", \"final\": " + number(r.mean_final) + "}");
  std::string its = "[";
  for (std::size_t k = 0; k < r.iterations.size(); ++k) {
    const RunControl::Iteration &it = r.iterations[k];
    its += std::string(k ? ",\n    " : "\n    ") + "{\"solve\": " + std::to_string(it.solve) +
           ", \"iteration\": " + std::to_string(it.iteration) + ", \"error\": " + number(it.error) +
           ", \"seconds\": " + number(it.seconds) + "}";
  }
  field("iterations", its + (r.iterations.empty() ? "]" : "\n  ]"));
  std::string cams = "[";
  for (std::size_t k = 0; k < r.per_camera.size(); ++k) {
    const CameraResidual &c = r.per_camera[k];
    cams += std::string(k ? ",\n    " : "\n    ") + "{\"camera\": " + std::to_string(k) +
            (c.name.empty() ? "" : ", \"name\": " + quoted(c.name)) +
            ", \"observations\": " + std::to_string(c.observations) +
            ", \"rms_px\": " + number(rms(c.sum_sq, c.observations)) + "}";
  }
  field("cameras", cams + (r.per_camera.empty() ? "]" : "\n  ]"), true);
  j += "}\n";

  return sbaformats::write_whole_file(path, j, error, outputs);
}

}  // namespace sbacli
