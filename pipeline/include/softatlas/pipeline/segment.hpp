// Stage 2b, seeded segmentation: competitive region growing (grow-cut style) on intensity with
// edge weighting, then hole filling and morphological clean-up.
#pragma once

#include <array>
#include <map>
#include <string>
#include <vector>

#include "softatlas/pipeline/volume.hpp"

namespace softatlas::pipeline {

struct Seeds {
  std::map<std::string, std::vector<std::array<double, 3>>> organs;  // world RAS mm
  std::vector<std::array<double, 3>> background;
};

// organs: {liver: [[x, y, z], ...], ...}, background: [[x, y, z], ...]. InputError with
// file:line:column for unknown organs, bad points, or seeds outside `ct` (when given).
Seeds read_seeds(const std::string& path);

struct SegmentOptions {
  double intensity_sigma_scale = 2.5;  // accept up to this many seed-sigma from the seed mean
  double edge_weight = 1.0;            // weight of the gradient term in the path cost
  double intensity_sigma_max_hu = 100.0;  // cap of the seed sigma
  double edge_sigma_hu = 30.0;         // intensity step that doubles the cost of a step
  int closing_radius = 1;              // voxels, morphological clean-up
};

// Label map on the CT's grid with TotalSegmentator ids. `where` names the seed file in errors.
Volume segment_seeded(const Volume& ct, const Seeds& seeds, const SegmentOptions& options,
                      const std::string& where);

// Dice of label `id_a` in a and `id_b` in b (same grid).
double dice(const Volume& a, int id_a, const Volume& b, int id_b);

}  // namespace softatlas::pipeline
