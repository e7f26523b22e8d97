// Headless rendering of a known scene: organ colour where the organ is, background elsewhere.
#include <gtest/gtest.h>

#include <cmath>

#include "softatlas/app/viewer.hpp"
#include "test_util.hpp"

namespace softatlas::app {
namespace {

TEST(Renderer, HeadlessLiverPixelsHaveItsColourAndTheBackgroundIsClear) {
  const io::OrganSet set = io::read_organ_set(test::atlas_dir());
  AtlasScene scene(set, {"liver"}, {}, PhysicsSettings{});
  auto ctx = make_osmesa_context(320, 240);
  EXPECT_NE(ctx->describe().find("Core Profile"), std::string::npos) << ctx->describe();
  Viewer viewer(*ctx, scene);
  viewer.cues.grid = false;
  viewer.cues.axes = false;
  viewer.camera.set_view("anterior");
  viewer.frame_all();
  viewer.render();
  const std::vector<uint8_t> px = viewer.screenshot();
  ASSERT_EQ(px.size(), 320u * 240u * 4u);
  auto at = [&](int x, int y) { return &px[(static_cast<size_t>(y) * 320 + x) * 4]; };
  // Background: the clear colour, exactly, in every corner.
  const auto& bg = viewer.cues.background;
  for (auto [x, y] : {std::pair{1, 1}, {318, 1}, {1, 238}, {318, 238}}) {
    EXPECT_NEAR(at(x, y)[0], std::lround(bg[0] * 255), 1);
    EXPECT_NEAR(at(x, y)[1], std::lround(bg[1] * 255), 1);
    EXPECT_NEAR(at(x, y)[2], std::lround(bg[2] * 255), 1);
  }
  // The liver's centroid projects onto the liver: its pixel is a shade of the liver colour
  // (Lambert shading scales all channels; the specular term adds a little white).
  const auto c = set.find("liver")->color;
  Eigen::Vector3f centroid(0, 0, 0);
  const auto& V = set.find("liver")->mesh.vertices;
  for (size_t i = 0; i < V.size(); i += 3) centroid += Eigen::Vector3f(V[i], V[i + 1], V[i + 2]);
  centroid /= static_cast<float>(V.size() / 3);
  float fx, fy;
  ASSERT_TRUE(viewer.camera.project(centroid, fx, fy));
  const uint8_t* p = at(static_cast<int>(fx), static_cast<int>(fy));
  const double r = p[0], g = p[1], b = p[2];
  EXPECT_GT(r, 60);
  // Hue: the ratios of the organ colour (0.62, 0.24, 0.19) within a tolerance for specular.
  EXPECT_NEAR(g / r, c[1] / c[0], 0.12);
  EXPECT_NEAR(b / r, c[2] / c[0], 0.12);
  // Coverage: a liver of ~20 cm framed in 240 px fills a large part of the picture.
  size_t organ_pixels = 0;
  for (size_t i = 0; i < px.size(); i += 4)
    if (std::abs(px[i] - std::lround(bg[0] * 255)) > 3) ++organ_pixels;
  EXPECT_GT(organ_pixels, 320u * 240u / 8);
  // Hidden organs are not drawn.
  viewer.styles[0].visible = false;
  viewer.render();
  const std::vector<uint8_t> empty = viewer.screenshot();
  const uint8_t* q = &empty[(static_cast<size_t>(fy) * 320 + static_cast<size_t>(fx)) * 4];
  EXPECT_NEAR(q[0], std::lround(bg[0] * 255), 1);
}

TEST(Renderer, WritesAReadablePng) {
  const io::OrganSet set = io::read_organ_set(test::atlas_dir());
  AtlasScene scene(set, {"kidney_left"}, {}, PhysicsSettings{});
  auto ctx = make_osmesa_context(64, 48);
  Viewer viewer(*ctx, scene);
  viewer.render();
  const std::string path = test::scratch("png") + "/k.png";
  viewer.save_png(path);
  std::FILE* f = std::fopen(path.c_str(), "rb");
  ASSERT_NE(f, nullptr);
  unsigned char sig[8];
  ASSERT_EQ(std::fread(sig, 1, 8, f), 8u);
  std::fclose(f);
  EXPECT_EQ(sig[1], 'P');
  EXPECT_EQ(sig[2], 'N');
  EXPECT_EQ(sig[3], 'G');
  EXPECT_THROW(write_png("/nonexistent-dir/x.png", 2, 2, std::vector<uint8_t>(16)), std::runtime_error);
}

}  // namespace
}  // namespace softatlas::app
