// Stage 1, read: CT volumes and label maps with their full image-to-world transform.
#pragma once

#include <array>
#include <map>
#include <cstdint>
#include <string>
#include <vector>

namespace softatlas::pipeline {

// A scalar volume on a regular grid. values has dims[0]*dims[1]*dims[2] entries, i fastest.
// ijk_to_ras (row-major 4x4) maps voxel indices to world millimetres in RAS, exactly as the
// NIfTI sform (or qform) maps them, as 3D Slicer shows them.
struct Volume {
  std::array<int, 3> dims{0, 0, 0};
  std::vector<float> values;
  std::array<double, 16> ijk_to_ras{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  std::string path;
  std::string format;  // nifti | nrrd | metaimage | dicom
  // Label value -> name, from a NIfTI header extension holding a Caret/CIFTI <LabelTable> (as
  // TotalSegmentator writes its multi-label maps); empty when the file has none.
  std::map<int, std::string> label_names;

  size_t voxel_count() const { return values.size(); }
  size_t index(int i, int j, int k) const {
    return static_cast<size_t>(i) +
           static_cast<size_t>(dims[0]) * (static_cast<size_t>(j) + static_cast<size_t>(dims[1]) * k);
  }
  std::array<double, 3> world(double i, double j, double k) const;
  // Inverse map (continuous voxel indices of a world point).
  std::array<double, 3> voxel(const std::array<double, 3>& ras) const;
  // |det| of the 3x3 part: one voxel's volume in mm^3.
  double voxel_volume_mm3() const;
  // Axis-aligned world bounding box of the voxel centres: min xyz, max xyz.
  std::array<double, 6> world_bounds() const;
};

// Reads NIfTI (.nii, .nii.gz), NRRD (.nrrd, .nhdr), MetaImage (.mha, .mhd) or a DICOM series
// (a folder, or one file of the series: every slice in that folder is read, sorted by
// ImagePositionPatient; JPEG 2000 through GDCM; LPS -> RAS). Rescale slope/intercept applied.
// Throws InputError naming the path for missing, truncated, corrupt or unsupported input.
Volume read_volume(const std::string& path);

// Writes a label volume as NIfTI (.nii or .nii.gz, uint8 if all values fit, else int16) with the
// volume's ijk_to_ras as sform (qform unset). Atomic (temp file + rename). A label map on a NIfTI
// CT's grid keeps the CT's index order (read_volume does not reorder NIfTI voxels, qfac = -1
// included).
void write_label_nifti(const Volume& labels, const std::string& path);

// SHA-256 of a file (or of every file of a folder, in name order), lowercase hex.
std::string sha256_file(const std::string& path);

}  // namespace softatlas::pipeline
