// The app's scene: mm -> m conversion, and only the organs a view shows (plus those connected
// to them) are simulated.
#include <gtest/gtest.h>

#include "softatlas/app/scene.hpp"
#include "softatlas/sim/error.hpp"
#include "test_util.hpp"

namespace softatlas::app {
namespace {

TEST(Scene, ConvertsMillimetresToMetresAndBack) {
  const io::OrganSet set = io::read_organ_set(test::atlas_dir());
  AtlasScene scene(set, {"kidney_left"}, {}, PhysicsSettings{});
  ASSERT_EQ(scene.model.organs.size(), 1u);
  const auto& V = set.find("kidney_left")->mesh.vertices;
  const auto& r = scene.model.organs[0];
  for (int32_t g = r.vert_begin; g < r.vert_end; g += 97) {
    const size_t local = static_cast<size_t>(scene.model.vert_source[static_cast<size_t>(g)]);
    EXPECT_DOUBLE_EQ(scene.model.vert_rest_x[static_cast<size_t>(g)], V[3 * local] * 1e-3);
    EXPECT_DOUBLE_EQ(scene.model.vert_rest_z[static_cast<size_t>(g)], V[3 * local + 2] * 1e-3);
  }
  std::vector<float> p;
  scene.positions_mm(0, p);
  ASSERT_EQ(p.size(), V.size());
  for (size_t i = 0; i < V.size(); i += 301) EXPECT_NEAR(p[i], V[i], 1e-3);
  EXPECT_DOUBLE_EQ(scene.mean_displacement_mm(scene.global_vertices(0, {0, 1, 2})), 0.0);
}

TEST(Scene, SimulatesShownOrgansAndContextOrgansOnlyWhenConnected) {
  const io::OrganSet set = io::read_organ_set(test::atlas_dir());
  // kidney_right is connected to the liver (connections.csv): simulated although only context.
  AtlasScene a(set, {"liver"}, {"kidney_right"}, PhysicsSettings{});
  EXPECT_GE(a.model_organ(a.view_index("liver")), 0);
  EXPECT_GE(a.model_organ(a.view_index("kidney_right")), 0);
  EXPECT_TRUE(a.is_context(a.view_index("kidney_right")));
  EXPECT_EQ(a.view_index("spleen"), -1);  // in neither list: not in the view at all
  // kidney_left is not connected to the liver: drawn (at rest) but not simulated.
  AtlasScene b(set, {"liver"}, {"kidney_left"}, PhysicsSettings{});
  EXPECT_EQ(b.model.organs.size(), 1u);
  EXPECT_EQ(b.model_organ(b.view_index("kidney_left")), -1);
  std::vector<float> rest;
  b.positions_mm(b.view_index("kidney_left"), rest);
  EXPECT_EQ(rest.size(), set.find("kidney_left")->mesh.vertices.size());
  EXPECT_THROW(AtlasScene(set, {"stomach"}, {}, PhysicsSettings{}), InputError);  // not in the set
}

TEST(Scene, RegionsAreThePatientsDirections) {
  const io::OrganSet set = io::read_organ_set(test::atlas_dir());
  AtlasScene scene(set, {"liver"}, {}, PhysicsSettings{});
  const auto& V = set.find("liver")->mesh.vertices;
  auto mean_z = [&](const std::vector<int32_t>& ids) {
    double z = 0;
    for (int32_t i : ids) z += V[3 * static_cast<size_t>(i) + 2];
    return z / static_cast<double>(ids.size());
  };
  const auto inferior = scene.region_vertices(0, "inferior", 12.0);
  const auto superior = scene.region_vertices(0, "superior", 12.0);
  ASSERT_FALSE(inferior.empty());
  ASSERT_FALSE(superior.empty());
  EXPECT_LT(mean_z(inferior) + 100.0, mean_z(superior));  // the liver is ~17 cm tall
  EXPECT_TRUE(scene.region_vertices(0, "middle", 12.0).empty());
}

}  // namespace
}  // namespace softatlas::app

namespace softatlas::app {
namespace {

TEST(OrganInfo, DisplayNamesAndSystems) {
  EXPECT_EQ(organ_info("kidney_right").display, "Right kidney");
  EXPECT_EQ(organ_info("kidney_right").system, "urinary");
  EXPECT_EQ(organ_info("liver").system, "digestive");
  EXPECT_EQ(organ_info("vertebrae_L5").system, "skeletal");
  // Unknown names stay readable.
  EXPECT_EQ(organ_info("left_thing_2").display, "Left thing 2");
  EXPECT_EQ(organ_info("left_thing_2").system, "other");
}

}  // namespace
}  // namespace softatlas::app
