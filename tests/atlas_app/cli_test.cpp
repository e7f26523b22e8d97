// The command-line contract: view --headless --screenshot, lesson check, bench render --json.
#include <gtest/gtest.h>

#include <filesystem>
#include <sstream>
#include <string>
#include <vector>
#include <nlohmann/json.hpp>

#include "softatlas/app/bench.hpp"
#include "softatlas/app/cli.hpp"
#include "softatlas/sim/error.hpp"
#include "test_util.hpp"

namespace softatlas::app {
namespace {

TEST(Cli, ViewHeadlessWritesAScreenshot) {
  const std::string out = test::scratch("cli_view") + "/v.png";
  EXPECT_EQ(cli_main({"view", test::atlas_dir(), "--headless", "--frames", "3", "--width", "160", "--height", "120",
                      "--screenshot", out}),
            0);
  EXPECT_GT(std::filesystem::file_size(out), 1000u);
  EXPECT_FALSE(std::filesystem::exists(out + ".tmp"));
}

TEST(Cli, ViewOfALessonAndBadInput) {
  const std::string out = test::scratch("cli_view_lesson") + "/v.png";
  EXPECT_EQ(cli_main({"view", test::lessons_dir() + "/organ_quiz.yaml", "--headless", "--width", "96", "--height", "64",
                      "--screenshot", out}),
            0);
  EXPECT_TRUE(std::filesystem::exists(out));
  EXPECT_THROW(cli_main({"view", "/no/such/set", "--headless"}), InputError);
  EXPECT_EQ(cli_main({"view", test::atlas_dir(), "--headless", "--frames", "0"}), 2);  // CLI11 range check
}

TEST(Cli, LessonCheck) {
  EXPECT_EQ(cli_main({"lesson", "check", test::lessons_dir() + "/liver_mobility.yaml", "--device",
                      test::lessons_dir() + "/scripts/liver_mobility.fail.yaml"}),
            0);
  // A script for another lesson: exit 1, every mismatch on its own FILE:LINE:COLUMN: line.
  testing::internal::CaptureStderr();
  EXPECT_EQ(cli_main({"lesson", "check", test::lessons_dir() + "/liver_mobility.yaml", "--device",
                      test::lessons_dir() + "/scripts/organ_quiz.pass.yaml"}),
            1);
  const std::string mismatch = testing::internal::GetCapturedStderr();
  EXPECT_NE(mismatch.find("organ_quiz.pass.yaml:6:5: task 1 is 'pick' but the lesson's task 1"), std::string::npos)
      << mismatch;
  EXPECT_NE(mismatch.find("organ_quiz.pass.yaml:7:5: task 2 is 'pick' but the lesson's task 2"), std::string::npos)
      << mismatch;
  // A bad lesson: all its errors in one run, in file order, one per line.
  const std::string bad = std::string(SOFTATLAS_SOURCE_DIR) + "/tests/atlas_app/bad_lessons/schema/bad_values.yaml";
  testing::internal::CaptureStderr();
  EXPECT_EQ(cli_main({"lesson", "check", bad}), 1);
  const std::string out = testing::internal::GetCapturedStderr();
  std::istringstream lines(out);
  std::vector<std::string> got;
  for (std::string l; std::getline(lines, l);) got.push_back(l);
  ASSERT_EQ(got.size(), 4u) << out;
  const char* at[] = {":9:20: ", ":10:34: ", ":11:11: ", ":13:20: "};
  for (size_t i = 0; i < 4; ++i) EXPECT_EQ(got[i].rfind(bad + at[i], 0), 0u) << got[i];
  EXPECT_EQ(cli_main({"lesson", "frobnicate"}), 2);
}

TEST(Cli, BenchRenderReportsFps) {
  RenderBenchOptions o;
  o.set = test::atlas_dir();
  o.width = 160;
  o.height = 120;
  o.frames = 10;
  const auto j = nlohmann::json::parse(bench_render(o));
  EXPECT_GT(j.at("fps").get<double>(), 0.0);
  EXPECT_EQ(j.at("faces").get<int>(), 16180);  // data/atlas
  EXPECT_EQ(j.at("backend").get<std::string>(), "osmesa");
}

}  // namespace
}  // namespace softatlas::app
