/* SPDX-License-Identifier: BSD-3-Clause */
// The command-line conventions of sba's programs (eucsbademo, balsba, sbagen, sba_bench), in
// one place so that they agree: long options only, a value as --opt=VALUE or --opt VALUE, "--"
// ends the options, --help and --version in every program, and one message for one mistake.
//
// A program describes its options as a table of Option rows, each with a function that checks
// and stores the value; parse() walks argv against the table. Errors are one line without the
// program's name and without a newline: the program prints "NAME: message" on stderr and
// exits with kExitUsage.
#ifndef SBA_DEMO_CLI_H
#define SBA_DEMO_CLI_H

#include <array>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

namespace sbacli {

constexpr int kExitFailure = 1;  // unreadable input, failed write, solver failure
constexpr int kExitUsage = 2;    // bad command line
constexpr int kExitInterrupted = 130;  // stopped by SIGINT or SIGTERM (128 + SIGINT, as shells report)

// Largest thread count a program accepts (the library caps a request at a few threads per
// hardware thread anyway; this bound only refuses absurd values early).
constexpr int kMaxThreads = 256;

// Checks a value and stores it; returns why it is bad ("expected ..."), empty when it is good.
using Apply = std::function<std::string(const std::string &value)>;

struct Option {
  std::string name;  // without the leading "--"
  std::string arg;   // the value's name in --help; empty for a flag
  std::string help;  // may hold line breaks
  Apply apply;       // for a flag it is called with an empty value
};

// The value checks the programs share.
// An integer in [lo, hi]. An option without an upper bound of its own passes INT_MAX (or
// LLONG_MAX); a larger number is then "too large", not "not an integer".
std::string to_int(const std::string &text, long long lo, long long hi, int *out);
std::string to_int64(const std::string &text, long long lo, long long hi, long long *out);
// A boolean as boost::program_options reads one (COLMAP's options): 1, true, yes or on, 0,
// false, no or off, in any case.
std::string to_bool(const std::string &text, bool *out);
// A finite number >= lo, or > lo when strict.
std::string to_real(const std::string &text, double lo, bool strict, double *out);
// One of choices, stored as given.
std::string to_choice(const std::string &text, const std::vector<std::string> &choices, std::string *out);
// A linear solver name the library knows (sba_linsolver_valid()).
std::string to_linsolver(const std::string &text, std::string *out);
// An LM strategy name the library knows (sba_strategy_valid()).
std::string to_strategy(const std::string &text, std::string *out);
// A robust loss: none (stored as empty) or a loss name of sba_ext.h.
std::string to_loss(const std::string &text, std::string *out);
// A thread count, 0 (the library's choice) to kMaxThreads.
std::string to_threads(const std::string &text, int *out);
// Seconds, a positive finite number.
std::string to_seconds(const std::string &text, double *out);
// A file name: anything but empty.
std::string to_file(const std::string &text, std::string *out);

// The LM options of sba's opts[]: --opts=TAU,EPS1,EPS2,EPS3,EPS4 and --tau, --eps1 .. --eps4.
void add_lm_options(std::vector<Option> *options, std::array<double, 5> *opts);

// --strategy NAME into *strategy (checked by to_strategy). default_text: what --help says the
// program runs when it is not given, after "default: " (null: the library's default).
Option strategy_option(std::string *strategy, const char *default_text = nullptr);

struct Parsed {
  std::vector<std::string> positional;  // arguments that are not options, in order
  bool help = false;
  bool version = false;
};

// Parses argv[1..argc) against options (--help, -h and --version are understood in addition).
// Returns false with a one-line message on the first mistake.
bool parse(int argc, const char *const *argv, const std::vector<Option> &options, Parsed *out,
           std::string *error);

// The options' part of --help, --help and --version included.
void print_options(std::FILE *out, const std::vector<Option> &options);

// What --version prints: "PROGRAM (sba VERSION)".
std::string version_line(const std::string &program);

}  // namespace sbacli

#endif  // SBA_DEMO_CLI_H
