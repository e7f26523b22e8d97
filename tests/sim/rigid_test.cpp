// The rigid model (ModelKind::rigid): fixed context such as bone. Drawn and picked like any
// organ, it never moves, has no springs, sleeps from the first step and is never woken, and it
// anchors the connection springs of the soft organs that touch it.
#include <gtest/gtest.h>

#include <cmath>

#include "softatlas/sim/sim.hpp"
#include "test_meshes.hpp"

namespace softatlas {
namespace {

// A soft sphere (r = 2 cm) resting on a rigid sphere below it, joined by connection springs
// between their closest vertices.
sim::SceneDesc bone_and_organ(sim::ModelKind soft, sim::Integrator integrator, int threads = 1, bool connected = true) {
  sim::SceneDesc scene;
  test::Mesh bone = test::icosphere(2, 0.02), organ = test::icosphere(2, 0.02);
  for (size_t i = 2; i < organ.V.size(); i += 3) organ.V[i] += 0.045;  // 5 mm gap above the bone
  scene.organs.push_back(test::organ("bone", bone));
  scene.organs.back().material.model = sim::ModelKind::rigid;
  scene.organs.push_back(test::organ("organ", organ));
  scene.organs.back().material.model = soft;
  scene.organs.back().material.volume_stiffness = soft == sim::ModelKind::flexion ? 0.5 : 0.0;
  scene.organs.back().material.flexion_stiffness = soft == sim::ModelKind::flexion ? 1e-4 : 0.0;
  const size_t nv = bone.V.size() / 3;
  int32_t added = 0;
  for (size_t a = 0; a < nv && added < 6; ++a) {
    if (bone.V[3 * a + 2] < 0.019) continue;  // the bone's top cap
    for (size_t b = 0; b < nv; ++b)
      if (std::abs(organ.V[3 * b] - bone.V[3 * a]) < 1e-9 && std::abs(organ.V[3 * b + 1] - bone.V[3 * a + 1]) < 1e-9 &&
          organ.V[3 * b + 2] < 0.045 - 0.019) {
        const double dz = organ.V[3 * b + 2] - bone.V[3 * a + 2];
        scene.connections.push_back({0, static_cast<int32_t>(a), 1, static_cast<int32_t>(b), dz, 20.0});
        ++added;
      }
  }
  EXPECT_GT(added, 0);
  if (!connected) scene.connections.clear();
  scene.integrator = integrator;
  scene.gravity = false;
  scene.sleep_steps = 20;
  scene.threads = threads;
  return scene;
}

double max_bone_displacement(const sim::Model& m, const sim::State& s) {
  const sim::OrganRange& r = m.organs[static_cast<size_t>(sim::find_organ(m, "bone"))];
  double d = 0.0;
  for (int32_t v = r.vert_begin; v < r.vert_end; ++v)
    d = std::max({d, std::abs(s.x[v] - m.vert_rest_x[v]), std::abs(s.y[v] - m.vert_rest_y[v]),
                  std::abs(s.z[v] - m.vert_rest_z[v])});
  return d;
}

// Largest displacement of the organ's vertices that the connection springs hold (compiled
// global indices; the unconnected twin scene has the same vertex order).
double max_held_displacement(const sim::Model& m, const sim::State& s, const std::vector<int32_t>& verts) {
  double d = 0.0;
  for (int32_t v : verts)
    d = std::max(d, std::sqrt(std::pow(s.x[v] - m.vert_rest_x[v], 2) + std::pow(s.y[v] - m.vert_rest_y[v], 2) +
                              std::pow(s.z[v] - m.vert_rest_z[v], 2)));
  return d;
}

TEST(Rigid, CompilesToFixedVerticesWithoutSpringsAndSaysSo) {
  const sim::Model m = sim::compile(bone_and_organ(sim::ModelKind::nmsm, sim::Integrator::semi_implicit));
  const sim::OrganRange& r = m.organs[static_cast<size_t>(sim::find_organ(m, "bone"))];
  EXPECT_EQ(r.model, sim::ModelKind::rigid);
  EXPECT_EQ(r.spring_end - r.spring_begin, 0);
  EXPECT_EQ(r.flex_end - r.flex_begin, 0);
  for (int32_t v = r.vert_begin; v < r.vert_end; ++v) EXPECT_EQ(m.vert_inv_mass[v], 0.0);
  EXPECT_GT(m.nconn, 0);
  EXPECT_FALSE(m.rigid_conn_verts.empty());
  bool said = false;
  for (const std::string& line : m.plan)
    said = said || line.find("[rigid]: all 162 vertices fixed") != std::string::npos;
  EXPECT_TRUE(said) << sim::explain(m);
  // a spring between two rigid organs can do nothing: left out, and said
  sim::SceneDesc two = bone_and_organ(sim::ModelKind::nmsm, sim::Integrator::semi_implicit);
  two.organs[1].material.model = sim::ModelKind::rigid;
  const sim::Model m2 = sim::compile(two);
  EXPECT_EQ(m2.nconn, 0);
  ASSERT_EQ(m2.dropped.size(), 1u);
  EXPECT_NE(m2.dropped[0].find("between two rigid organs"), std::string::npos);
  sim::ModelKind k;
  ASSERT_TRUE(sim::parse_model_kind("rigid", k));
  EXPECT_EQ(k, sim::ModelKind::rigid);
  EXPECT_STREQ(sim::to_string(sim::ModelKind::rigid), "rigid");
}

// Under a pull the soft organ moves and stays finite; the bone does not move by a single bit, is
// never awake, and the connection springs hold the organ near it (without them the same pull
// sends the free organ drifting away).
TEST(Rigid, NeverMovesNeverWakesAndAnchorsTheConnectedOrgan) {
  for (sim::Integrator integ : {sim::Integrator::semi_implicit, sim::Integrator::verlet, sim::Integrator::implicit})
    for (int threads : {1, 2}) {
      SCOPED_TRACE(std::string(sim::to_string(integ)) + " threads " + std::to_string(threads));
      const sim::Model m = sim::compile(bone_and_organ(sim::ModelKind::nmsm, integ, threads));
      sim::State s = sim::make_state(m);
      sim::Work w = sim::make_work(m);
      const int32_t bone = sim::find_organ(m, "bone"), organ = sim::find_organ(m, "organ");
      EXPECT_EQ(s.organ_awake[bone], 0);
      const sim::OrganRange& o = m.organs[organ];
      sim::pull_force(m, s, {o.vert_begin, o.vert_begin + 1}, {0.02, 0.0, 0.0});
      for (int k = 0; k < 300; ++k) {
        sim::step(m, s, w);
        ASSERT_EQ(s.organ_awake[bone], 0) << "step " << k;
      }
      EXPECT_EQ(max_bone_displacement(m, s), 0.0);
      const double moved = sim::max_displacement(m, s);
      EXPECT_GT(moved, 1e-4);
      EXPECT_TRUE(std::isfinite(moved));
      sim::release(s);
      for (int k = 0; k < 3000; ++k) sim::step(m, s, w);
      EXPECT_EQ(max_bone_displacement(m, s), 0.0);
      std::vector<int32_t> ends;
      for (int32_t q = 0; q < m.nconn; ++q)
        for (int32_t v : {m.conn_a[q], m.conn_b[q]})
          if (m.vert_organ[v] == organ) ends.push_back(v);
      ASSERT_FALSE(ends.empty());
      const double held = max_held_displacement(m, s, ends);
      EXPECT_LT(held, 0.02);  // the bone's radius
      // the same pull without the connection springs: nothing holds the organ
      const sim::Model mf = sim::compile(bone_and_organ(sim::ModelKind::nmsm, integ, threads, false));
      sim::State sf = sim::make_state(mf);
      sim::Work wf = sim::make_work(mf);
      const sim::OrganRange& of = mf.organs[sim::find_organ(mf, "organ")];
      sim::pull_force(mf, sf, {of.vert_begin, of.vert_begin + 1}, {0.02, 0.0, 0.0});
      for (int k = 0; k < 300; ++k) sim::step(mf, sf, wf);
      sim::release(sf);
      for (int k = 0; k < 3000; ++k) sim::step(mf, sf, wf);
      EXPECT_GT(max_held_displacement(mf, sf, ends), 3.0 * held);
    }
}

// A grasp or pull on the bone holds nothing: no vertex moves, the reaction is zero, no NaN,
// and waking the bone (as a tool does) leaves it asleep.
TEST(Rigid, AGraspOnTheBoneHoldsNothing) {
  const sim::Model m = sim::compile(bone_and_organ(sim::ModelKind::tmsm, sim::Integrator::semi_implicit));
  sim::State s = sim::make_state(m);
  sim::Work w = sim::make_work(m);
  const int32_t bone = sim::find_organ(m, "bone");
  const sim::OrganRange& r = m.organs[bone];
  sim::attach(m, s, {r.vert_begin, r.vert_begin + 3}, {0.01, 0, 0}, 5);
  EXPECT_TRUE(s.tool.verts.empty());
  sim::wake(m, s, bone);
  EXPECT_EQ(s.organ_awake[bone], 0);
  for (int k = 0; k < 50; ++k) sim::step(m, s, w);
  sim::pull_force(m, s, {r.vert_begin + 7}, {0, 0, 5.0});
  for (int k = 0; k < 50; ++k) sim::step(m, s, w);
  EXPECT_EQ(max_bone_displacement(m, s), 0.0);
  const auto reaction = sim::tool_reaction(s);
  for (double c : reaction) EXPECT_EQ(c, 0.0);
  for (int32_t v = 0; v < m.nvert; ++v) ASSERT_TRUE(std::isfinite(s.x[v] + s.y[v] + s.z[v]));
}

// The bone costs no per-vertex work: its force entries stay zero after every step except where
// connections end (cleared after the update), so a scene with a big rigid organ keeps the
// explicit update's "forces already zero" shortcut.
TEST(Rigid, LeavesNoForcesBehindAndKeepsTheZeroForceShortcut) {
  const sim::Model m = sim::compile(bone_and_organ(sim::ModelKind::nmsm, sim::Integrator::semi_implicit));
  sim::State s = sim::make_state(m);
  sim::Work w = sim::make_work(m);
  for (int k = 0; k < 10; ++k) sim::step(m, s, w);
  EXPECT_TRUE(w.forces_zero);
  for (double f : w.fx) EXPECT_EQ(f, 0.0);
  for (double f : w.fz) EXPECT_EQ(f, 0.0);
}

}  // namespace
}  // namespace softatlas
