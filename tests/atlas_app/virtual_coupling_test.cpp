// Multirate haptics: the coupling's sizing against Colgate's criterion, its passivity on a
// simulated device, blending without jumps, a replayed pull of the liver (bitwise repeatable,
// no jump above the bound) and a probe pressed into the liver's surface (force grows with depth).
#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <cmath>
#include <cstring>
#include <vector>

#include "softatlas/app/haptics.hpp"
#include "softatlas/app/scene.hpp"
#include "softatlas/app/virtual_coupling.hpp"
#include "test_util.hpp"

namespace softatlas::app {
namespace {

double norm(const Vec3d& v) { return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }
double dot(const Vec3d& a, const Vec3d& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

TEST(VirtualCoupling, SizingKeepsColgatesCriterionWithItsMargin) {
  // 1000 N/m rated at 1 kHz: b = 0.5 N s/m; b_c = 0.1; k_c = 0.5 * 2 * 0.4 / 1e-3 = 400 N/m.
  const CouplingParams c = size_coupling(1000.0, 1000.0);
  EXPECT_NEAR(c.damping_N_s_m, 0.1, 1e-12);
  EXPECT_NEAR(c.stiffness_N_m, 400.0, 1e-9);
  EXPECT_NEAR(c.period_s, 1e-3, 1e-15);
  EXPECT_TRUE(passive(c, 1000.0));
  // Ticking slower at the same rating leaves less stiffness; the full bound (margin 1) is the edge.
  EXPECT_NEAR(size_coupling(1000.0, 500.0).stiffness_N_m, 200.0, 1e-9);
  CouplingParams over = c;
  over.stiffness_N_m = 2.5 * c.stiffness_N_m;
  EXPECT_FALSE(passive(over, 1000.0));
}

// A device (mass m, physical damping b = K_dev T_dev / 2) integrated finely in continuous time,
// with the force of the coupling sampled and held every tick, against a wall-like tissue model
// (K = 1e5 N/m). Let go with a velocity into the wall and no hand: with the sized coupling the
// energy (kinetic + both springs) only decays; with a coupling 4x past Colgate's bound and no
// virtual damper it grows (the test can fail).
double energy_ratio_after(const CouplingParams& c, double K_wall) {
  HapticCoupling coupling(c);
  LocalModel wall;
  wall.serial = 1;
  wall.valid = wall.has_stiffness = true;
  wall.K_N_m[0] = wall.K_N_m[4] = wall.K_N_m[8] = K_wall;
  coupling.update(wall, 0.0);
  const double m = 0.05, b = 1000.0 * 1e-3 / 2.0, T = c.period_s;
  const int sub = 200;
  const double h = T / sub;
  double x = 0.0, v = -0.05;  // 5 cm/s into the wall
  auto energy = [&](const Vec3d& p) {
    const double kc = c.stiffness_N_m;
    return 0.5 * m * v * v + 0.5 * kc * (x - p[2]) * (x - p[2]) + 0.5 * K_wall * p[2] * p[2];
  };
  double e0 = 0.0, e_late = 0.0;
  for (int k = 0; k < 3000; ++k) {
    ToolCommand cmd;
    cmd.engaged = true;
    cmd.offset_m = {0, 0, x};
    bool from_model = false;
    const Vec3d f = coupling.tick(cmd, k * T, from_model);
    if (k == 0) e0 = 0.5 * m * v * v;
    for (int s = 0; s < sub; ++s) {  // semi-implicit Euler, exact enough at h = 5 us
      v += h * (f[2] - b * v) / m;
      x += h * v;
    }
    if (k >= 2800) e_late = std::max(e_late, energy(coupling.proxy()));
  }
  return e_late / e0;
}

TEST(VirtualCoupling, SampledCouplingStaysPassiveOnTheDevice) {
  const CouplingParams c = size_coupling(1000.0, 1000.0);
  EXPECT_LT(energy_ratio_after(c, 1e5), 1e-3);
  CouplingParams over = c;
  over.stiffness_N_m = 4.0 * 2.0 * (0.5 - 0.0) / c.period_s;
  over.damping_N_s_m = 0.0;
  EXPECT_FALSE(passive(over, 1000.0));
  EXPECT_GT(energy_ratio_after(over, 1e5), 1.0);
}

TEST(VirtualCoupling, ForceComesFromTheModelAndAModelUpdateDoesNotJump) {
  const CouplingParams c = size_coupling(1000.0, 1000.0);
  HapticCoupling coupling(c);
  LocalModel a;
  a.serial = 1;
  a.valid = a.has_stiffness = true;
  a.reaction0_N = {0, 0, 0.2};
  a.K_N_m[0] = a.K_N_m[4] = a.K_N_m[8] = 50.0;
  coupling.update(a, 0.0);
  ToolCommand cmd;
  cmd.engaged = true;
  cmd.offset_m = {0, 0, -0.004};
  bool from_model = false;
  Vec3d f{0, 0, 0};
  for (int k = 0; k < 50; ++k) f = coupling.tick(cmd, k * 1e-3, from_model);  // settle the damper
  EXPECT_TRUE(from_model);
  // Series springs: R = R0 - K p with p = (k_c x + R0) / (k_c + K) at rest.
  const double p = (c.stiffness_N_m * -0.004 + 0.2) / (c.stiffness_N_m + 50.0);
  EXPECT_NEAR(f[2], 0.2 - 50.0 * p, 1e-9);
  EXPECT_NEAR(coupling.proxy()[2], p, 1e-12);
  EXPECT_TRUE(cmd.contact);
  EXPECT_NEAR(cmd.proxy_m[2], p, 1e-12);
  // A new model 0.3 N away arrives every 4 ms: the force moves there over the blend, each tick
  // at most (0.3 N) / (4 ticks) plus what the damper adds.
  LocalModel b = a;
  b.serial = 2;
  b.reaction0_N = {0, 0, 0.5};
  const double t0 = 0.050;
  coupling.update(b, t0 - 4e-3);  // the previous update 4 ms earlier sets the blend period
  coupling.update(b, t0);
  double jump = 0;
  Vec3d last = f;
  for (int k = 1; k <= 20; ++k) {
    const Vec3d g = coupling.tick(cmd, t0 + k * 1e-3, from_model);
    jump = std::max(jump, std::abs(g[2] - last[2]));
    last = g;
  }
  EXPECT_LT(jump, 0.3 * 0.5);
  EXPECT_NEAR(last[2], 0.5 - 50.0 * (c.stiffness_N_m * -0.004 + 0.5) / (c.stiffness_N_m + 50.0), 1e-6);
  // Released: no force, proxy follows the device.
  cmd.engaged = false;
  EXPECT_EQ(norm(coupling.tick(cmd, 0.2, from_model)), 0.0);
  EXPECT_FALSE(from_model);
}

// Headless replay of the loop's own tick (HapticLoop::tick, no thread): one physics step every
// `every` ticks, so the force is computed from the model between steps as on a machine where
// the physics runs at a third of the tick rate.
struct Trace {
  std::vector<Vec3d> force, proxy, device;
  std::vector<uint8_t> contact;
  HapticStats stats;
};

// With `busy`, the step takes the whole interval, as on a machine where the physics is slower
// than the tick: the proxy is read at its start and the model published at its end.
Trace replay(AtlasScene& scene, ScriptedDevice& device, int ticks, int every, const std::vector<int32_t>& grasp,
             bool busy = false) {
  HapticLoop loop(device, ForceShaper{4.0, 0.02}, ticks, 1000.0);
  CouplingPhysics physics(scene.model);
  physics.grasp(scene.model, scene.state, grasp);
  Trace tr;
  for (int k = 0; k < ticks; ++k) {
    const double t = k * 1e-3;
    if (k % every == 0) {
      ToolCommand cmd;
      if (loop.latest_command(cmd)) physics.apply(scene.model, scene.state, cmd);
      sim::step(scene.model, scene.state, scene.work);
      if (!busy) loop.publish(physics.local_model(scene.model, scene.state, scene.work));
    }
    if (busy && k % every == every - 1) loop.publish(physics.local_model(scene.model, scene.state, scene.work));
    tr.force.push_back(loop.tick(t));
    ToolCommand cmd;
    loop.latest_command(cmd);
    tr.proxy.push_back(cmd.proxy_m);
    tr.device.push_back(cmd.offset_m);
    tr.contact.push_back(cmd.contact);
  }
  tr.stats = loop.stats();
  return tr;
}

// On a surface model the coupling's local model is the grasped patch's springs (a membrane):
// these tests run the atlas liver as one (flexion: Hooke springs + the volume constraint, the
// material of the BodyParts3D atlas they were written on). data/atlas's own organs are
// `model: solid`: SolidPullIsSmoothAtEveryPhysicsRate and the solid probe test cover them.
PhysicsSettings membrane_liver() {
  PhysicsSettings p;
  p.model = "flexion";
  return p;
}

TEST(VirtualCoupling, ReplayedPullGivesTheSameForceEveryRunWithoutJumps) {
  const io::OrganSet set = io::read_organ_set(test::atlas_dir());
  auto run = [&]() {
    AtlasScene scene(set, {"liver"}, {}, membrane_liver());
    const int v = scene.view_index("liver");
    const auto verts = scene.global_vertices(v, scene.region_vertices(v, "inferior", 12.0));
    EXPECT_GT(verts.size(), 5u);
    // 10 mm down over 0.4 s as a hand moves (smooth start and stop), held 0.2 s
    std::vector<Keyframe> keys;
    for (int i = 0; i <= 60; ++i) {
      const double t = i * 0.01, w = std::min(t / 0.4, 1.0);
      keys.push_back({t, {0, 0, -0.010 * 0.5 * (1 - std::cos(M_PI * w))}});
    }
    ScriptedDevice device(keys, false, 4.0);
    return replay(scene, device, 600, 3, verts);
  };
  const Trace a = run(), b = run();
  ASSERT_EQ(a.force.size(), b.force.size());
  EXPECT_EQ(std::memcmp(a.force.data(), b.force.data(), a.force.size() * sizeof(Vec3d)), 0)
      << "the replay must give the same force trace bit for bit";
  double peak = 0, jump = 0;
  for (size_t k = 0; k < a.force.size(); ++k) {
    peak = std::max(peak, norm(a.force[k]));
    if (k > 0 && a.contact[k] && a.contact[k - 1]) {
      const Vec3d d{a.force[k][0] - a.force[k - 1][0], a.force[k][1] - a.force[k - 1][1],
                    a.force[k][2] - a.force[k - 1][2]};
      jump = std::max(jump, norm(d));
    }
  }
  EXPECT_GT(peak, 1e-3);
  EXPECT_LE(jump, 0.05 * peak);
  EXPECT_DOUBLE_EQ(a.stats.force_jump_max_N, jump);
  EXPECT_DOUBLE_EQ(a.stats.peak_force_N, peak);
  // Every tick after the first model computes the force from it (not 1 in 3).
  EXPECT_GE(a.stats.model_ticks, 595);
  EXPECT_GT(a.force.back()[2], 0.0) << "held 10 mm down, the liver pulls the tool back up";
  // The coupling is far stiffer than the membrane: the proxy follows the device within 1 mm.
  EXPECT_LT(std::abs(a.proxy.back()[2] - a.device.back()[2]), 1e-3);
}

// The same pull on the solid model (volumetric lattice, implicit step at its own 8 ms): the
// local model is the step's own stiffness (sim::solid_hold_stiffness), the physics steps once
// every 8 ticks (real time) or every 24 or 32 (a third, a quarter of it, each step taking the
// whole interval), and the force neither jumps nor rings at the physics rate.
TEST(VirtualCoupling, SolidPullIsSmoothAtEveryPhysicsRate) {
  const io::OrganSet set = io::read_organ_set(test::atlas_dir());
  for (const auto& [every, busy] : std::vector<std::pair<int, bool>>{{8, false}, {8, true}, {24, true}, {32, true}}) {
    PhysicsSettings ps;
    ps.model = "solid";
    AtlasScene scene(set, {}, {}, ps);  // the whole atlas, as the window and bench haptic
    ASSERT_DOUBLE_EQ(scene.model.dt_s, sim::kSolidStep_s);
    const int v = scene.view_index("liver");
    const auto verts = scene.global_vertices(v, scene.region_vertices(v, "inferior", 12.0));
    std::vector<Keyframe> keys;
    for (int i = 0; i <= 120; ++i) {
      const double t = i * 0.01, w = std::min(t / 0.8, 1.0);
      keys.push_back({t, {0, 0, -0.008 * 0.5 * (1 - std::cos(M_PI * w))}});
    }
    ScriptedDevice device(keys, false, 4.0);
    const Trace a = replay(scene, device, 1200, every, verts, busy);
    double peak = 0, jump = 0;
    size_t at = 0;
    for (size_t k = 0; k < a.force.size(); ++k) {
      peak = std::max(peak, norm(a.force[k]));
      if (k > 0 && a.contact[k] && a.contact[k - 1]) {
        const Vec3d d{a.force[k][0] - a.force[k - 1][0], a.force[k][1] - a.force[k - 1][1],
                      a.force[k][2] - a.force[k - 1][2]};
        if (norm(d) > jump) jump = norm(d), at = k;
      }
    }
    std::string trace;
    for (size_t k = at > 12 ? at - 12 : 0; k < std::min(a.force.size(), at + 12); ++k)
      trace += std::to_string(k) + ": f " + std::to_string(a.force[k][2]) + " proxy " +
               std::to_string(a.proxy[k][2] * 1e3) + " mm device " + std::to_string(a.device[k][2] * 1e3) + " mm\n";
    EXPECT_GT(peak, 1e-2) << "every " << every;
    EXPECT_LT(peak, 4.0) << "every " << every << " (the clamp)";
    EXPECT_LE(jump, 0.05 * peak) << "every " << every << ", largest jump at tick " << at << "\n" << trace;
    for (const Vec3d& f : a.force) ASSERT_TRUE(std::isfinite(f[0] + f[1] + f[2]));
    EXPECT_GT(a.force.back()[2], 0.0) << "held 8 mm down, the liver pulls the tool back up";
  }
}

// A probe whose home is the liver's inferior vertex, not touching: after one physics step the
// published model has the surface there (its plane and the patch's stiffness). False if the
// atlas has no single inferior vertex or nothing was published.
bool free_probe_at_liver_front(AtlasScene& scene, CouplingPhysics& physics, LocalModel& out) {
  const int v = scene.view_index("liver");
  const auto front = scene.global_vertices(v, scene.region_vertices(v, "inferior", 0.0));
  if (front.size() != 1u) return false;
  const size_t g = static_cast<size_t>(front[0]);
  physics.probe({scene.state.x[g], scene.state.y[g], scene.state.z[g]});
  ToolCommand free_cmd;
  free_cmd.engaged = true;
  physics.apply(scene.model, scene.state, free_cmd);
  sim::step(scene.model, scene.state, scene.work);
  out = physics.local_model(scene.model, scene.state, scene.work);
  return out.surface;
}

// The probe against the liver's surface as the physics publishes it before contact (the plane
// of the nearest surface and the linearised stiffness of the patch there, from the liver's
// springs and dampers): pressed 2, 4, ... 10 mm below the surface, the tip is held by the
// coupling, the proxy stays on the (deformed) surface above the tip, and the force pushes out
// along the normal, growing with depth as the coupling and the patch in series.
TEST(VirtualCoupling, ProbePressedIntoTheLiverPushesBackMoreTheDeeperItGoes) {
  const io::OrganSet set = io::read_organ_set(test::atlas_dir());
  AtlasScene scene(set, {"liver"}, {}, membrane_liver());
  CouplingPhysics physics(scene.model);
  LocalModel m;
  ASSERT_TRUE(free_probe_at_liver_front(scene, physics, m));
  ASSERT_FALSE(m.valid);               // not touching yet
  EXPECT_LT(norm(m.surface_m), 1e-4);  // the vertex itself (it barely moved in one step)
  const Vec3d n = m.normal;
  ASSERT_NEAR(norm(n), 1.0, 1e-9);
  double Kn = 0;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) Kn += n[r] * m.K_N_m[3 * r + c] * n[c];
  EXPECT_GT(Kn, 0.1) << "the patch's springs resist pressing";

  const CouplingParams cp = size_coupling(1000.0, 1000.0);
  HapticCoupling probe(cp, true);
  probe.update(m, 0.0);
  bool from_model = false;
  // Tip 3 mm outside: no contact, no force.
  ToolCommand cmd;
  cmd.engaged = true;
  for (int c = 0; c < 3; ++c) cmd.offset_m[c] = m.surface_m[c] + 3e-3 * n[c];
  EXPECT_EQ(norm(probe.tick(cmd, 0.0, from_model)), 0.0);
  EXPECT_FALSE(cmd.contact);
  double last = 0.0;
  int tick = 1;
  for (int step = 1; step <= 5; ++step) {
    const double depth = 2e-3 * step;
    // 0.5 mm per tick down to the depth, then 100 ticks of hold
    Vec3d f{0, 0, 0};
    for (int k = 0; k < 100 + 4; ++k, ++tick) {
      const double d = std::min(depth, depth - 2e-3 + 0.5e-3 * (k + 1));
      for (int c = 0; c < 3; ++c) cmd.offset_m[c] = m.surface_m[c] - d * n[c];
      f = probe.tick(cmd, tick * 1e-3, from_model);
      ASSERT_TRUE(cmd.contact) << "no pop-through at " << d * 1e3 << " mm";
    }
    EXPECT_TRUE(from_model);
    const double push = dot(f, n);
    EXPECT_GT(push, last) << depth * 1e3 << " mm";
    // at rest: the patch (K) and the coupling (k_c) in series, F = k_c K (k_c I + K)^-1 depth n
    Eigen::Matrix3d K = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(m.K_N_m);
    const Eigen::Vector3d nv(n[0], n[1], n[2]);
    const double kc = cp.stiffness_N_m;
    const double expected = nv.dot(kc * K * (kc * Eigen::Matrix3d::Identity() + K).inverse() * (depth * nv));
    EXPECT_NEAR(push, expected, 0.01 * push);
    const Vec3d rel{probe.proxy()[0] - m.surface_m[0], probe.proxy()[1] - m.surface_m[1],
                    probe.proxy()[2] - m.surface_m[2]};
    const double proxy_depth = -dot(rel, n);
    EXPECT_GT(proxy_depth, 0.0);    // the surface gives way under the proxy...
    EXPECT_LT(proxy_depth, depth);  // ...but the proxy stays on it, above the tip
    last = push;
  }
  // Back out above the proxy: the contact ends, the force is zero, the next touch is new.
  const uint32_t id = cmd.contact_id;
  Vec3d f_out{1, 1, 1};
  for (int k = 1; k <= 22; ++k) {  // 10 mm -> 1 mm outside at 0.5 mm per tick
    const double d = std::max(-1e-3, 10e-3 - 0.5e-3 * k);
    for (int c = 0; c < 3; ++c) cmd.offset_m[c] = m.surface_m[c] - d * n[c];
    f_out = probe.tick(cmd, ++tick * 1e-3, from_model);
  }
  EXPECT_EQ(norm(f_out), 0.0);
  EXPECT_FALSE(cmd.contact);
  for (int c = 0; c < 3; ++c) cmd.offset_m[c] = m.surface_m[c] - 1e-3 * n[c];
  probe.tick(cmd, ++tick * 1e-3, from_model);
  EXPECT_TRUE(cmd.contact);
  EXPECT_EQ(cmd.contact_id, id + 1);
}

// Palpation closed loop on the solid liver: the probe tip goes 2, 4, 6, 8 mm below the surface
// at the liver's inferior vertex (scripted device, 1 kHz ticks, a physics step every 8), holds,
// and the force along the outward normal grows with depth; the proxy stays outside the tip.
TEST(VirtualCoupling, ProbePressedIntoTheSolidLiverPushesBackMoreTheDeeperItGoes) {
  const io::OrganSet set = io::read_organ_set(test::atlas_dir());
  PhysicsSettings ps;
  ps.model = "solid";
  AtlasScene scene(set, {"liver"}, {}, ps);
  CouplingPhysics physics(scene.model);
  LocalModel first;  // the outward normal there, from one physics step's published surface
  ASSERT_TRUE(free_probe_at_liver_front(scene, physics, first));
  double Kn = 0;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) Kn += first.normal[r] * first.K_N_m[3 * r + c] * first.normal[c];
  EXPECT_GT(Kn, 1.0) << "the solid under the patch resists pressing before the touch";
  const Vec3d n = first.normal;
  std::vector<Keyframe> keys;  // 3 mm outside, then 2 mm deeper every 0.6 s (0.2 s ramps)
  keys.push_back({0.0, {3e-3 * n[0], 3e-3 * n[1], 3e-3 * n[2]}});
  for (int k = 1; k <= 4; ++k) {
    const double d = 2e-3 * k, t = 0.6 * k;
    keys.push_back({t - 0.4, {-(d - 2e-3) * n[0], -(d - 2e-3) * n[1], -(d - 2e-3) * n[2]}});
    keys.push_back({t - 0.2, {-d * n[0], -d * n[1], -d * n[2]}});
    keys.push_back({t, {-d * n[0], -d * n[1], -d * n[2]}});
  }
  ScriptedDevice device(keys, false, 4.0);
  HapticLoop loop(device, ForceShaper{4.0, 0.02}, 2500, 1000.0, true);
  loop.publish(first);
  double last = 0.0;
  for (int k = 0; k <= 2400; ++k) {
    if (k % 8 == 0 && k > 0) {
      ToolCommand cmd;
      if (loop.latest_command(cmd)) physics.apply(scene.model, scene.state, cmd);
      sim::step(scene.model, scene.state, scene.work);
      loop.publish(physics.local_model(scene.model, scene.state, scene.work));
    }
    const Vec3d f = loop.tick(k * 1e-3);
    ASSERT_TRUE(std::isfinite(f[0] + f[1] + f[2])) << "tick " << k;
    if (k % 600 == 0 && k > 0) {  // end of a hold
      ToolCommand cmd;
      loop.latest_command(cmd);
      ASSERT_TRUE(cmd.contact) << "in contact at " << k / 300 << " mm";
      const double push = dot(f, n);
      EXPECT_GT(push, last + 1e-3) << "deeper pushes back more, at " << k / 300 << " mm";
      const Vec3d rel{cmd.proxy_m[0] - cmd.offset_m[0], cmd.proxy_m[1] - cmd.offset_m[1],
                      cmd.proxy_m[2] - cmd.offset_m[2]};
      EXPECT_GT(dot(rel, n), 0.0) << "the proxy stays outside the tip";
      last = push;
    }
  }
  EXPECT_GT(last, 0.01);
}

// A grasp on rigid bone (data/atlas's hip bone, model: rigid) holds nothing: the coupling is not
// attached, the device's pull moves no vertex of the bone or of the organs, and every force the
// loop sends is finite (and zero: nothing is held).
TEST(VirtualCoupling, AGraspOnRigidBoneHoldsNothingAndStaysFinite) {
  const io::OrganSet set = io::read_organ_set(test::atlas_dir());
  AtlasScene scene(set, {"kidney_right", "hip_right"}, {}, PhysicsSettings{});
  const int v = scene.view_index("hip_right");
  ASSERT_TRUE(scene.is_rigid(v));
  EXPECT_FALSE(scene.is_rigid(scene.view_index("kidney_right")));
  const auto verts = scene.global_vertices(v, scene.region_vertices(v, "superior", 15.0));
  ASSERT_GT(verts.size(), 3u);
  std::vector<Keyframe> keys;
  for (int i = 0; i <= 30; ++i) keys.push_back({i * 0.01, {0, 0, 0.010 * std::min(i / 20.0, 1.0)}});
  ScriptedDevice device(keys, false, 4.0);
  const Trace t = replay(scene, device, 300, 3, verts);
  for (const Vec3d& f : t.force) {
    ASSERT_TRUE(std::isfinite(f[0]) && std::isfinite(f[1]) && std::isfinite(f[2]));
    EXPECT_EQ(norm(f), 0.0);
  }
  const sim::OrganRange& bone = scene.model.organs[static_cast<size_t>(scene.model_organ(v))];
  for (int32_t g = bone.vert_begin; g < bone.vert_end; ++g) {
    ASSERT_EQ(scene.state.x[g], scene.model.vert_rest_x[g]);
    ASSERT_EQ(scene.state.z[g], scene.model.vert_rest_z[g]);
  }
  EXPECT_LT(sim::max_displacement(scene.model, scene.state), 1e-9);  // the kidney: rounding only
}

}  // namespace
}  // namespace softatlas::app
