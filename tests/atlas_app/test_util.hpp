#pragma once

#include <filesystem>
#include <string>

namespace softatlas::app::test {

inline std::string atlas_dir() { return std::string(SOFTATLAS_SOURCE_DIR) + "/data/atlas"; }
inline std::string lessons_dir() { return std::string(SOFTATLAS_SOURCE_DIR) + "/data/lessons"; }

// A fresh folder under the build tree for one test's output.
inline std::string scratch(const std::string& name) {
  const std::filesystem::path p = std::filesystem::path(SOFTATLAS_BINARY_DIR) / "test_output" / "atlas_app" / name;
  std::filesystem::remove_all(p);
  std::filesystem::create_directories(p);
  return p.string();
}

}  // namespace softatlas::app::test
