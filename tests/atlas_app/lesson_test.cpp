// Lesson and device-script validation: one error per kind of bad input, each as
// FILE:LINE:COLUMN: message, pointing at the offending node.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include "softatlas/app/lesson.hpp"
#include "softatlas/sim/error.hpp"
#include "test_util.hpp"
#include "../../atlas_app/src/yaml_check.hpp"

namespace softatlas::app {
namespace {

// A valid lesson whose organ set is the demo atlas (absolute path).
std::string valid_lesson() {
  return "lesson: Test lesson\n"  // line 1
         "organ_set: " +
         test::atlas_dir() +
         "\n"                                                                                    // 2
         "scene:\n"                                                                              // 3
         "  organs: [liver]\n"                                                                   // 4
         "  context: [kidney_left]\n"                                                            // 5
         "  physics: {dt_s: 0.001}\n"                                                            // 6
         "steps:\n"                                                                              // 7
         "  - say: hello\n"                                                                      // 8
         "  - pull: {organ: liver, region: inferior, min_displacement_mm: 5, max_force_N: 1}\n"  // 9
         "  - pick: {organ: kidney_left}\n";                                                     // 10
}

std::string write(const std::string& name, const std::string& text) {
  const std::string path = test::scratch("lesson_" + name) + "/" + name + ".yaml";
  std::ofstream(path) << text;
  return path;
}

// Loads and expects an InputError at LINE:COLUMN whose message contains `what`.
void expect_error(const std::string& name, const std::string& text, int line, int column, const std::string& what) {
  const std::string path = write(name, text);
  try {
    load_lesson(path);
    FAIL() << name << ": no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.where(), path + ":" + std::to_string(line) + ":" + std::to_string(column)) << e.what();
    EXPECT_NE(e.problem().find(what), std::string::npos) << e.what();
    // One line, FILE:LINE:COLUMN: message
    EXPECT_TRUE(std::regex_match(std::string(e.what()), std::regex(".+\\.yaml:[0-9]+:[0-9]+: [^\n]+"))) << e.what();
  }
}

std::string replace(std::string s, const std::string& from, const std::string& to) {
  const size_t at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return s.replace(at, from.size(), to);
}

TEST(Lesson, ValidLessonLoads) {
  const Lesson l = load_lesson(write("valid", valid_lesson()));
  EXPECT_EQ(l.title, "Test lesson");
  ASSERT_EQ(l.steps.size(), 3u);
  EXPECT_EQ(l.steps[1].kind, StepKind::pull);
  EXPECT_EQ(l.steps[1].pull.region, "inferior");
  EXPECT_DOUBLE_EQ(l.steps[1].pull.max_force_N, 1.0);
  EXPECT_EQ(l.task_count(), 2);
  EXPECT_EQ(l.set.organs.size(), 10u);  // data/atlas
}

// A pull may name a region of its organ (data/atlas's liver has the HRA sub-meshes' regions):
// it becomes that region's landmark; a name the organ does not have lists the ones it has.
TEST(Lesson, NamedRegionsBecomeLandmarks) {
  const Lesson l =
      load_lesson(write("named_region", replace(valid_lesson(), "region: inferior", "region: gastric_impression")));
  ASSERT_EQ(l.steps[1].kind, StepKind::pull);
  EXPECT_EQ(l.steps[1].pull.region, "gastric_impression");
  ASSERT_TRUE(l.steps[1].pull.has_landmark);
  const auto* p = l.set.find("liver")->find_region("gastric_impression");
  ASSERT_NE(p, nullptr);
  EXPECT_EQ(l.steps[1].pull.landmark_mm, Eigen::Vector3d((*p)[0], (*p)[1], (*p)[2]));
  expect_error("bad_named_region", replace(valid_lesson(), "region: inferior", "region: hilum"), 9, 34,
               "unknown region 'hilum' (expected anterior, posterior, superior, inferior, left or right, or a named "
               "region of liver: bare_area, liver_capsule,");
}

TEST(Lesson, UnknownKey) {
  expect_error("unknown_top", valid_lesson() + "colour: red\n", 11, 1, "unknown key 'colour'");
  expect_error("unknown_pull", replace(valid_lesson(), "max_force_N: 1}", "max_force_N: 1, speed: 3}"), 9, 84,
               "unknown key 'speed' in pull");
}

TEST(Lesson, WrongType) {
  expect_error("wrong_type", replace(valid_lesson(), "max_force_N: 1}", "max_force_N: strong}"), 9, 81,
               "'max_force_N' must be a number");
  expect_error(
      "wrong_steps",
      replace(replace(replace(valid_lesson(), "  - say: hello\n", ""),
                      "  - pull: {organ: liver, region: inferior, min_displacement_mm: 5, max_force_N: 1}\n", ""),
              "  - pick: {organ: kidney_left}\n", "  hello: 3\n"),
      8, 3, "'steps' must be a non-empty list");
}

TEST(Lesson, AbsentOrganFailsWithAClearMessage) {
  expect_error("absent_organ", replace(valid_lesson(), "organs: [liver]", "organs: [liver, stomach]"), 4, 19,
               "organ 'stomach' is not in the organ set");
  expect_error("absent_in_step", replace(valid_lesson(), "pick: {organ: kidney_left}", "pick: {organ: stomach}"), 10, 5,
               "organ 'stomach' is not in the organ set");
  expect_error("not_in_scene", replace(valid_lesson(), "pick: {organ: kidney_left}", "pick: {organ: pancreas}"), 10, 5,
               "not in this lesson's scene");
}

TEST(Lesson, OutOfRangeValues) {
  expect_error("negative_force", replace(valid_lesson(), "max_force_N: 1}", "max_force_N: -2}"), 9, 81,
               "'max_force_N' must be in [0.001, 50], got -2");
  expect_error("dt", replace(valid_lesson(), "dt_s: 0.001", "dt_s: 0.5"), 6, 19, "'dt_s' must be in");
  expect_error("region", replace(valid_lesson(), "region: inferior", "region: middle"), 9, 34,
               "unknown region 'middle'");
}

TEST(Lesson, MissingRequiredKeyAndBadStructure) {
  expect_error("missing_min", replace(valid_lesson(), "min_displacement_mm: 5, ", ""), 9, 11,
               "pull needs 'min_displacement_mm'");
  expect_error("two_actions", replace(valid_lesson(), "  - say: hello\n", "  - say: hello\n    wait: {seconds: 1}\n"),
               8, 5, "exactly one action");
  expect_error("missing_set", replace(valid_lesson(), "organ_set: " + test::atlas_dir(), "organ_set: /no/such/set"), 2,
               12, "does not exist");
}

TEST(Lesson, YamlSyntaxErrorHasLineAndColumn) {
  const std::string path = write("syntax", valid_lesson() + "  - pick: {organ: [liver\n");
  try {
    load_lesson(path);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(e.problem().find("YAML syntax"), std::string::npos) << e.what();
    EXPECT_EQ(e.where().rfind(path + ":", 0), 0u) << e.what();
  }
}

// Every lesson in tests/atlas_app/bad_lessons (schema/ and yaml/) fails with exactly the errors its
// `# expect: LINE:COLUMN text` comments list, in file order, from one load.
TEST(Lesson, BadLessonsReportEveryErrorInFileOrder) {
  const std::string root = std::string(SOFTATLAS_SOURCE_DIR) + "/tests/atlas_app/bad_lessons";
  int files = 0;
  for (const std::string sub : {"schema", "yaml"})
    for (const auto& entry : std::filesystem::directory_iterator(root + "/" + sub)) {
      const std::string path = entry.path().string();
      std::ifstream in(path);
      std::vector<std::string> expected;
      for (std::string line; std::getline(in, line);)
        if (line.rfind("# expect: ", 0) == 0) expected.push_back(line.substr(10));
      ASSERT_FALSE(expected.empty()) << path << " has no '# expect:' lines";
      ++files;
      try {
        load_lesson(path);
        ADD_FAILURE() << path << ": no error";
      } catch (const yamlcheck::CheckErrors& e) {
        const std::vector<std::string> got = e.lines();
        ASSERT_EQ(got.size(), expected.size()) << path << ":\n" << e.what();
        for (size_t i = 0; i < got.size(); ++i) {
          const std::string want = expected[i];
          const size_t sp = want.find(' ');
          const std::string at = path + ":" + want.substr(0, sp) + ": ";
          EXPECT_EQ(got[i].rfind(at, 0), 0u) << "expected at " << at << "\n got " << got[i];
          EXPECT_NE(got[i].find(want.substr(sp + 1)), std::string::npos)
              << "expected '" << want << "'\n got " << got[i];
        }
      } catch (const InputError& e) {
        ADD_FAILURE() << path << ": not a collected error: " << e.what();
      }
    }
  EXPECT_GE(files, 6);
}

TEST(Lesson, StrictYaml) {
  // lesson: 42 is a number, not a title; a quoted number is text, not a number.
  expect_error("number_title", replace(valid_lesson(), "lesson: Test lesson", "lesson: 42"), 1, 9,
               "'lesson' must be text, got the number 42");
  expect_error("quoted_number", replace(valid_lesson(), "dt_s: 0.001", "dt_s: \"0.001\""), 6, 19,
               "'dt_s' must be a number, got the text");
  expect_error("duplicate",
               replace(valid_lesson(), "pick: {organ: kidney_left}", "pick: {organ: kidney_left, organ: liver}"), 10,
               32, "duplicate key 'organ' in pick (first given on line 10)");
  // An unterminated quote is reported where it opens, not where yaml-cpp stops.
  expect_error("unterminated", replace(valid_lesson(), "say: hello", "say: \"hello"), 8, 10, "unterminated quote");
  // Quotes inside words, escaped quotes and block scalars are fine.
  const Lesson ok = load_lesson(write("quotes_ok", replace(valid_lesson(), "  - say: hello\n",
                                                           "  - say: the patient's \"right\"\n"
                                                           "  - say: 'it''s \"fine\"'\n"
                                                           "  - say: \"a \\\" b\"\n"
                                                           "  - say: >\n      a long \"text\n      over lines\n")));
  ASSERT_EQ(ok.steps.size(), 6u);
  EXPECT_EQ(ok.steps[0].text, "the patient's \"right\"");
  EXPECT_EQ(ok.steps[1].text, "it's \"fine\"");
  EXPECT_EQ(ok.steps[3].text, "a long \"text over lines\n");
}

TEST(Lesson, QuestionAndSliceSteps) {
  const Lesson l = load_lesson(
      write("question", valid_lesson() + "  - question: {ask: \"Which?\", choices: [Liver, Stomach], answer: Stomach}\n"
                                         "  - slice: {plane: coronal, at_mm: 120}\n"));
  ASSERT_EQ(l.steps.size(), 5u);
  EXPECT_EQ(l.steps[3].kind, StepKind::question);
  EXPECT_EQ(l.steps[3].question.answer, 1);
  EXPECT_EQ(l.task_count(), 3);
  EXPECT_EQ(l.steps[4].kind, StepKind::slice);
  EXPECT_EQ(slice_plane(l.steps[4].slice).axis, 1);
  EXPECT_FLOAT_EQ(slice_plane(l.steps[4].slice).at_mm, 120.0f);
  EXPECT_NE(question_text(l.steps[3].question, "Liver").find("1) Liver   <- your answer"), std::string::npos);
}

TEST(Lesson, ShippedLessonsAndScriptsValidate) {
  for (const std::string name :
       {"liver_mobility", "organ_quiz", "kidney_anchor", "sectional_anatomy", "kidney_sections", "spleen_pull"}) {
    const Lesson l = load_lesson(test::lessons_dir() + "/" + name + ".yaml");
    for (const std::string kind : {"pass", "fail"}) {
      const DeviceScript s = load_device_script(test::lessons_dir() + "/scripts/" + name + "." + kind + ".yaml");
      EXPECT_NO_THROW(check_script_matches(s, l)) << name << "." << kind;
    }
  }
}

TEST(DeviceScript, ErrorsPointAtTheNode) {
  const std::string dir = test::scratch("script");
  auto load = [&](const std::string& text) {
    const std::string path = dir + "/s.yaml";
    std::ofstream(path) << text;
    try {
      load_device_script(path);
    } catch (const InputError& e) {
      return std::string(e.what()).substr(path.size());
    }
    return std::string("no error");
  };
  EXPECT_EQ(load("device: scripted\ntasks:\n  - pull:\n      timeline:\n        - {t_s: 0, offset_mm: [0, 0]}\n"),
            ":5:31: 'offset_mm' must be a list of 3 numbers, e.g. [0, 0, -10]");
  EXPECT_EQ(load("device: scripted\ntasks:\n  - pull:\n      timeline:\n        - {t_s: 1, offset_mm: [0, 0, 0]}\n"
                 "        - {t_s: 0.5, offset_mm: [0, 0, 1]}\n"),
            ":6:17: timeline times must increase, got 0.5 after 1");
  EXPECT_EQ(load("device: phantom\ntasks: []\n"), ":1:9: device must be 'scripted' in a device script, got 'phantom'");
  // A script that does not match the lesson's tasks.
  const Lesson l = load_lesson(test::lessons_dir() + "/sectional_anatomy.yaml");  // pick, question
  const DeviceScript wrong = load_device_script(test::lessons_dir() + "/scripts/kidney_anchor.pass.yaml");
  EXPECT_THROW(check_script_matches(wrong, l), InputError);
  // Every mismatch, in the script's order, each naming both tasks.
  const std::string path = dir + "/mismatch.yaml";
  std::ofstream(path)
      << "device: scripted\ntasks:\n  - wait: {}\n  - pull: {timeline: [{t_s: 0, offset_mm: [0, 0, 0]}]}\n"
         "  - pick: {click_mm: [0, 0, 0]}\n";
  try {
    check_script_matches(load_device_script(path), l);
    FAIL();
  } catch (const InputError& e) {
    const std::string w = e.what();
    const size_t a = w.find(path + ":3:5: task 1 is 'wait' but the lesson's task 1");
    const size_t b = w.find(path + ":4:5: task 2 is 'pull' but the lesson's task 2");
    const size_t c = w.find(path + ":5:5: the script has 3 tasks but lesson");
    EXPECT_NE(a, std::string::npos) << w;
    EXPECT_NE(b, std::string::npos) << w;
    EXPECT_NE(c, std::string::npos) << w;
    EXPECT_TRUE(a < b && b < c) << w;
    EXPECT_NE(w.find("(1 pick, 2 answer)"), std::string::npos) << w;
  }
}

}  // namespace
}  // namespace softatlas::app
