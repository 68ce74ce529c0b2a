// SPDX-License-Identifier: BSD-3-Clause
// The stop reasons have one vocabulary: sba_ext.h's SBA_STOP_* values and the words of
// sba_stop_reason_text, which the programs' report prints (demo/cli/report.h) and pysba reads.
#include <gtest/gtest.h>

#include <climits>
#include <cstdio>
#include <fstream>
#include <set>
#include <sstream>
#include <string>

#include "cli/report.h"
#include "sba_ext.h"
#include "scratch.h"

namespace {

// info[6] as sba 1.6 documents it (1..7), and this library's three beside them.
TEST(StopReason, MacrosAreInfo6Values) {
  EXPECT_EQ(SBA_STOP_GRADIENT, 1);
  EXPECT_EQ(SBA_STOP_STEP, 2);
  EXPECT_EQ(SBA_STOP_ITMAX, 3);
  EXPECT_EQ(SBA_STOP_REDUCTION, 4);
  EXPECT_EQ(SBA_STOP_ERROR, 5);
  EXPECT_EQ(SBA_STOP_DAMPING, 6);
  EXPECT_EQ(SBA_STOP_NONFINITE, 7);
  EXPECT_EQ(SBA_STOP_NONE, 0);
  EXPECT_EQ(SBA_STOP_SINGULAR, 8);
  EXPECT_EQ(SBA_STOP_USER, 9);
}

TEST(StopReason, EveryReasonHasWordsOfItsOwn) {
  std::set<std::string> seen;
  for (int r = SBA_STOP_NONE; r <= SBA_STOP_USER; ++r) {
    const char *text = sba_stop_reason_text(r);
    ASSERT_NE(text, nullptr) << r;
    EXPECT_STRNE(text, "") << r;
    EXPECT_STRNE(text, "unknown") << r;
    EXPECT_TRUE(seen.insert(text).second) << r << ": " << text;
  }
}

TEST(StopReason, AnyOtherValueIsUnknown) {
  for (int r : {INT_MIN, -1, SBA_STOP_USER + 1, INT_MAX}) EXPECT_STREQ(sba_stop_reason_text(r), "unknown") << r;
}

std::string read_all(std::FILE *f) {
  std::rewind(f);
  std::string s;
  for (int c; (c = std::fgetc(f)) != EOF;) s += char(c);
  return s;
}

// The programs' "Stop reason" line and --json's stop_reason carry the library's words; a stop
// on request also says what asks these programs to stop.
TEST(StopReason, TheReportPrintsTheLibrarysWords) {
  const std::string json_path = sbatest::scratch_dir() + "stop_reason.json";
  for (int r = SBA_STOP_NONE - 1; r <= SBA_STOP_USER + 1; ++r) {
    sbacli::Report report;
    report.info[6] = r;
    const std::string words =
        std::string(sba_stop_reason_text(r)) + (r == SBA_STOP_USER ? " (a signal or --max-time)" : "");
    std::FILE *f = std::tmpfile();
    ASSERT_NE(f, nullptr);
    sbacli::print_report(f, report);
    const std::string printed = read_all(f);
    std::fclose(f);
    EXPECT_NE(printed.find("\nStop reason " + std::to_string(r) + ": " + words + "\n"), std::string::npos) << printed;

    std::string why;
    ASSERT_TRUE(sbacli::write_json(json_path, report, &why)) << why;
    std::ifstream in(json_path);
    std::stringstream json;
    json << in.rdbuf();
    EXPECT_NE(json.str().find("\"stop_reason\": \"" + words + "\""), std::string::npos) << json.str();
  }
  std::remove(json_path.c_str());
}

}  // namespace
