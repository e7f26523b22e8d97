// Stage 3 (surface): the world-coordinate test of the issue (heart on its own larger grid vs
// cropped to the CT grid), volumes against voxel counts, orientation, empty labels.
#include <gtest/gtest.h>

#include <cmath>

#include "softatlas/pipeline/surface.hpp"
#include "softatlas/pipeline/topology.hpp"
#include "softatlas/sim/error.hpp"
#include "test_util.hpp"

namespace softatlas::pipeline {
namespace {
using test::chest;

TEST(Surface, SameHeartSurfaceFromBothGridsWithin0p01mm) {
  const Volume big = read_volume(chest("heart.nii.gz"));
  const Volume crop = read_volume(chest("heart_on_ct_heart_crop_grid.nii.gz"));
  const SurfaceResult a = label_surface(big, {1}, SurfaceOptions{}, "heart.nii.gz");
  const SurfaceResult b = label_surface(crop, {1}, SurfaceOptions{}, "heart_on_grid");
  ASSERT_EQ(a.mesh.vertex_count(), b.mesh.vertex_count());
  ASSERT_EQ(a.mesh.faces, b.mesh.faces);
  double worst = 0;
  for (size_t i = 0; i < a.mesh.vertices.size(); ++i)
    worst = std::max(worst, std::abs(a.mesh.vertices[i] - b.mesh.vertices[i]));
  EXPECT_LT(worst, 0.01);
  // The surface lies where the label is: its bounding box is the voxel box +- half a voxel.
  double lo[3] = {1e9, 1e9, 1e9}, hi[3] = {-1e9, -1e9, -1e9};
  for (size_t v = 0; v < b.mesh.vertex_count(); ++v)
    for (int d = 0; d < 3; ++d) {
      lo[d] = std::min(lo[d], b.mesh.vertices[3 * v + d]);
      hi[d] = std::max(hi[d], b.mesh.vertices[3 * v + d]);
    }
  double vlo[3] = {1e9, 1e9, 1e9}, vhi[3] = {-1e9, -1e9, -1e9};
  for (int k = 0; k < crop.dims[2]; ++k)
    for (int j = 0; j < crop.dims[1]; ++j)
      for (int i = 0; i < crop.dims[0]; ++i)
        if (crop.values[crop.index(i, j, k)] != 0) {
          const auto w = crop.world(i, j, k);
          for (int d = 0; d < 3; ++d) vlo[d] = std::min(vlo[d], w[d]), vhi[d] = std::max(vhi[d], w[d]);
        }
  for (int d = 0; d < 3; ++d) {
    EXPECT_NEAR(lo[d], vlo[d], 1.5);
    EXPECT_NEAR(hi[d], vhi[d], 1.5);
  }
}

TEST(Surface, ClosedOutwardAndVolumeNearTheVoxelVolume) {
  const Volume pa = read_volume(chest("pulmonary_artery.nii.gz"));
  const SurfaceResult s = label_surface(pa, {1}, SurfaceOptions{}, "pa");
  const SurfaceReport r = inspect_surface(s.mesh);
  EXPECT_EQ(r.boundary_edges, 0u);
  EXPECT_TRUE(r.oriented());
  EXPECT_GT(r.signed_volume_mm3, 0.0);
  // Voxel volume counted independently here.
  size_t n = 0;
  for (float x : pa.values) n += x == 1.0f;
  EXPECT_EQ(s.mask_voxels, n);
  EXPECT_NEAR(r.signed_volume_mm3 / (n * 3.375), 1.0, 0.15);
}

TEST(Surface, EmptyLabelNamesTheSource) {
  const Volume pa = read_volume(chest("pulmonary_artery.nii.gz"));
  try {
    label_surface(pa, {5}, SurfaceOptions{}, "pa.nii.gz: liver");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("pa.nii.gz: liver"), std::string::npos);
  }
}

}  // namespace
}  // namespace softatlas::pipeline
