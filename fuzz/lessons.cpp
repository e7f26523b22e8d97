// The lesson and device-script entries: they need only the lesson sources (atlas_app/src/lesson.cpp,
// device_script.cpp) beside the readers, so their fuzz executables build in minutes, like the
// readers' (fuzz/CMakeLists.txt).
#include <filesystem>

#include "entries.hpp"
#include "softatlas/app/lesson.hpp"

namespace fs = std::filesystem;

namespace softatlas::fuzz {

bool feed_lesson(const std::string& target, const std::string& bytes) {
  const fs::path dir = scratch();
  if (target == "lesson") {
    const fs::path f = dir / "lessons" / "input.yaml";  // its organ set is ../atlas, the demo set
    write_input(f.string(), bytes);
    app::load_lesson(f.string());
  } else if (target == "device_script") {
    const fs::path f = dir / "script.yaml";
    write_input(f.string(), bytes);
    app::load_device_script(f.string());
  } else {
    return false;
  }
  return true;
}

}  // namespace softatlas::fuzz
