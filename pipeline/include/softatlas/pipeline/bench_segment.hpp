// The fair evaluation of the seeded segmentation (`softatlas bench segment`): fixed random draws
// of interior seeds per organ and background points, no corrections, on the shared CTs and on
// stress variants made from them (resampled to 3 mm, enhancement removed, noise added).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "softatlas/pipeline/segment.hpp"
#include "softatlas/pipeline/volume.hpp"

namespace CLI {
class App;
}
namespace softatlas::cli {
struct Status;
}

namespace softatlas::pipeline {

struct EvalOrgan {
  std::string name;
  int id;  // TotalSegmentator id, in both the reference and the result
};

// One CT with its reference label map on the CT's grid and the organs that are seeded.
struct EvalCase {
  std::string name;     // slab | heart_crop | aorta_crop
  std::string variant;  // original | 3mm | unenhanced | noise | unenhanced_3mm
  Volume ct, ref;
  std::vector<EvalOrgan> organs;
};

// The shared cases, from data_dir (the shared data folder holding ct/): "slab" (abdomen DICOM
// slab: liver, spleen, stomach, pancreas, aorta), "heart_crop" (heart, aorta), "aorta_crop"
// (aorta, heart).
EvalCase load_eval_case(const std::string& data_dir, const std::string& name);

// The stress variants: "original"; "3mm" (isotropic 3 mm voxels: the CT blurred to 3 mm slices
// and resampled, labels nearest); "unenhanced" (each enhanced organ's voxels set to its
// unenhanced HU plus the voxel's own noise: liver 50, spleen 45, pancreas/vessels/heart 40,
// kidneys 30; edges blended over a voxel); "noise" (white Gaussian noise of 40 HU added, fixed
// seed); "unenhanced_3mm" (both). Deterministic.
EvalCase make_variant(const EvalCase& c, const std::string& variant);
const std::vector<std::string>& stress_variants();

// One draw of the protocol: per organ `per_organ` random voxels of its reference label eroded by
// 3 mm (the deeper half of the label when nothing is 3 mm deep), and `background` random voxels
// with label 0, CT value -500..300 HU, at least 3 voxels from every seeded organ. Same `seed`,
// same points (own generator arithmetic, not std::uniform_int_distribution).
Seeds draw_seeds(const EvalCase& c, uint64_t seed, int per_organ = 5, int background = 10);

// Seed of draw number `draw` (0-based) of the bench.
uint64_t draw_seed(int draw);

struct EvalRun {
  std::vector<double> dice, volume_ratio;  // per organ of the case, in order
  double seconds = 0;
};
EvalRun run_draw(const EvalCase& c, uint64_t seed, const SegmentOptions& options = SegmentOptions{});

// Binary masks (files) resampled (nearest voxel centre) onto `grid` as one label map with the
// given ids; the first mask wins where they overlap.
Volume masks_on_grid(const Volume& grid, const std::vector<std::pair<std::string, int>>& masks);

// Resamples a volume onto dims `to` covering the same world extent (voxel corners): trilinear for
// the CT, nearest for label maps.
Volume resample(const Volume& v, const std::array<int, 3>& to, bool nearest);

// `softatlas bench segment [--data DIR] [--cases a,b] [--variants a,b] [--draws N] [--json]
//  [--write-variants DIR]`: registered on the `bench` group of the one command line.
void add_bench_segment(CLI::App& bench, cli::Status* status);

}  // namespace softatlas::pipeline
