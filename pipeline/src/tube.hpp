// Tube model for large vessels in seeded segmentation (private to the pipeline).
//
// A contrast bolus does not fill a vessel evenly: in an early arterial phase the descending aorta
// holds a bright crescent of contrast next to unenhanced blood (about 60-90 HU), and an
// intensity window that admits both also admits bone, muscle and the branch vessels. A vessel is
// a tube, so the grown region is replaced by one:
//  1. centreline: the cheapest path through the grown region (its cost falls with the depth
//     inside it, so the path stays medial; gaps in the enhancement are crossed at a high cost)
//     between the two seeds farthest apart along it (double sweep);
//  2. cross-sections every `step_mm`, normal to the path smoothed over +-10 mm: rays stop where
//     the smoothed image falls to fat or air, turns bright outside the grown region and its
//     one-voxel rim (bone, another vessel), or meets another organ. The ray ends lie on the
//     vessel's outline from any point inside it, except for rays that leak (into muscle, a
//     branch), which end too far out: a circle is fitted to the shorter 60 % of them, then to the
//     ends within 20 % of that circle (four rounds). Three passes re-centre the path on the
//     circles; then each end is extended while its sections stay round (half the rays or more
//     fit), of a similar radius (0.6-1.4x) and do not jump sideways;
//     Where the lumen is filled with contrast, a ray that crossed it (peak >= lumen_min_hu) ends
//     wall_mm past its edge, so soft tissue touching the wall (the crura of the diaphragm, the
//     sinus at the root) does not widen the tube; in a crescent section the rays through the
//     crescent end at the wall anyway and the others never see contrast. The first and last
//     end_trim samples of a long path are dropped before fitting (their tangents can lie across
//     the vessel) and the extension walks on from the clean part, turning by max_turn_deg at most;
//  3. radii (median of 9 sections, less the wall) and centres smoothed along the path, then
//     capsules between consecutive sections rasterised, with a band of wall_mm along their sides
//     (kTubeWall); beyond the two ends, the grown region within the end radius of the end's axis
//     (up to four radii on) continues the tube.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace softatlas::pipeline {

struct TubeOptions {
  double stop_hu = -30;       // a ray ends where the smoothed image drops below this (fat, air)
  double bright_hu = 200;     // or where it rises above this outside the region (bone, other vessels)
  double step_mm = 2.0;       // spacing of the cross-sections along the centreline
  double max_radius_mm = 30;  // rays longer than this are cut
  int rays = 48;
  int end_trim = 5;          // centreline samples dropped at each end before fitting (paths of 8x as many or more)
  double max_turn_deg = 30;  // the ends are extended while they turn less than this
  // The rays end at the fat outside the vessel wall; the label is the lumen (TotalSegmentator's
  // aorta: the voxels just outside it read a median 95 HU on the chest crop, the wall, not fat).
  double wall_mm = 2.0;
  // A ray that has crossed contrast-filled lumen (its peak >= lumen_min_hu) ends wall_mm past the
  // lumen's edge, where the image falls to tissue_hu + edge_fraction * (peak - tissue_hu), also
  // when soft tissue rather than fat lies beyond (the crura, the root's sinus). 0 switches it off.
  double lumen_min_hu = 200;
  double tissue_hu = 60;
  double edge_fraction = 1.0 / 3;
  double lumen_edge_hu = 150;
};

struct TubeReport {
  size_t sections = 0;
  double median_radius_mm = 0;
  double length_mm = 0;
};

// dims, spacing (mm): the image grid; smooth: the smoothed image; owner: stage-1 region index per
// voxel (-1: none); self: this vessel's region; other_organ: 1 at another organ's region or a
// background click (a ray stops there and the tube does not take it); seeds: this vessel's seed
// voxels. Returns the tube mask (kTubeInside, or kTubeWall within wall_mm outside the radius
// along the sides, not past the two ends), or an empty vector when the seeds do not give a path
// (one seed, or seeds the region does not connect).
constexpr char kTubeInside = 1, kTubeWall = 2;
std::vector<char> vessel_tube(const std::array<int, 3>& dims, const double spacing[3], const std::vector<float>& smooth,
                              const std::vector<int16_t>& owner, int self, const std::vector<char>& other_organ,
                              const std::vector<size_t>& seeds, const TubeOptions& options, TubeReport* report);

}  // namespace softatlas::pipeline
