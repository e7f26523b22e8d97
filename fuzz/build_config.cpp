// The build.yaml entry: it needs only pipeline/src/build_config.cpp (yaml-cpp) beside the readers'
// scratch helpers, so its fuzz executable builds in seconds (fuzz/CMakeLists.txt).
#include <filesystem>

#include "entries.hpp"
#include "softatlas/pipeline/build.hpp"

namespace fs = std::filesystem;

namespace softatlas::fuzz {

bool feed_build_config(const std::string& target, const std::string& bytes) {
  if (target != "build_yaml") return false;
  const fs::path f = fs::path(scratch()) / "build.yaml";
  write_input(f.string(), bytes);
  pipeline::BuildOptions options;
  pipeline::apply_build_config(f.string(), &options);
  return true;
}

}  // namespace softatlas::fuzz
