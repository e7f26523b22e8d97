// Voxel-grid walking shared by the segmentation passes (private to the pipeline).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <vector>

#include "softatlas/pipeline/volume.hpp"

namespace softatlas::pipeline {

// Calls f(q, axis) for each of the 6 face neighbours q of voxel `id` that lie inside a grid of
// `d` voxels (x fastest), in the order -x, +x, -y, +y, -z, +z; axis is 0, 1 or 2.
template <class F>
inline void for_each_face_neighbour(const std::array<int, 3>& d, size_t id, F&& f) {
  const size_t sy = static_cast<size_t>(d[0]), sz = sy * static_cast<size_t>(d[1]);
  const int i = static_cast<int>(id % sy), j = static_cast<int>((id / sy) % static_cast<size_t>(d[1])),
            k = static_cast<int>(id / sz);
  if (i > 0) f(id - 1, 0);
  if (i + 1 < d[0]) f(id + 1, 0);
  if (j > 0) f(id - sy, 1);
  if (j + 1 < d[1]) f(id + sy, 1);
  if (k > 0) f(id - sz, 2);
  if (k + 1 < d[2]) f(id + sz, 2);
}

// Voxel spacing in mm along each index axis (lengths of the columns of ijk_to_ras).
inline std::array<double, 3> spacing_mm(const Volume& v) {
  std::array<double, 3> sp{};
  for (int c = 0; c < 3; ++c)
    sp[c] = std::sqrt(v.ijk_to_ras[c] * v.ijk_to_ras[c] + v.ijk_to_ras[4 + c] * v.ijk_to_ras[4 + c] +
                      v.ijk_to_ras[8 + c] * v.ijk_to_ras[8 + c]);
  return sp;
}

// Separable Gaussian blur with sigma in voxels per axis (kernel cut at 3 sigma, clamped edges).
inline std::vector<float> gaussian(const std::vector<float>& in, const std::array<int, 3>& d, const double sigma[3]) {
  std::vector<float> a = in, b(in.size());
  const size_t stride[3] = {1, static_cast<size_t>(d[0]), static_cast<size_t>(d[0]) * d[1]};
  for (int axis = 0; axis < 3; ++axis) {
    if (sigma[axis] <= 0) continue;
    const int r = static_cast<int>(std::ceil(3.0 * sigma[axis]));
    std::vector<float> w(2 * r + 1);
    double sum = 0;
    for (int t = -r; t <= r; ++t)
      sum += w[t + r] = static_cast<float>(std::exp(-0.5 * t * t / (sigma[axis] * sigma[axis])));
    for (float& x : w) x = static_cast<float>(x / sum);
    for (size_t id = 0; id < a.size(); ++id) {
      const int c = static_cast<int>((id / stride[axis]) % d[axis]);
      float acc = 0;
      for (int t = -r; t <= r; ++t) {
        const int q = std::clamp(c + t, 0, d[axis] - 1);
        acc += w[t + r] * a[id + (static_cast<long>(q) - c) * static_cast<long>(stride[axis])];
      }
      b[id] = acc;
    }
    a.swap(b);
  }
  return a;
}

}  // namespace softatlas::pipeline
