// The reader entries (volumes, meshes, organ sets): they need only the reader sources, so the
// fuzz executables for them build in minutes (fuzz/CMakeLists.txt).
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <stdexcept>

#include "entries.hpp"
#include "softatlas/io/mesh_io.hpp"
#include "softatlas/io/organ_set.hpp"
#include "softatlas/pipeline/volume.hpp"
#include "softatlas/sim/error.hpp"

namespace fs = std::filesystem;

namespace softatlas::fuzz {
namespace {
void write(const fs::path& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out) throw std::runtime_error("fuzz harness: cannot write " + path.string());
}

// The scratch folder is under TMPDIR (scripts/fuzz sets /dev/shm: every input is written to a
// file, since the readers take paths, and tmpfs makes that write cheap).
struct Scratch {
  fs::path dir;
  Scratch() {
    const char* t = std::getenv("TMPDIR");
    dir = fs::path(t && *t ? t : "/tmp") / ("softatlas-fuzz-" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir / "lessons");
    // Lessons name their organ set as ../atlas: the demo set, read-only, by a link.
    fs::create_directory_symlink(fs::path(SOFTATLAS_SOURCE_DIR) / "data" / "atlas", dir / "atlas");
  }
  ~Scratch() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

Scratch& the_scratch() {
  static Scratch s;
  return s;
}

// An organ set folder: atlas.yaml is the input up to a line "--- connections.csv", the rest is
// connections.csv; the meshes are the demo set's.
// The folder and its link are made once; each input rewrites atlas.yaml and writes or removes
// connections.csv (a remove_all + mkdir + symlink per input cost more than the reader).
void feed_organ_set(const std::string& bytes) {
  const fs::path set = the_scratch().dir / "set";
  static const bool made = [&] {
    fs::create_directories(set);
    fs::create_directory_symlink(fs::path(SOFTATLAS_SOURCE_DIR) / "data" / "atlas" / "organs", set / "organs");
    return true;
  }();
  (void)made;
  const std::string sep = "\n--- connections.csv\n";
  const size_t p = bytes.find(sep);
  write(set / "atlas.yaml", bytes.substr(0, p));
  if (p != std::string::npos) {
    write(set / "connections.csv", bytes.substr(p + sep.size()));
  } else {
    std::error_code ec;
    fs::remove(set / "connections.csv", ec);
  }
  io::read_organ_set(set.string());
}

}  // namespace

void write_input(const std::string& path, const std::string& bytes) { write(path, bytes); }

const std::string& scratch() {
  static const std::string s = the_scratch().dir.string();
  return s;
}

bool feed_reader(const std::string& target, const std::string& bytes) {
  const fs::path dir = the_scratch().dir;
  if (target == "nifti") {
    const bool gz = bytes.size() >= 2 && static_cast<unsigned char>(bytes[0]) == 0x1f &&
                    static_cast<unsigned char>(bytes[1]) == 0x8b;
    const fs::path f = dir / (gz ? "input.nii.gz" : "input.nii");
    write(f, bytes);
    pipeline::read_volume(f.string());
  } else if (target == "nrrd" || target == "metaimage") {
    const fs::path f = dir / (target == "nrrd" ? "input.nrrd" : "input.mha");
    write(f, bytes);
    pipeline::read_volume(f.string());
  } else if (target == "dicom") {
    const fs::path folder = dir / "dicom";  // made once; its one file is rewritten per input
    static const bool made = fs::create_directories(folder);
    (void)made;
    write(folder / "slice.dcm", bytes);
    pipeline::read_volume(folder.string());
  } else if (target.rfind("mesh_", 0) == 0) {
    const fs::path f = dir / ("input." + target.substr(5));
    write(f, bytes);
    io::read_mesh(f.string());
  } else if (target == "organ_set") {
    feed_organ_set(bytes);
  } else {
    return false;
  }
  return true;
}

}  // namespace softatlas::fuzz
