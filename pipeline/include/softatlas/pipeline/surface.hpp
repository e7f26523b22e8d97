// Stage 3, surface (VTK): label mask -> discrete flying edges -> windowed-sinc smoothing ->
// specks removed -> outward orientation, in world RAS millimetres.
#pragma once

#include <string>
#include <vector>

#include "softatlas/io/mesh_io.hpp"
#include "softatlas/pipeline/volume.hpp"

namespace softatlas::pipeline {

struct SurfaceOptions {
  int smoothing_iterations = 20;  // vtkWindowedSincPolyDataFilter
  double smoothing_passband = 0.05;
  double speck_share = 0.01;        // components under this share of the organ volume are specks
  double large_piece_share = 0.10;  // pieces above this share count as real pieces (reported)
};

struct SurfaceResult {
  io::TriMesh mesh;  // closed pieces, outward, RAS mm
  size_t mask_voxels = 0;
  double mask_volume_mm3 = 0.0;
  int pieces_kept = 0;
  int large_pieces = 0;  // > large_piece_share of the volume
  int specks_removed = 0;
  double specks_volume_mm3 = 0.0;
};

// Surface of the voxels whose value is in `values` (rounded). Throws InputError naming `where`
// (file + organ) if the label is empty.
SurfaceResult label_surface(const Volume& labels, const std::vector<int>& values, const SurfaceOptions& options,
                            const std::string& where);

}  // namespace softatlas::pipeline
