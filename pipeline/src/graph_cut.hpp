// Binary s-t minimum cut on a box of voxels with face-neighbour edges (Boykov & Kolmogorov 2004
// max-flow, Boost.Graph). Private to the pipeline.
#pragma once

#include <array>
#include <vector>

namespace softatlas::pipeline {

struct VoxelCut {
  std::array<int, 3> dims{0, 0, 0};  // box voxels, x fastest
  // Per voxel: cost of giving it the sink label (background), minus cost of the source label
  // (organ). Positive: the voxel prefers the organ. Hard constraints are large magnitudes.
  std::vector<float> preference;
  // Per voxel and axis: capacity of the edge to the +axis neighbour (symmetric).
  std::array<std::vector<float>, 3> edge;
};

// 1 where the voxel is on the source (organ) side of a minimum cut.
std::vector<char> min_cut(const VoxelCut& problem);

}  // namespace softatlas::pipeline
