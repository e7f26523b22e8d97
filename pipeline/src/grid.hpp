// Voxel-grid walking shared by the segmentation passes (private to the pipeline).
#pragma once

#include <array>
#include <cstddef>

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

}  // namespace softatlas::pipeline
