// Headless rendering of a known scene: organ colour where the organ is, background elsewhere.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>

#include "softatlas/io/ct_image.hpp"

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

// The CT on an axial slice: a set of the liver with a CT around it (HU 40 left of x = xm, 140
// right of it: grey 128 and 191 in the 400/40 window), sliced at the liver's middle and seen from
// above. On the plane outside the liver the pixels are the CT's grey, the step sits at xm (the
// world mapping), the liver's section shows its colour over the CT; without the CT the plane
// shows the background there.
TEST(Renderer, AxialSliceShowsTheCtGreyOnThePlaneAndTheSectionOverIt) {
  const io::OrganSet atlas = io::read_organ_set(test::atlas_dir());
  io::OrganSet set;
  set.organs = {*atlas.find("liver")};
  set.organs[0].regions.clear();
  double lo[3] = {1e9, 1e9, 1e9}, hi[3] = {-1e9, -1e9, -1e9}, c[3] = {0, 0, 0};
  const auto& V = set.organs[0].mesh.vertices;
  for (size_t i = 0; i < V.size(); ++i) {
    lo[i % 3] = std::min(lo[i % 3], V[i]);
    hi[i % 3] = std::max(hi[i % 3], V[i]);
    c[i % 3] += V[i] / (V.size() / 3);
  }
  const double xm = 0.5 * (lo[0] + hi[0]), zm = c[2];
  io::CtImage ct;
  for (int d = 0; d < 3; ++d) ct.dims[d] = static_cast<int>((hi[d] - lo[d] + 40) / 2) + 1;
  ct.ijk_to_ras = {2, 0, 0, lo[0] - 20, 0, 2, 0, lo[1] - 20, 0, 0, 2, lo[2] - 20, 0, 0, 0, 1};
  for (int k = 0; k < ct.dims[2]; ++k)
    for (int j = 0; j < ct.dims[1]; ++j)
      for (int i = 0; i < ct.dims[0]; ++i) ct.hu.push_back(static_cast<int16_t>(ct.world(i, j, k)[0] < xm ? 40 : 140));
  set.ct = io::CtRecord{"ct.nii.gz", 400, 40};
  const std::string dir = test::scratch("ct_slice") + "/set";
  io::write_organ_set(set, dir, {{"ct.nii.gz", io::encode_ct_nifti_gz(ct)}});
  const io::OrganSet with_ct = io::read_organ_set(dir);
  ASSERT_TRUE(with_ct.ct.has_value());
  io::OrganSet without_ct = with_ct;
  without_ct.ct.reset();

  auto render = [&](const io::OrganSet& s, Camera* cam) {
    AtlasScene scene(s, {"liver"}, {}, PhysicsSettings{});
    auto ctx = make_osmesa_context(320, 240);
    Viewer viewer(*ctx, scene);
    viewer.cues.grid = false;
    viewer.cues.axes = false;
    viewer.camera.set_view("superior");
    viewer.frame_all();
    viewer.slice = SlicePlane{2, static_cast<float>(zm), true};
    viewer.render();
    *cam = viewer.camera;
    if (&s == &with_ct) viewer.save_png(test::scratch("ct_slice_png") + "/axial.png");
    return viewer.screenshot();
  };
  Camera cam;
  const std::vector<uint8_t> px = render(with_ct, &cam);
  auto pixel = [&](const std::vector<uint8_t>& img, double x, double y) {
    float fx = 0, fy = 0;
    EXPECT_TRUE(cam.project(Eigen::Vector3f(x, y, zm), fx, fy));
    const int ix = std::clamp(static_cast<int>(fx), 0, 319), iy = std::clamp(static_cast<int>(fy), 0, 239);
    const uint8_t* p = &img[(static_cast<size_t>(iy) * 320 + ix) * 4];
    return std::array<int, 4>{p[0], p[1], p[2], p[3]};
  };
  auto expect_grey = [&](std::array<int, 4> p, int level, const char* where) {
    EXPECT_NEAR(p[0], level, 3) << where;
    EXPECT_NEAR(p[1], level, 3) << where;
    EXPECT_NEAR(p[2], level, 3) << where;
    EXPECT_EQ(p[3], 255) << where;
  };
  // In the CT's 20 mm margin outside the liver (front corners of the box), both sides of xm.
  const double y_out = lo[1] - 12;
  expect_grey(pixel(px, lo[0] - 12, y_out), 128, "left of xm");
  expect_grey(pixel(px, hi[0] + 12, y_out), 191, "right of xm");
  expect_grey(pixel(px, xm - 5, y_out), 128, "5 mm left of the step");
  expect_grey(pixel(px, xm + 5, y_out), 191, "5 mm right of the step");
  // The section: the liver's colour over the CT (red above blue), not a grey.
  const auto cap = pixel(px, c[0], c[1]);
  EXPECT_GT(cap[0] - cap[2], 25) << cap[0] << " " << cap[1] << " " << cap[2];
  // Without the CT the plane shows the background there.
  const std::vector<uint8_t> none = render(without_ct, &cam);
  const auto bg = pixel(none, lo[0] - 12, y_out);
  EXPECT_NEAR(bg[0], 26, 3);
  EXPECT_NEAR(bg[2], 33, 3);
}

// A label sits on what the slice keeps: the kept part's centroid, and no label at all when the
// slice removes the whole organ (sectional views named organs that were no longer drawn).
TEST(Renderer, LabelAnchorFollowsTheSliceAndVanishesWithTheOrgan) {
  const io::OrganSet set = io::read_organ_set(test::atlas_dir());
  AtlasScene scene(set, {"liver"}, {}, PhysicsSettings{});
  auto ctx = make_osmesa_context(64, 48);
  Viewer viewer(*ctx, scene);
  const auto& V = set.find("liver")->mesh.vertices;
  float zlo = 1e9f, zhi = -1e9f;
  for (size_t i = 2; i < V.size(); i += 3)
    zlo = std::min(zlo, static_cast<float>(V[i])), zhi = std::max(zhi, static_cast<float>(V[i]));
  Eigen::Vector3f whole, kept;
  ASSERT_TRUE(viewer.label_anchor(0, whole));
  const float zm = 0.5f * (zlo + zhi);
  viewer.slice = SlicePlane{2, zm, true};  // keeps z < zm
  ASSERT_TRUE(viewer.label_anchor(0, kept));
  EXPECT_LT(kept.z(), zm);
  EXPECT_LT(kept.z(), whole.z());
  viewer.slice = SlicePlane{2, zlo - 1.0f, true};  // everything lies above the plane: cut away
  EXPECT_FALSE(viewer.label_anchor(0, kept));
  viewer.slice = SlicePlane{2, zlo - 1.0f, false};  // keeps z > the plane: all of it
  ASSERT_TRUE(viewer.label_anchor(0, kept));
  EXPECT_NEAR((kept - whole).norm(), 0.0f, 1e-3f);
}

}  // namespace
}  // namespace softatlas::app
