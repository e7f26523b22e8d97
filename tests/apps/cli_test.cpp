// The softatlas binary run as a user runs it: exit 0 ok, 1 bad input, 2 usage error (docs/user-guide.md),
// every error one line on stderr beginning "softatlas:".
#include <gtest/gtest.h>

#include "run_softatlas.hpp"

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

using softatlas::test::Result;

// A scratch folder per test, removed afterwards.
struct Scratch {
  fs::path dir;
  Scratch() {
    dir = fs::temp_directory_path() / ("softatlas-cli-" + std::to_string(::getpid()) + "-" +
                                       ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  ~Scratch() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
  std::string operator()(const std::string& name) const { return (dir / name).string(); }
};

Result run(const Scratch& tmp, const std::vector<std::string>& args) {
  return softatlas::test::run_softatlas(args, tmp(""));
}

int lines(const std::string& s) {
  int n = 0;
  for (char c : s) n += c == '\n';
  return n;
}

std::string data(const std::string& rel) { return std::string(SOFTATLAS_SOURCE_DIR) + "/data/" + rel; }

// A usage error: status 2, the first stderr line names the command, the second points to --help.
void expect_usage_error(const Scratch& tmp, const std::vector<std::string>& args, const std::string& names) {
  const Result r = run(tmp, args);
  std::string cmd;
  for (const auto& a : args) cmd += a + " ";
  EXPECT_EQ(r.rc, 2) << cmd << "\n" << r.err;
  EXPECT_EQ(r.err.rfind("softatlas: ", 0), 0u) << cmd << "\n" << r.err;
  EXPECT_NE(r.err.find(names), std::string::npos) << cmd << "\n" << r.err;
  EXPECT_TRUE(r.out.empty()) << cmd;
}

// Bad input: status 1, exactly one stderr line "softatlas: ..." naming the file or option (`lesson
// check` prints FILE:LINE:COLUMN: lines without the prefix, the format editors read).
void expect_bad_input(const Scratch& tmp, const std::vector<std::string>& args, const std::string& names,
                      const std::string& prefix = "softatlas: ") {
  const Result r = run(tmp, args);
  std::string cmd;
  for (const auto& a : args) cmd += a + " ";
  EXPECT_EQ(r.rc, 1) << cmd << "\n" << r.err;
  EXPECT_EQ(r.err.rfind(prefix, 0), 0u) << cmd << "\n" << r.err;
  EXPECT_EQ(lines(r.err), 1) << cmd << "\n" << r.err;
  EXPECT_NE(r.err.find(names), std::string::npos) << cmd << "\n" << r.err;
}

}  // namespace

TEST(SoftatlasCli, UsageErrorsExit2) {
  Scratch tmp;
  const Result none = run(tmp, {});
  EXPECT_EQ(none.rc, 2);
  EXPECT_EQ(none.err.rfind("usage: softatlas", 0), 0u) << none.err;
  expect_usage_error(tmp, {"frobnicate"}, "unknown command 'frobnicate'");
  expect_usage_error(tmp, {"bench"}, "bench");
  expect_usage_error(tmp, {"bench", "frobnicate"}, "bench");
  expect_usage_error(tmp, {"sim"}, "sim: inputs");
  expect_usage_error(tmp, {"sim", "demo", "--hold-steps", "1000000"}, "sim demo: --hold-steps");
  expect_usage_error(tmp, {"sim", "demo", "--pull-mm", "nan"}, "--pull-mm");
  expect_usage_error(tmp, {"bench", "sim", "--steps", "100"}, "--mesh");  // --mesh is required
  expect_usage_error(tmp, {"bench", "accuracy", "--grid", "tiny"}, "--out");
  expect_usage_error(tmp, {"demo", "--bogus"}, "--bogus");
#ifdef SOFTATLAS_HAVE_PIPELINE
  expect_usage_error(tmp, {"build", data("sample/ct_heart_crop.nii.gz"), "--stiffness", "nan", "-o", tmp("set")},
                     "build: --stiffness");
  expect_usage_error(tmp, {"build", "-o", tmp("set"), "--frobnicate"}, "--frobnicate");
  expect_usage_error(tmp, {"export", data("atlas"), "-o", tmp("a.glb"), "--web", tmp("web")}, "export");
  EXPECT_FALSE(fs::exists(tmp("set")));
#endif
#ifdef SOFTATLAS_HAVE_APP
  expect_usage_error(tmp, {"lesson"}, "lesson");
  expect_usage_error(tmp, {"lesson", "run", data("lessons/liver_mobility.yaml")}, "--device");
  expect_usage_error(tmp, {"view", data("atlas"), "--headless", "--frames", "0"}, "--frames");
#endif
}

TEST(SoftatlasCli, BadInputExits1WithOneLine) {
  Scratch tmp;
  expect_bad_input(tmp, {"sim", tmp("missing.obj"), "--explain"}, "missing.obj");
  expect_bad_input(tmp, {"bench", "sim", "--mesh", tmp("missing.obj"), "--steps", "10"}, "missing.obj");
  expect_bad_input(tmp, {"sim", "demo", "--mesh", tmp("missing.obj"), "--out", tmp("demo")}, "missing.obj");
  EXPECT_FALSE(fs::exists(tmp("demo")));
#ifdef SOFTATLAS_HAVE_PIPELINE
  expect_bad_input(tmp, {"check", tmp("no_set")}, "no_set");
  expect_bad_input(tmp, {"build", tmp("missing.nii.gz"), "-o", tmp("set")}, "missing.nii.gz");
  EXPECT_FALSE(fs::exists(tmp("set")));
#endif
#ifdef SOFTATLAS_HAVE_APP
  { std::ofstream(tmp("bad.yaml")) << "lesson: [unclosed\n"; }
  expect_bad_input(tmp, {"lesson", "check", tmp("bad.yaml")}, "YAML syntax", tmp("bad.yaml") + ":2:");
#endif
}

TEST(SoftatlasCli, SuccessExits0) {
  Scratch tmp;
  Result r = run(tmp, {"--version"});
  EXPECT_EQ(r.rc, 0);
  EXPECT_EQ(r.out.rfind("softatlas ", 0), 0u) << r.out;
  r = run(tmp, {"--help"});
  EXPECT_EQ(r.rc, 0);
  EXPECT_NE(r.out.find("usage: softatlas"), std::string::npos);
  for (const std::vector<std::string>& help :
       {std::vector<std::string>{"sim", "demo", "--help"}, {"bench", "restore", "--help"}, {"demo", "--help"}}) {
    r = run(tmp, help);
    EXPECT_EQ(r.rc, 0) << help[0] << " " << help[1];
    EXPECT_NE(r.out.find("Usage: softatlas " + help[0]), std::string::npos) << r.out;
  }
  r = run(tmp, {"sim", data("meshes/liver_1000.obj"), "--explain"});
  EXPECT_EQ(r.rc, 0) << r.err;
  EXPECT_NE(r.out.find("compiled plan"), std::string::npos);
  r = run(tmp, {"sim", "demo", "--hold-steps", "20", "--out", tmp("physics")});
  EXPECT_EQ(r.rc, 0) << r.err;
  EXPECT_TRUE(fs::exists(tmp("physics/results.json")));
  EXPECT_TRUE(fs::exists(tmp("physics/deformation.svg")));
#ifdef SOFTATLAS_HAVE_PIPELINE
  r = run(tmp, {"build", "--help"});
  EXPECT_EQ(r.rc, 0);
  EXPECT_NE(r.out.find("--stiffness"), std::string::npos);
  r = run(tmp, {"check", data("atlas")});
  EXPECT_EQ(r.rc, 0) << r.err;
  EXPECT_NE(r.out.find("\"ok\""), std::string::npos);
  r = run(tmp, {"export", data("atlas"), "-o", tmp("atlas.glb")});
  EXPECT_EQ(r.rc, 0) << r.err;
  EXPECT_TRUE(fs::exists(tmp("atlas.glb")));
#endif
#ifdef SOFTATLAS_HAVE_APP
  r = run(tmp, {"lesson", "check", data("lessons/liver_mobility.yaml"), "--device",
                data("lessons/scripts/liver_mobility.pass.yaml")});
  EXPECT_EQ(r.rc, 0) << r.err;
  EXPECT_NE(r.out.find(": ok ("), std::string::npos) << r.out;
#endif
}
