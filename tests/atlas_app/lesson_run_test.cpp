// Every shipped lesson, played headless with its passing and failing device script: the pass
// script passes, the fail script fails with the reason, one PNG per step, report.json.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "softatlas/app/lesson_run.hpp"
#include "softatlas/app/viewer.hpp"
#include "test_util.hpp"

namespace softatlas::app {
namespace {

struct Case {
  const char* lesson;
  const char* script;
  bool passes;
  const char* reason;  // expected in the failing step's reason
};

class LessonRun : public ::testing::TestWithParam<Case> {};

TEST_P(LessonRun, PlaysHeadlessAndReports) {
  const Case c = GetParam();
  const std::string out = test::scratch(std::string(c.lesson) + "_" + c.script);
  const Lesson lesson = load_lesson(test::lessons_dir() + "/" + c.lesson + ".yaml");
  const DeviceScript script =
      load_device_script(test::lessons_dir() + "/scripts/" + c.lesson + "." + c.script + ".yaml");
  RunOptions opt;
  opt.width = 320;
  opt.height = 180;
  const LessonReport r = run_lesson(lesson, script, out, opt);
  EXPECT_EQ(r.passed, c.passes);
  std::ifstream in(out + "/report.json");
  const nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_EQ(j.at("passed").get<bool>(), c.passes);
  ASSERT_EQ(j.at("steps").size(), lesson.steps.size());
  std::string reasons;
  for (const auto& s : j.at("steps")) {
    EXPECT_TRUE(std::filesystem::exists(out + "/" + s.at("png").get<std::string>()));
    if (s.at("task").get<bool>()) reasons += s.at("reason").get<std::string>() + "; ";
    if (s.at("kind") == "pull") {
      EXPECT_GE(s.at("displacement_mm").get<double>(), 0.0);
      EXPECT_GE(s.at("peak_force_N").get<double>(), 0.0);
    }
  }
  EXPECT_NE(reasons.find(c.reason), std::string::npos) << reasons;
  // The end screen and the score.
  EXPECT_TRUE(std::filesystem::exists(out + "/end.png"));
  EXPECT_EQ(j.at("score").at("tasks").get<int>(), lesson.task_count());
  EXPECT_EQ(j.at("score").at("passed").get<int>() == lesson.task_count(), c.passes);
}

// A lesson and device script with 100,000-character lines (the title, what the lesson says, a
// question and its answer) play to the end: overlays cut their text (overlay_text), an ImGui draw
// list would otherwise pass 65,536 vertices and abort (issue 17).
TEST(LessonRunLongText, LinesOfAnyLengthPlay) {
  const std::string dir = test::scratch("long_text");
  std::filesystem::create_directories(dir);
  auto slurp = [](const std::string& path) {
    std::ifstream f(path);
    return std::string(std::istreambuf_iterator<char>(f), {});
  };
  auto replace = [](std::string s, const std::string& from, const std::string& to) {
    const size_t at = s.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return at == std::string::npos ? s : s.replace(at, from.size(), to);
  };
  std::string words;
  while (words.size() < 100000) words += "word ";
  const std::string long_choice(100000, 'K');
  std::string lesson = slurp(test::lessons_dir() + "/kidney_sections.yaml");
  lesson = replace(lesson, "organ_set: ../atlas", "organ_set: " + test::atlas_dir());
  lesson = replace(lesson, "lesson: \"Kidneys: retroperitoneal, seen in a coronal cut\"", "lesson: \"" + words + "\"");
  lesson = replace(lesson, "ask: \"Which of these organs is retroperitoneal?\"", "ask: \"" + words + "\"");
  lesson = replace(lesson, "choices: [Liver, Spleen, Kidney]", "choices: [Liver, Spleen, " + long_choice + "]");
  lesson = replace(lesson, "answer: Kidney", "answer: " + long_choice);
  std::string script = slurp(test::lessons_dir() + "/scripts/kidney_sections.pass.yaml");
  script = replace(script, "choice: Kidney}", "choice: " + long_choice + "}");
  std::ofstream(dir + "/long.yaml") << lesson;
  std::ofstream(dir + "/long.pass.yaml") << script;
  RunOptions opt;
  opt.width = 320;
  opt.height = 180;
  const LessonReport r =
      run_lesson(load_lesson(dir + "/long.yaml"), load_device_script(dir + "/long.pass.yaml"), dir + "/out", opt);
  EXPECT_TRUE(r.passed);
  EXPECT_TRUE(std::filesystem::exists(dir + "/out/end.png"));
}

TEST(LessonRunLongText, OverlayTextIsCutAtACharacterBoundary) {
  EXPECT_EQ(overlay_text("short"), "short");
  std::string s(kOverlayChars - 1, 'a');
  s += "\xc3\xa9\xc3\xa9";  // two 2-byte characters across the limit
  const std::string cut = overlay_text(s);
  EXPECT_EQ(cut, std::string(kOverlayChars - 1, 'a') + "...");
  EXPECT_LE(overlay_text(std::string(1000000, 'x')).size(), kOverlayChars + 3);
}

INSTANTIATE_TEST_SUITE_P(
    Shipped, LessonRun,
    ::testing::Values(
        Case{"liver_mobility", "pass", true, "reached"}, Case{"liver_mobility", "fail", false, "pulled too hard"},
        Case{"organ_quiz", "pass", true, "picked pancreas"},
        Case{"organ_quiz", "fail", false, "picked liver, expected pancreas"},
        Case{"kidney_anchor", "pass", true, "reached"}, Case{"kidney_anchor", "fail", false, "pulled too little"},
        Case{"sectional_anatomy", "pass", true, "picked kidney_right"},
        Case{"sectional_anatomy", "fail", false, "answered Liver, the answer is Spleen"},
        Case{"kidney_sections", "pass", true, "answered Right kidney"},
        Case{"kidney_sections", "fail", false, "picked kidney_right, expected kidney_left"},
        Case{"spleen_pull", "pass", true, "reached"}, Case{"spleen_pull", "fail", false, "pulled too hard"}),
    [](const ::testing::TestParamInfo<Case>& i) { return std::string(i.param.lesson) + "_" + i.param.script; });

const char* kCovered[] = {"liver_mobility",    "organ_quiz",      "kidney_anchor",
                          "sectional_anatomy", "kidney_sections", "spleen_pull"};

TEST(LessonRunCoverage, EveryShippedLessonHasPassAndFailCases) {
  int n = 0;
  for (const auto& e : std::filesystem::directory_iterator(test::lessons_dir())) {
    if (e.path().extension() != ".yaml") continue;
    const std::string name = e.path().stem().string();
    ++n;
    bool covered = false;
    for (const char* c : kCovered) covered = covered || name == c;
    EXPECT_TRUE(covered) << name << " has no LessonRun case";
    for (const char* k : {"pass", "fail"})
      EXPECT_TRUE(std::filesystem::exists(test::lessons_dir() + "/scripts/" + name + "." + k + ".yaml"))
          << name << "." << k;
  }
  EXPECT_GE(n, 6);
}

}  // namespace
}  // namespace softatlas::app
