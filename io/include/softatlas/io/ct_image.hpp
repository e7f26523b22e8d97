// The CT an organ set was built from (SET/ct.nii.gz, docs/organ-set.md): the pipeline writes it
// cropped to the organs, as int16 Hounsfield units with its voxel-to-RAS-mm transform as the NIfTI
// sform; the viewer draws it on the slice plane.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace softatlas::io {

struct CtImage {
  std::array<int, 3> dims{0, 0, 0};
  std::vector<int16_t> hu;  // dims[0]*dims[1]*dims[2], i fastest
  // Row-major 4x4: voxel (i, j, k) -> RAS mm, as the NIfTI sform maps it (pipeline::Volume's).
  std::array<double, 16> ijk_to_ras{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};

  std::array<double, 3> world(double i, double j, double k) const;
  std::array<double, 3> voxel(const std::array<double, 3>& ras) const;  // continuous indices
  // Trilinear HU at a world point; false outside the grid (beyond the outer voxel centres).
  bool sample(const std::array<double, 3>& ras, float* hu_out) const;
  std::array<double, 6> world_bounds() const;  // min xyz, max xyz of the voxel centres
};

// NIfTI-1 (.nii.gz) bytes: int16, sform_code 1, qform unset, gzip.
std::string encode_ct_nifti_gz(const CtImage& ct);

// Reads a 3-D NIfTI-1 CT (.nii or .nii.gz; int16, uint8, int32 or float32; sform, else qform;
// scl_slope applied, values rounded and clamped to int16). header_only: checks the header and
// the length and leaves hu empty. Errors are InputError naming the file (and the field).
CtImage read_ct_nifti(const std::string& path, bool header_only = false);

}  // namespace softatlas::io
