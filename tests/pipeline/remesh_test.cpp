// Stage 4 (repair + remesh): budgets, closedness, angles, Hausdorff; BodyParts3D liver with
// holes repaired; budgets below a closed surface rejected.
#include <gtest/gtest.h>

#include <cmath>

#include "softatlas/pipeline/remesh.hpp"
#include "softatlas/pipeline/surface.hpp"
#include "softatlas/pipeline/topology.hpp"
#include "softatlas/sim/error.hpp"
#include "softatlas/sim/geometry.hpp"
#include "test_util.hpp"

namespace softatlas::pipeline {
namespace {
using test::chest;

void expect_contract(const io::TriMesh& m, int budget) {
  const SurfaceReport r = inspect_surface(m);
  EXPECT_NEAR(static_cast<double>(r.faces), budget, 0.02 * budget);
  EXPECT_TRUE(r.closed());
  EXPECT_TRUE(r.edge_manifold());
  EXPECT_TRUE(r.oriented());
  EXPECT_GT(r.signed_volume_mm3, 0.0);
  EXPECT_GE(r.share_angle_ge_20, 0.99);
}

TEST(Remesh, PulmonaryArteryToBudget) {
  const Volume pa = read_volume(chest("pulmonary_artery.nii.gz"));
  const SurfaceResult s = label_surface(pa, {1}, SurfaceOptions{}, "pa");
  for (int budget : {1500, 600}) {
    RemeshOptions o;
    o.face_budget = budget;
    const RemeshResult r = repair_and_remesh(s.mesh, o, "pa");
    expect_contract(r.mesh, budget);
    EXPECT_FALSE(r.self_intersections);
    EXPECT_GT(r.hausdorff_mm, 0.0);
    EXPECT_LT(r.hausdorff_mm, 5.0);
    EXPECT_LT(r.mean_distance_mm, 0.5);
    // sim's enclosed_volume, independent of the report's own volume.
    const double v = softatlas::sim::enclosed_volume(r.mesh.vertices, r.mesh.faces);
    EXPECT_NEAR(v / s.mask_volume_mm3, 1.0, 0.15);
  }
}

TEST(Remesh, BodyParts3dLiverHolesAreRepaired) {
  const io::TriMesh liver = io::read_mesh(test::shared("meshes/bodyparts3d/FMA7197_Liver.obj"));
  const SurfaceReport in = inspect_surface(liver);
  EXPECT_EQ(in.boundary_edges, 70u);  // README: 70 boundary edges
  RemeshOptions o;
  o.face_budget = 3000;
  const RemeshResult r = repair_and_remesh(liver, o, "liver.obj");
  expect_contract(r.mesh, 3000);
  // The 70 boundary edges were closed by stitching cracks and/or filling holes (reported).
  bool repaired = false;
  std::string all;
  for (const auto& s : r.repairs) {
    repaired |= s.rfind("holes_filled", 0) == 0 || s.rfind("stitched", 0) == 0 || s.rfind("soup_repair", 0) == 0;
    all += s + " ";
  }
  EXPECT_TRUE(repaired) << all;
  // README: about 1.56 L.
  EXPECT_NEAR(softatlas::sim::enclosed_volume(r.mesh.vertices, r.mesh.faces) / 1e6, 1.56, 0.1);
}

TEST(Remesh, BudgetBelowAClosedSurfaceIsRejected) {
  const Volume pa = read_volume(chest("pulmonary_artery.nii.gz"));
  const SurfaceResult s = label_surface(pa, {1}, SurfaceOptions{}, "pa");
  RemeshOptions o;
  o.face_budget = 3;
  EXPECT_THROW(repair_and_remesh(s.mesh, o, "pa"), InputError);
}

}  // namespace
}  // namespace softatlas::pipeline
