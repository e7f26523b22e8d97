// Stage 2b, seeded segmentation: competitive region growing (fuzzy-connectedness style: fronts
// meet at the lowest intensity barrier), a tube model for large vessels, a wall model for the
// heart, then hole filling and morphological clean-up (pipeline/src/segment.cpp).
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
  // Stage 1: "graph_cut" (per-organ minimum cut with seed-learned intensity models, a whole-image
  // background model, a distance prior and volume bounds; pipeline/src/seeded_cut.hpp) or
  // "growth" (the earlier competitive region growing inside seed-derived windows).
  std::string method = "graph_cut";
  double seed_radius_mm = 4;          // intensity samples within this distance of each seed
  double cut_bandwidth_min_hu = 15;   // kernel density bandwidth floor (else 1.5 x image noise)
  double cut_edge_sigma_min_hu = 10;  // boundary term's intensity scale floor (else 2 x noise)
  double cut_window_weight = 0.4;     // share of the seeds' flat window in the organ's density
  double cut_prior_weight = 0.1;      // share of the phase's HU prior in the organ's density
  double cut_max_nats = 6;            // data term clamp per voxel
  double cut_distance_weight = 2;     // nats per mm^3 per organ radius beyond the radius prior
  double cut_margin_radii = 3;        // the cut's box: the seeds' box grown by this many radii
  double cut_smoothness_mm = 1.5;     // boundary weight per mm^2 (relative to the data per mm^3)
  // background model: "box", the histogram of the cut's box (for a large organ nearly the whole
  // image; slab stomach 0.47 -> 0.64, pancreas volume 5.4x -> 2.4x), or "image", the whole image's histogram
  std::string cut_background = "box";
  double cut_radius_scale = 1.0;            // scales every organ's radius prior
  double intensity_sigma_scale = 2.5;       // accept down to this many seed-sigma below the seed mean
  double intensity_sigma_scale_high = 4.0;  // and up to this many above (dense contrast at an inflow)
  double intensity_sigma_max_hu = 100.0;    // cap of the seed sigma
  double edge_bin_hu = 10.0;                // intensity steps are compared in bins of this size
  // Where fronts meet over equal barriers, a background front's path counts this many times its
  // length: organ clicks go deep inside an organ, background clicks onto a leak near its edge, so
  // an even split of the distance would cut into the organ (a click in a pulmonary vein took a
  // fifth of the left atrium; docs/pipeline.md).
  double background_length_weight = 2.0;
  int closing_radius = 1;  // voxels, morphological clean-up
  // Organs whose label holds a contrast-filled cavity and a muscular wall that no blood-pool
  // window admits (the heart: chambers + myocardium). After the competitive growth, such an
  // organ grows a wall from its region through voxels whose smoothed intensity is at least
  // min_hu (and below the organ's window) up to thickness_mm, competing with the other organs and
  // the background seeds. See docs/pipeline.md for the measurements behind the defaults.
  struct Wall {
    double min_hu;
    double thickness_mm;
  };
  // (walls and tubes apply to method "growth" only: with the graph cut the tube took the heart
  // crop's aorta from Dice 0.45 to 0.12; docs/pipeline.md)
  std::map<std::string, Wall> walls = {{"heart", {95.0, 10.5}}};
  // Vessels replaced by a tube fitted to the grown region (centreline between the farthest seeds,
  // round cross-sections bounded by fat or air; see pipeline/src/tube.hpp): an uneven contrast
  // bolus leaves part of the lumen dark, and a wide window leaks into bone and branches.
  std::vector<std::string> tubes = {"aorta"};
  double tube_stop_hu = -30;  // the tube's wall ends where the smoothed image drops below this
  // A ray that crossed a contrast-filled lumen (this bright or more) ends a wall past its edge,
  // also where soft tissue rather than fat touches the wall; 0 switches it off.
  double tube_lumen_min_hu = 200;
  double smoothing_mm = 1.0;  // Gaussian sigma of the image the growth, walls and tubes read
};

// Label map on the CT's grid with TotalSegmentator ids. `where` names the seed file in errors.
Volume segment_seeded(const Volume& ct, const Seeds& seeds, const SegmentOptions& options, const std::string& where);

// Dice of label `id_a` in a and `id_b` in b (same grid).
double dice(const Volume& a, int id_a, const Volume& b, int id_b);

}  // namespace softatlas::pipeline
