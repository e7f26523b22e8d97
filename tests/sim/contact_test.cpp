// Contact between organs (sim/contact.hpp): a sphere pushed into another stays out of it, organs
// overlapping at rest stay at rest, a held patch driven deep stops at the neighbour, a vertex pushed through is let go and comes back,
// contact can be turned off.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "solid_helpers.hpp"

namespace softatlas {
namespace {

// Two solid spheres of radius 20 mm, centres `gap_m` + 40 mm apart along x; the left one's
// leftmost 10 mm held by the tool and pushed `push_m` toward the right one over 0.5 s.
struct Pushed {
  double penetration_m = 0.0, right_moved_m = 0.0;
  int contacts = 0;
  bool finite = true;
};

sim::SceneDesc two_spheres(double gap_m, bool contact) {
  sim::SceneDesc s;
  for (int i = 0; i < 2; ++i) {
    test::Mesh m = test::icosphere(3, 0.02);
    for (size_t v = 0; v < m.V.size(); v += 3) m.V[v] += i * (0.04 + gap_m);
    sim::OrganDesc o = test::organ(i == 0 ? "left" : "right", m);
    o.material.model = sim::ModelKind::solid;
    o.material.young_modulus_pa = 4000.0;
    s.organs.push_back(o);
  }
  // the right sphere held at its far side (x > its centre + 15 mm)
  sim::OrganDesc& r = s.organs[1];
  r.fixed.clear();
  for (size_t v = 0; v < r.vertices.size() / 3; ++v)
    if (r.vertices[3 * v] > 0.04 + gap_m + 0.015) r.fixed.push_back(static_cast<int32_t>(v));
  s.integrator = sim::Integrator::implicit;
  s.dt_s = 8e-3;
  s.allow_sleep = false;
  s.contact = contact;
  return s;
}

// The left sphere's vertices within 10 mm of its extreme point along dir, as global indices.
std::vector<int32_t> left_patch(const sim::SceneDesc& scene, const sim::Model& m, const std::array<double, 3>& dir) {
  std::vector<int32_t> out;
  for (int32_t v : solid_test::region(scene.organs[0], dir, 0.01)) out.push_back(sim::global_vertex(m, 0, v));
  return out;
}

Pushed push(const sim::SceneDesc& scene, const sim::Model& measure, double push_m, int steps = 125) {
  const sim::Model m = sim::compile(scene);
  sim::State s = sim::make_state(m);
  sim::Work w = sim::make_work(m);
  const std::vector<int32_t> held = left_patch(scene, m, {-1, 0, 0});
  sim::attach(m, s, held, {push_m, 0, 0}, 60);
  Pushed out;
  for (int i = 0; i < steps; ++i) {
    const sim::StepReport r = sim::step(m, s, w);
    out.contacts = std::max(out.contacts, r.contacts);
    if (i % 5 == 4) out.penetration_m = std::max(out.penetration_m, sim::max_penetration(measure, s));
  }
  const int32_t right = sim::find_organ(m, "right");
  for (int32_t v = m.organs[right].vert_begin; v < m.organs[right].vert_end; ++v) {
    out.finite = out.finite && std::isfinite(s.x[v]);
    out.right_moved_m = std::max(out.right_moved_m, std::abs(s.x[v] - m.vert_rest_x[v]));
  }
  return out;
}

TEST(Contact, PushedSphereStaysOutOfItsNeighbour) {
  const sim::SceneDesc on = two_spheres(0.002, true);
  const sim::Model measure = sim::compile(on);
  ASSERT_TRUE(measure.contact.on);
  const Pushed with = push(on, measure, 0.015);
  const Pushed without = push(two_spheres(0.002, false), measure, 0.015);
  EXPECT_TRUE(with.finite);
  EXPECT_GT(without.penetration_m, 0.008);  // without contact the left sphere enters the right
  EXPECT_LT(with.penetration_m, 1e-3);
  EXPECT_GT(with.contacts, 0);
  EXPECT_GT(with.right_moved_m, 0.002);  // the right sphere was pushed, not passed through
  EXPECT_EQ(without.contacts, 0);
}

TEST(Contact, OrgansOverlappingAtRestStayAtRest) {
  // 3 mm overlap at rest (surfaces from a label map overlap by a voxel or two)
  const sim::SceneDesc scene = two_spheres(-0.003, true);
  const sim::Model m = sim::compile(scene);
  int inside = 0;
  for (uint8_t f : m.contact.rest_inside) inside += f;
  EXPECT_GT(inside, 0);
  sim::State s = sim::make_state(m);
  sim::Work w = sim::make_work(m);
  for (int i = 0; i < 100; ++i) {
    const sim::StepReport r = sim::step(m, s, w);
    EXPECT_EQ(r.contacts, 0);
  }
  EXPECT_LT(sim::max_displacement(m, s), 1e-6);
  EXPECT_DOUBLE_EQ(sim::max_penetration(m, s), 0.0);  // the rest overlap is not counted
}

// The left sphere anchored at its top, so that it has a rest to return to.
sim::SceneDesc anchored_spheres() {
  sim::SceneDesc scene = two_spheres(0.002, true);
  sim::OrganDesc& left = scene.organs[0];
  for (size_t v = 0; v < left.vertices.size() / 3; ++v)
    if (left.vertices[3 * v + 1] > 0.016) left.fixed.push_back(static_cast<int32_t>(v));
  return scene;
}

TEST(Contact, HeldPatchDrivenDeepStopsAtTheNeighbour) {
  // the tool's target 25 mm away, 23 mm into the right sphere: the hold stops at the
  // right sphere's surface (a proxy, contact.cpp follow_contact) and follows the device back out
  const sim::SceneDesc scene = anchored_spheres();
  const sim::Model m = sim::compile(scene);
  sim::State s = sim::make_state(m);
  sim::Work w = sim::make_work(m);
  const std::vector<int32_t> held = left_patch(scene, m, {-1, 0, 0});
  sim::attach(m, s, held, {0.025, 0, 0}, 60);
  double deepest = 0.0;
  for (int i = 0; i < 120; ++i) {
    sim::step(m, s, w);
    if (i % 5 == 4) deepest = std::max(deepest, sim::max_penetration(m, s));
  }
  EXPECT_LT(deepest, 1e-3);
  sim::move_attachment(s, {0.0, 0, 0});  // the device back where it grasped
  for (int i = 0; i < 400; ++i) sim::step(m, s, w);
  EXPECT_LT(std::abs(s.tool.contact_shift[0]), 1e-9);  // the hold is back on the device
  sim::release(s);
  for (int i = 0; i < 300; ++i) sim::step(m, s, w);
  EXPECT_LT(sim::max_displacement(m, s), 5e-4);
}

TEST(Contact, VertexPushedThroughIsLetGoAndComesBack) {
  // 5 N on the left sphere's near side, far past what contact holds: its vertices get deeper than
  // the contact depth and through the right sphere's near half. They are let go; after release the
  // left sphere returns to its rest shape instead of being caught on the far side (a vertex let go
  // stays let go while its straight way home crosses the right sphere).
  const sim::SceneDesc scene = anchored_spheres();
  const sim::Model m = sim::compile(scene);
  sim::State s = sim::make_state(m);
  sim::Work w = sim::make_work(m);
  const std::vector<int32_t> pushed = left_patch(scene, m, {1, 0, 0});
  sim::pull_force(m, s, pushed, {5.0, 0, 0});
  int let_go = 0;
  double deepest = 0.0;
  for (int i = 0; i < 60; ++i) {
    sim::step(m, s, w);
    for (uint8_t f : s.contact_let_go) let_go += f;
    deepest = std::max(deepest, sim::max_penetration(m, s));
  }
  std::printf("pushed with 5 N: %d let-go vertex-steps, %.1f mm deep\n", let_go, 1e3 * deepest);
  EXPECT_GT(let_go, 0);
  EXPECT_GT(deepest, 3e-3);  // deeper than the contact depth: the case under test happened
  sim::release(s);
  // the vertices that went through hold the sphere on the far side for a while (2-4 s at 5 N):
  // elasticity pulls them back against contact on the ones that did not
  int back = -1;
  for (int i = 0; i < 1000 && back < 0; ++i) {
    sim::step(m, s, w);
    if (sim::max_displacement(m, s) < 5e-4) back = i;
  }
  std::printf("back at rest after %d steps of 8 ms\n", back);
  for (double x : s.x) ASSERT_TRUE(std::isfinite(x));
  EXPECT_LT(sim::max_penetration(m, s), 1e-3);
  EXPECT_LT(sim::max_displacement(m, s), 5e-4);
  for (uint8_t f : s.contact_let_go) EXPECT_EQ(f, 0);
}

// A small organ pulled away from the vessel it touches comes back: the right adrenal gland of the
// CT abdomen slab's `--organs all` build (data/meshes/ct_adrenal_gland_right.obj, its 4 anchors)
// next to the inferior vena cava of the same build (ct_inferior_vena_cava.obj, its 6 anchors; the
// two touch, 0.08 mm apart at rest), both solid, pulled 30 mm as SmallThinOrganHeldByTwoVertices
// pulls it alone. With the contact projection's displacement added as velocity (the earlier rule)
// the gland was flung against the vena cava and caught there: here +101 % volume and a residual of
// 21.0 mm (bench restore on the whole set: 11.1 mm, -19 %); contact that only stops motion into
// what it touches (contact.cpp stop_approach) lets it return: 0.27 mm, 0.5 %.
TEST(Contact, OrganPulledFromTheVesselItTouchesComesBack) {
  sim::SceneDesc scene =
      solid_test::ct_solid_scene("adrenal_gland_right", "meshes/ct_adrenal_gland_right.obj", {72, 259, 363, 500});
  const sim::SceneDesc ivc = solid_test::ct_solid_scene("inferior_vena_cava", "meshes/ct_inferior_vena_cava.obj",
                                                        {173, 204, 467, 541, 573, 627});
  scene.organs.push_back(ivc.organs[0]);
  scene.contact = true;
  ASSERT_TRUE(sim::compile(scene).contact.on);
  const double s2 = std::sqrt(0.5);
  double deepest = 0.0;
  const solid_test::PullResult r = solid_test::pull_release(scene, 0.030, {0, s2, -s2}, {0, s2, -s2}, 0.00188,
                                                            [&](const sim::Model& m, const sim::State& s, int step) {
                                                              if (step >= 0 && step % 5 == 4)
                                                                deepest = std::max(deepest, sim::max_penetration(m, s));
                                                            });
  std::printf(
      "CT adrenal gland next to the vena cava: reached %.1f mm, volume change %.2f %%, residual %.3f mm 2 s "
      "after release, deepest %.2f mm\n",
      r.reached_mm, r.volume_change_run_pct, r.residual_mm, 1e3 * deepest);
  ASSERT_EQ(r.grasped, 2u);
  EXPECT_TRUE(r.finite);
  EXPECT_GE(r.reached_mm, 20.0);
  EXPECT_LE(r.volume_change_run_pct, 2.0);
  EXPECT_LT(r.residual_mm, 1.0);
  EXPECT_LT(deepest, 3e-3);  // within the contact depth: nothing was let go through the vena cava
}

TEST(Contact, OffWhenAskedOrAlone) {
  sim::SceneDesc scene = two_spheres(0.002, false);
  EXPECT_FALSE(sim::compile(scene).contact.on);
  scene.contact = true;
  scene.organs.pop_back();
  EXPECT_FALSE(sim::compile(scene).contact.on);
}

}  // namespace
}  // namespace softatlas
