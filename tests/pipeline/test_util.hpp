// Helpers shared by the pipeline tests: shared-data paths and scratch folders.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "softatlas/io/mesh_io.hpp"
#include "softatlas/pipeline/volume.hpp"

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

// A closed surface as a 0/1 label map on an axis-aligned grid of `h` mm (voxel centres inside
// by ray parity along +z; two voxels of margin): real organ shapes, thin tips included, become
// label maps whose truth is known.
inline Volume voxelize(const io::TriMesh& m, double h) {
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  for (size_t v = 0; v < m.vertex_count(); ++v)
    for (int c = 0; c < 3; ++c)
      lo[c] = std::min(lo[c], m.vertices[3 * v + c]), hi[c] = std::max(hi[c], m.vertices[3 * v + c]);
  Volume vol;
  for (int c = 0; c < 3; ++c) {
    lo[c] -= 2 * h;
    vol.dims[c] = static_cast<int>(std::ceil((hi[c] + 2 * h - lo[c]) / h)) + 1;
  }
  vol.ijk_to_ras = {h, 0, 0, lo[0], 0, h, 0, lo[1], 0, 0, h, lo[2], 0, 0, 0, 1};
  vol.values.assign(static_cast<size_t>(vol.dims[0]) * vol.dims[1] * vol.dims[2], 0.0f);
  vol.format = "nifti";
  std::vector<std::vector<double>> hits(static_cast<size_t>(vol.dims[0]) * vol.dims[1]);
  for (size_t f = 0; f < m.face_count(); ++f) {
    const double* a = &m.vertices[3 * m.faces[3 * f]];
    const double* b = &m.vertices[3 * m.faces[3 * f + 1]];
    const double* c = &m.vertices[3 * m.faces[3 * f + 2]];
    const double det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
    if (std::abs(det) < 1e-14) continue;
    const int i0 = std::max(0, static_cast<int>(std::floor((std::min({a[0], b[0], c[0]}) - lo[0]) / h)));
    const int i1 = std::min(vol.dims[0] - 1, static_cast<int>(std::ceil((std::max({a[0], b[0], c[0]}) - lo[0]) / h)));
    const int j0 = std::max(0, static_cast<int>(std::floor((std::min({a[1], b[1], c[1]}) - lo[1]) / h)));
    const int j1 = std::min(vol.dims[1] - 1, static_cast<int>(std::ceil((std::max({a[1], b[1], c[1]}) - lo[1]) / h)));
    for (int j = j0; j <= j1; ++j)
      for (int i = i0; i <= i1; ++i) {
        const double x = lo[0] + i * h, y = lo[1] + j * h;
        const double u = ((b[0] - x) * (c[1] - y) - (c[0] - x) * (b[1] - y)) / det;
        const double v = ((c[0] - x) * (a[1] - y) - (a[0] - x) * (c[1] - y)) / det;
        const double w = 1.0 - u - v;
        if (u < 0 || v < 0 || w < 0) continue;
        hits[i + static_cast<size_t>(vol.dims[0]) * j].push_back(u * a[2] + v * b[2] + w * c[2]);
      }
  }
  for (int j = 0; j < vol.dims[1]; ++j)
    for (int i = 0; i < vol.dims[0]; ++i) {
      auto& z = hits[i + static_cast<size_t>(vol.dims[0]) * j];
      std::sort(z.begin(), z.end());
      for (size_t p = 0; p + 1 < z.size(); p += 2)
        for (int k = std::max(0, static_cast<int>(std::ceil((z[p] - lo[2]) / h)));
             k < vol.dims[2] && lo[2] + k * h <= z[p + 1]; ++k)
          vol.values[vol.index(i, j, k)] = 1.0f;
    }
  return vol;
}

}  // namespace softatlas::pipeline::test
