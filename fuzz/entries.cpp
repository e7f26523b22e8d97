#include "entries.hpp"

#include <filesystem>
#include <stdexcept>

#include "softatlas/app/lesson.hpp"
#include "softatlas/pipeline/build.hpp"
#include "softatlas/sim/error.hpp"

namespace fs = std::filesystem;

namespace softatlas::fuzz {

const std::vector<std::string>& targets() {
  static const std::vector<std::string> t = {"nifti",         "nrrd",     "metaimage", "dicom",     "mesh_obj",
                                             "mesh_ply",      "mesh_stl", "mesh_off",  "organ_set", "lesson",
                                             "device_script", "seeds",    "build_yaml"};
  return t;
}

void feed(const std::string& target, const std::string& bytes) {
  if (feed_reader(target, bytes) || feed_lesson(target, bytes) || feed_seeds(target, bytes)) return;
  const fs::path dir = scratch();
  if (target == "build_yaml") {
    const fs::path f = dir / "build.yaml";
    write_input(f.string(), bytes);
    pipeline::BuildOptions options;
    pipeline::apply_build_config(f.string(), &options);
  } else {
    throw std::invalid_argument("unknown fuzz target '" + target + "'");
  }
}

}  // namespace softatlas::fuzz
