// The seed-file entry: it needs only the segmentation sources (pipeline/src/segment.cpp and what
// it calls, no CGAL) beside the readers, so its fuzz executable builds in minutes, like the
// readers' (fuzz/CMakeLists.txt).
#include <filesystem>

#include "entries.hpp"
#include "softatlas/pipeline/segment.hpp"

namespace fs = std::filesystem;

namespace softatlas::fuzz {

bool feed_seeds(const std::string& target, const std::string& bytes) {
  if (target != "seeds") return false;
  const fs::path f = fs::path(scratch()) / "seeds.yaml";
  write_input(f.string(), bytes);
  pipeline::read_seeds(f.string());
  return true;
}

}  // namespace softatlas::fuzz
