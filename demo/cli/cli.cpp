// SPDX-License-Identifier: BSD-3-Clause
#include "cli/cli.h"

#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>

#include "sba.h"
#include "sba_ext.h"

namespace sbacli {

namespace {

std::string int_range(long long lo, long long hi) {
  if (hi == std::numeric_limits<int>::max() || hi == std::numeric_limits<long long>::max())
    return "an integer >= " + std::to_string(lo);
  return "an integer from " + std::to_string(lo) + " to " + std::to_string(hi);
}

std::string joined(const std::vector<std::string> &items) {
  std::string s;
  for (const std::string &item : items) s += (s.empty() ? "" : ", ") + item;
  return s;
}

}  // namespace

std::string to_int64(const std::string &text, long long lo, long long hi, long long *out) {
  const char *s = text.c_str();
  char *end = nullptr;
  errno = 0;
  const long long v = std::strtoll(s, &end, 10);
  if (end == s || *end != '\0') return "expected " + int_range(lo, hi);
  // A number beyond a stated range is told the range; one beyond what the type holds (an
  // unbounded option) is told that it is too large, not that it is not an integer.
  const bool unbounded = hi == std::numeric_limits<int>::max() || hi == std::numeric_limits<long long>::max();
  if (unbounded && ((errno == ERANGE && v > 0) || v > hi)) return "too large: the most is " + std::to_string(hi);
  if (errno == ERANGE || v < lo || v > hi) return "expected " + int_range(lo, hi);
  *out = v;
  return {};
}

std::string to_int(const std::string &text, long long lo, long long hi, int *out) {
  long long v = 0;
  hi = std::min<long long>(hi, std::numeric_limits<int>::max());
  if (std::string why = to_int64(text, lo, hi, &v); !why.empty()) return why;
  *out = static_cast<int>(v);
  return {};
}

std::string to_real(const std::string &text, double lo, bool strict, double *out) {
  const char *s = text.c_str();
  char *end = nullptr;
  const double v = std::strtod(s, &end);
  if (end == s || *end != '\0' || !std::isfinite(v) || v < lo || (strict && v == lo)) {
    if (lo == 0.0) return strict ? "expected a positive number" : "expected a non-negative number";
    char bound[64];
    std::snprintf(bound, sizeof bound, "%g", lo);
    return std::string("expected a number ") + (strict ? "> " : ">= ") + bound;
  }
  *out = v;
  return {};
}

std::string to_bool(const std::string &text, bool *out) {
  std::string lower = text;
  for (char &c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  for (const char *yes : {"1", "true", "yes", "on"})
    if (lower == yes) {
      *out = true;
      return {};
    }
  for (const char *no : {"0", "false", "no", "off"})
    if (lower == no) {
      *out = false;
      return {};
    }
  return "expected 1, true, yes or on, or 0, false, no or off (in any case)";
}

std::string to_choice(const std::string &text, const std::vector<std::string> &choices, std::string *out) {
  for (const std::string &c : choices)
    if (text == c) {
      *out = text;
      return {};
    }
  return "expected one of: " + joined(choices);
}

std::string to_linsolver(const std::string &text, std::string *out) {
  if (!sba_linsolver_valid(text.c_str())) return std::string("expected one of: ") + sba_linsolver_names();
  *out = text;
  return {};
}

std::string to_strategy(const std::string &text, std::string *out) {
  if (!sba_strategy_valid(text.c_str())) return std::string("expected one of: ") + sba_strategy_names();
  *out = text;
  return {};
}

std::string to_loss(const std::string &text, std::string *out) {
  if (!sba_loss_valid(text.c_str())) {
    std::string names = sba_loss_names();  // space-separated; listed here with commas
    for (std::size_t at = names.find(' '); at != std::string::npos; at = names.find(' ', at + 2))
      names.replace(at, 1, ", ");
    return "expected one of: " + names;
  }
  *out = text == "none" ? std::string() : text;
  return {};
}

std::string to_threads(const std::string &text, int *out) { return to_int(text, 0, kMaxThreads, out); }

std::string to_seconds(const std::string &text, double *out) { return to_real(text, 0.0, true, out); }

std::string to_file(const std::string &text, std::string *out) {
  if (text.empty()) return "expected a file name";
  *out = text;
  return {};
}

Option strategy_option(std::string *strategy, const char *default_text) {
  return {"strategy", "NAME",
          std::string("how LM damps, accepts steps and stops: sba (sba 1.6's algorithm),\n"
                      "sba-clean-retry (the same, but a rejected step is retried on the undamped normal\n"
                      "equations, as the sba paper writes it) or trust-region (Marquardt's scaled damping and\n"
                      "a relative cost tolerance: usually far fewer iterations); default: ") +
              (default_text ? default_text : "the environment\nvariable SBA_STRATEGY if set, else sba"),
          [strategy](const std::string &v) { return to_strategy(v, strategy); }};
}

void add_lm_options(std::vector<Option> *options, std::array<double, 5> *opts) {
  // tau must be positive (it scales the initial damping); the thresholds may be 0 (off).
  auto set = [opts](int k) {
    return [opts, k](const std::string &v) { return to_real(v, 0.0, k == 0, &(*opts)[k]); };
  };
  options->push_back(
      {"opts", "TAU,EPS1,EPS2,EPS3,EPS4",
       "LM options: initial damping scale and the stopping thresholds on ||J^T e||_inf, the\n"
       "relative step, ||e||^2 and the relative error reduction (default 1e-3,1e-12,1e-12,1e-12,0)",
       [opts](const std::string &v) -> std::string {
         std::array<double, 5> parsed{};
         std::size_t start = 0;
         for (int k = 0; k < 5; ++k) {
           const std::size_t comma = v.find(',', start);
           if ((comma == std::string::npos) != (k == 4)) return "expected 5 comma-separated numbers";
           const std::string item = v.substr(start, comma == std::string::npos ? comma : comma - start);
           if (std::string why = to_real(item, 0.0, k == 0, &parsed[k]); !why.empty())
             return "number " + std::to_string(k + 1) + ": " + why;
           start = comma + 1;
         }
         *opts = parsed;
         return {};
       }});
  options->push_back({"tau", "X", "initial damping scale, opts[0] (default 1e-3)", set(0)});
  options->push_back({"eps1", "X", "stop when ||J^T e||_inf <= X, opts[1] (default 1e-12)", set(1)});
  options->push_back({"eps2", "X", "stop when ||dp||^2 <= X^2 ||p||^2, opts[2] (default 1e-12)", set(2)});
  options->push_back({"eps3", "X", "stop when ||e||^2 <= X^2, opts[3] (default 1e-12)", set(3)});
  options->push_back(
      {"eps4", "X", "stop when the relative RMS error reduction is below X, opts[4] (default 0)", set(4)});
}

bool parse(int argc, const char *const *argv, const std::vector<Option> &options, Parsed *out,
           std::string *error) {
  Parsed p;
  bool only_positional = false;  // after "--"
  for (int k = 1; k < argc; ++k) {
    const std::string arg = argv[k];
    // A lone "-" is an argument (standard input), not an option.
    if (only_positional || arg.size() < 2 || arg[0] != '-') {
      p.positional.push_back(arg);
      continue;
    }
    if (arg == "--") {
      only_positional = true;
      continue;
    }
    if (arg == "-h") {
      p.help = true;
      continue;
    }
    if (arg[1] != '-') {
      *error = "unknown option '" + arg + "' (options are long: see --help)";
      return false;
    }
    const std::size_t eq = arg.find('=');
    const std::string name = arg.substr(2, eq == std::string::npos ? eq : eq - 2);
    const bool has_value = eq != std::string::npos;
    if (name == "help" || name == "version") {
      if (has_value) {
        *error = "option '--" + name + "' takes no value";
        return false;
      }
      (name == "help" ? p.help : p.version) = true;
      continue;
    }
    const Option *spec = nullptr;
    for (const Option &o : options)
      if (o.name == name) spec = &o;
    if (!spec) {
      *error = "unknown option '--" + name + "' (see --help)";
      return false;
    }
    std::string value;
    if (!spec->arg.empty()) {
      if (has_value) {
        value = arg.substr(eq + 1);
      } else if (k + 1 < argc) {
        value = argv[++k];
      } else {
        *error = "option '--" + name + "' needs a value (" + spec->arg + ")";
        return false;
      }
    } else if (has_value) {
      *error = "option '--" + name + "' takes no value";
      return false;
    }
    if (std::string why = spec->apply(value); !why.empty()) {
      *error = "bad value '" + value + "' for --" + name + ": " + why;
      return false;
    }
  }
  *out = std::move(p);
  return true;
}

void print_options(std::FILE *out, const std::vector<Option> &options) {
  auto row = [out](const std::string &name, const std::string &arg, const std::string &help) {
    std::fprintf(out, "  --%s%s\n", name.c_str(), arg.empty() ? "" : ("=" + arg).c_str());
    // Help texts carry their own line breaks; indent every line.
    std::size_t start = 0;
    while (start < help.size()) {
      std::size_t nl = help.find('\n', start);
      if (nl == std::string::npos) nl = help.size();
      std::fprintf(out, "        %s\n", help.substr(start, nl - start).c_str());
      start = nl + 1;
    }
  };
  for (const Option &o : options) row(o.name, o.arg, o.help);
  row("help", "", "show this help and exit");
  row("version", "", "show the program's and the library's version and exit");
}

std::string version_line(const std::string &program) { return program + " (sba " + SBA_VERSION + ")"; }

}  // namespace sbacli
