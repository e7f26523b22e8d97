// Seeded organ segmentation by graph cut (private to the pipeline; used by segment.cpp).
//
// Per seeded organ, a binary minimum cut (Boykov & Jolly 2001; max-flow of Boykov & Kolmogorov
// 2004) in a box around its seeds. The energy, with every constant in millimetres:
//  * data term per mm^3: -log p_organ(I) + log p_image(I), where I is the image smoothed at 1 mm,
//    p_organ a kernel density of the smoothed values within seed_radius_mm of the organ's seeds
//    mixed with the organ's HU prior for the contrast phase detected in the image, and p_image
//    the histogram of the whole image (the background model: how common the value is anywhere);
//  * distance prior per mm^3: distance_weight * (d - r) / r beyond r, with d the distance to the
//    organ's seed tree (the minimum spanning tree of its seeds, so a vessel's seeds span the
//    vessel) and r the organ's radius prior;
//  * boundary per mm^2 of face: smoothness_mm * exp(-dI^2 / (2 edge_sigma^2)), edge_sigma from
//    the image's own noise (Boykov & Jolly 2001, eq. 2 of their boundary term);
//  * hard constraints: the organ's seeds are organ, background points and other organs' seeds
//    are background, the box's inner faces are background.
// Voxels claimed by two organs go to the one whose data + distance term prefers it most. A
// region above its organ's volume bound is cut again with a doubled distance prior (twice at
// most), then a warning is printed.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "softatlas/pipeline/segment.hpp"
#include "softatlas/pipeline/volume.hpp"

namespace softatlas::pipeline {

struct CutOrgan {
  int id;  // TotalSegmentator id
  std::vector<size_t> seeds;
};

// owner per voxel: index into `organs`, or -1. Progress and warnings on stderr.
std::vector<int16_t> seeded_cut(const Volume& ct, const std::vector<float>& smooth, const std::vector<CutOrgan>& organs,
                                const std::vector<size_t>& background, const SegmentOptions& options);

}  // namespace softatlas::pipeline
