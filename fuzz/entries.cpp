#include "entries.hpp"

#include <stdexcept>

namespace softatlas::fuzz {

const std::vector<std::string>& targets() {
  static const std::vector<std::string> t = {"nifti",         "nrrd",     "metaimage", "dicom",     "mesh_obj",
                                             "mesh_ply",      "mesh_stl", "mesh_off",  "organ_set", "lesson",
                                             "device_script", "seeds",    "build_yaml"};
  return t;
}

void feed(const std::string& target, const std::string& bytes) {
  if (feed_reader(target, bytes) || feed_lesson(target, bytes) || feed_seeds(target, bytes) ||
      feed_build_config(target, bytes))
    return;
  throw std::invalid_argument("unknown fuzz target '" + target + "'");
}

}  // namespace softatlas::fuzz
