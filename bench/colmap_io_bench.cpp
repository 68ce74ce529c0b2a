// SPDX-License-Identifier: BSD-3-Clause
// COLMAP model reading and writing: read_model and write_model (lib/formats/colmap_io.h) in
// this process, sbarefine --itmax 0 (the same conversion as a program), and COLMAP's own
// `colmap model_converter`, on the same model, for the four conversions bin->bin, txt->txt,
// bin->txt and txt->bin. Each is run --repeat times, interleaved so that a burst of load on
// the shared machine falls on all of them; the table gives medians. bench/colmap_io.sh makes
// the model and runs this (bench/README.md, "COLMAP model I/O").
#include <fcntl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "formats/colmap_io.h"

namespace {

namespace colmap = sbaformats::colmap;

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

double median(std::vector<double> v) {
  if (v.empty()) return -1;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// Runs argv with stdout and stderr to /dev/null: its wall time, or -1 when it fails.
double time_process(const std::vector<std::string> &argv) {
  std::vector<char *> args;
  for (const std::string &a : argv) args.push_back(const_cast<char *>(a.c_str()));
  args.push_back(nullptr);
  const Clock::time_point t0 = Clock::now();
  const pid_t pid = ::fork();
  if (pid < 0) return -1;
  if (pid == 0) {
    const int null = ::open("/dev/null", O_WRONLY);
    if (null >= 0) {
      ::dup2(null, 1);
      ::dup2(null, 2);
    }
    ::execv(args[0], args.data());
    ::_exit(127);
  }
  int status = 0;
  if (::waitpid(pid, &status, 0) != pid || !WIFEXITED(status) || WEXITSTATUS(status) != 0) return -1;
  return seconds_since(t0);
}

struct Conversion {
  const char *label;  // "bin->txt"
  bool text_in, text_out;
  std::vector<double> read, format, write, total, sbarefine, colmap;
};

void usage() {
  std::fprintf(stderr,
               "Usage: colmap_io_bench --bin DIR --txt DIR --work DIR [--repeat N] [--colmap EXE|none]\n"
               "                       [--sbarefine EXE] [--only bin->bin,txt->txt,bin->txt,txt->bin]\n"
               "Times reading and writing the COLMAP model of DIR (the same model in both encodings) with\n"
               "read_model/write_model, sbarefine --itmax 0 and colmap model_converter; outputs go under\n"
               "the work directory. Prints a Markdown table of medians.\n");
}

}  // namespace

int main(int argc, char **argv) {
  std::string bin, txt, work, colmap_exe = "/usr/bin/colmap", sbarefine, only;
  int repeat = 3;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) {
      usage();
      return 2;
    }
    const std::string v = argv[++i];
    if (a == "--bin") bin = v;
    else if (a == "--txt") txt = v;
    else if (a == "--work") work = v;
    else if (a == "--repeat") repeat = std::atoi(v.c_str());
    else if (a == "--colmap") colmap_exe = v == "none" ? "" : v;
    else if (a == "--sbarefine") sbarefine = v;
    else if (a == "--only") only = v;
    else {
      usage();
      return 2;
    }
  }
  if (bin.empty() || txt.empty() || work.empty() || repeat < 1) {
    usage();
    return 2;
  }
  if (!colmap_exe.empty() && ::access(colmap_exe.c_str(), X_OK) != 0) {
    std::fprintf(stderr, "colmap_io_bench: %s not found: COLMAP's column left out\n", colmap_exe.c_str());
    colmap_exe.clear();
  }

  Conversion conv[] = {{"bin->bin", false, false, {}, {}, {}, {}, {}, {}},
                       {"txt->txt", true, true, {}, {}, {}, {}, {}, {}},
                       {"bin->txt", false, true, {}, {}, {}, {}, {}, {}},
                       {"txt->bin", true, false, {}, {}, {}, {}, {}, {}}};
  for (int rep = 0; rep < repeat; ++rep) {
    for (Conversion &c : conv) {
      if (!only.empty() && ("," + only + ",").find(std::string(",") + c.label + ",") == std::string::npos) continue;
      const std::string in = c.text_in ? txt : bin;
      const std::string tag = std::string(c.text_in ? "txt" : "bin") + "_" + (c.text_out ? "txt" : "bin");
      const colmap::Encoding out_enc = c.text_out ? colmap::Encoding::Text : colmap::Encoding::Binary;
      {
        colmap::Model model;
        std::string error;
        const Clock::time_point t0 = Clock::now();
        if (!colmap::read_model(in, &model, nullptr, &error)) {
          std::fprintf(stderr, "colmap_io_bench: %s\n", error.c_str());
          return 1;
        }
        const double r = seconds_since(t0);
        // The formatting alone, in memory: the part of write_model that is not the disk's.
        {
          const Clock::time_point tf = Clock::now();
          const colmap::Files files = colmap::format_model(model, out_enc);
          c.format.push_back(seconds_since(tf));
        }
        const Clock::time_point t1 = Clock::now();
        if (!colmap::write_model(work + "/sba_" + tag, model, out_enc, &error)) {
          std::fprintf(stderr, "colmap_io_bench: %s\n", error.c_str());
          return 1;
        }
        const double w = seconds_since(t1);
        c.read.push_back(r);
        c.write.push_back(w);
        c.total.push_back(r + w);
      }
      if (!sbarefine.empty()) {
        const double t = time_process({sbarefine, "--itmax", "0", "--write", work + "/sbarefine_" + tag,
                                       "--write-format", c.text_out ? "text" : "binary", in});
        if (t < 0) {
          std::fprintf(stderr, "colmap_io_bench: %s --itmax 0 failed on %s\n", sbarefine.c_str(), in.c_str());
          return 1;
        }
        c.sbarefine.push_back(t);
      }
      if (!colmap_exe.empty()) {
        const std::string out = work + "/colmap_" + tag;
        (void)::mkdir(out.c_str(), 0777);
        const double t = time_process({colmap_exe, "model_converter", "--input_path", in, "--output_path", out,
                                       "--output_type", c.text_out ? "TXT" : "BIN"});
        if (t < 0) {
          std::fprintf(stderr, "colmap_io_bench: colmap model_converter failed on %s\n", in.c_str());
          return 1;
        }
        c.colmap.push_back(t);
      }
      std::fprintf(stderr, "colmap_io_bench: run %d of %d, %s done\n", rep + 1, repeat, c.label);
    }
  }

  auto cell = [](double v) {
    char buf[32];
    if (v < 0) return std::string("-");
    std::snprintf(buf, sizeof buf, "%.2f", v);
    return std::string(buf);
  };
  auto ratio = [](double a, double b) {
    char buf[32];
    if (a < 0 || b <= 0) return std::string("-");
    std::snprintf(buf, sizeof buf, "%.2f", a / b);
    return std::string(buf);
  };
  std::printf("Medians of %d runs, seconds (wall).\n\n", repeat);
  std::printf(
      "| conversion | read_model | (format_model) | write_model | read+write | sbarefine --itmax 0 "
      "| colmap model_converter | read+write / colmap | sbarefine / colmap |\n");
  std::printf("|---|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (const Conversion &c : conv) {
    if (c.total.empty()) continue;
    const double total = median(c.total), sr = median(c.sbarefine), cm = median(c.colmap);
    std::printf("| %s | %s | %s | %s | %s | %s | %s | %s | %s |\n", c.label, cell(median(c.read)).c_str(),
                cell(median(c.format)).c_str(), cell(median(c.write)).c_str(), cell(total).c_str(), cell(sr).c_str(),
                cell(cm).c_str(), ratio(total, cm).c_str(), ratio(sr, cm).c_str());
  }
  return 0;
}
