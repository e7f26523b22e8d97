// Every input under tests/data/fuzz/TARGET/ once crashed, hung or was accepted silently; each is fed
// through the same entry as the fuzz target and must give at most one clean InputError: one line (lessons and device scripts: one line per
// error, each starting with the file), printable text, naming the input's file. A hang is caught by the test's timeout.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "entries.hpp"
#include "softatlas/sim/error.hpp"

namespace fs = std::filesystem;

namespace softatlas::fuzz {
namespace {

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

class Regression : public ::testing::TestWithParam<std::string> {};

TEST_P(Regression, EveryInputIsAcceptedOrRejectedWithOneCleanLine) {
  const fs::path dir = fs::path(SOFTATLAS_SOURCE_DIR) / "tests" / "data" / "fuzz" / GetParam();
  if (!fs::is_directory(dir)) GTEST_SKIP() << "no regression inputs for " << GetParam();
  int count = 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (!e.is_regular_file() || e.path().filename().string()[0] == '.') continue;
    ++count;
    try {
      feed(GetParam(), slurp(e.path()));
    } catch (const InputError& err) {
      const std::string msg = err.what();
      // Lessons and device scripts report every error of the file (docs/lessons.md), one
      // FILE:LINE:COLUMN line each; every other reader stops at its first error: one line.
      const bool many = GetParam() == "lesson" || GetParam() == "device_script";
      if (many) {
        std::istringstream lines(msg);
        for (std::string line; std::getline(lines, line);)
          EXPECT_EQ(line.rfind(scratch(), 0), 0u) << e.path() << ": a line that does not start with the file: " << line;
      } else {
        EXPECT_EQ(msg.find('\n'), std::string::npos) << e.path() << ": " << msg;
      }
      // The readers of io/ and pipeline/ quote only printable text; the lesson, device-script,
      // seed and build.yaml messages are made printable where `softatlas` prints them (main.cpp).
      const bool own = GetParam() != "lesson" && GetParam() != "device_script" && GetParam() != "seeds" &&
                       GetParam() != "build_yaml";
      for (unsigned char c : msg) {
        if (!own) break;
        EXPECT_TRUE(c >= 32 && c < 127) << e.path() << ": non-printable byte in: " << msg;
        if (!(c >= 32 && c < 127)) break;
      }
      EXPECT_NE(msg.find(scratch()), std::string::npos) << e.path() << ": does not name the file: " << msg;
    } catch (const std::exception& err) {
      ADD_FAILURE() << e.path() << ": not an InputError: " << err.what();
    }
  }
  EXPECT_GT(count, 0);
}

INSTANTIATE_TEST_SUITE_P(Fuzz, Regression, ::testing::ValuesIn(targets()),
                         [](const ::testing::TestParamInfo<std::string>& i) { return i.param; });

}  // namespace
}  // namespace softatlas::fuzz
