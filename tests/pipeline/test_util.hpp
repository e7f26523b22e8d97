// Helpers shared by the pipeline tests: shared-data paths and scratch folders.
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <random>
#include <string>

namespace softatlas::pipeline::test {

inline std::string shared(const std::string& rel) { return std::string(SOFTATLAS_SHARED_DATA) + "/" + rel; }
inline std::string chest(const std::string& f) { return shared("ct/chest_cta_crops/" + f); }
inline std::string abdomen(const std::string& f) { return shared("ct/abdomen_dicom_slab/" + f); }

// A fresh scratch folder under the build tree, removed at the end of the test.
struct Scratch {
  std::filesystem::path dir;
  Scratch() {
    std::random_device rd;
    dir = std::filesystem::path(SOFTATLAS_BINARY_DIR) / "test-scratch" /
          ("pipeline-" + std::to_string(rd()) + std::to_string(rd()));
    std::filesystem::create_directories(dir);
  }
  ~Scratch() {
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
  }
  std::string operator()(const std::string& name) const { return (dir / name).string(); }
};

}  // namespace softatlas::pipeline::test
