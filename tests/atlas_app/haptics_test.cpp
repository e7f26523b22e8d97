// Haptics: force shaping (closed form), the scripted device, the scripted pull of the liver
// (device force == the core's reaction), and the 1 kHz loop thread.
#include <gtest/gtest.h>
#include <pthread.h>
#include <sched.h>

#include <chrono>
#include <cmath>
#include <thread>

#include "softatlas/app/haptics.hpp"
#include "softatlas/app/scene.hpp"
#include "test_util.hpp"

namespace softatlas::app {
namespace {

double norm(const Vec3d& v) { return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }

TEST(Haptics, ShaperRampsOnContactAndClampsToTheDeviceLimit) {
  ForceShaper s{2.0, 0.1};
  EXPECT_EQ(norm(s.shape({0, 0, 1}, false, 0.0)), 0.0);  // no contact, no force
  // Contact starts at t = 1.0: linear ramp over 0.1 s.
  EXPECT_NEAR(s.shape({0, 0, 1}, true, 1.0)[2], 0.0, 1e-12);
  EXPECT_NEAR(s.shape({0, 0, 1}, true, 1.05)[2], 0.5, 1e-12);
  EXPECT_NEAR(s.shape({0, 0, 1}, true, 1.2)[2], 1.0, 1e-12);
  EXPECT_FALSE(s.clamped);
  // 3-4-5 force of 5 N clamps to 2 N, same direction.
  const Vec3d f = s.shape({3, 4, 0}, true, 2.0);
  EXPECT_TRUE(s.clamped);
  EXPECT_NEAR(norm(f), 2.0, 1e-12);
  EXPECT_NEAR(f[0] / f[1], 0.75, 1e-12);
  // Losing contact resets the ramp.
  s.shape({0, 0, 1}, false, 3.0);
  EXPECT_NEAR(s.shape({0, 0, 1}, true, 3.0)[2], 0.0, 1e-12);
}

TEST(Haptics, ScriptedDeviceInterpolatesItsTimeline) {
  ScriptedDevice d({{0.0, {0, 0, 0}}, {1.0, {0, 0, -0.01}}, {2.0, {0.01, 0, -0.01}}}, false, 3.0);
  EXPECT_NEAR(d.read(0.5).offset_m[2], -0.005, 1e-12);
  EXPECT_NEAR(d.read(1.5).offset_m[0], 0.005, 1e-12);
  EXPECT_NEAR(d.read(9.0).offset_m[0], 0.01, 1e-12);  // holds the last keyframe
  EXPECT_FALSE(d.read(0.5).force_mode);
  d.write_force({0, 3, 4});
  d.write_force({0, 0, 1});
  EXPECT_NEAR(d.peak_sent_N(), 5.0, 1e-12);
  EXPECT_NEAR(d.last_sent_N()[2], 1.0, 1e-12);
}

TEST(Haptics, SeqLockHandsOverWholeValues) {
  SeqLock<ToolFeedback> lock;
  ToolFeedback out;
  EXPECT_FALSE(lock.load(out));  // nothing published yet
  std::atomic<bool> stop{false};
  std::thread writer([&] {
    for (int i = 1; !stop.load(); ++i) {
      ToolFeedback fb;
      fb.reaction_N = {double(i), double(i), double(i)};
      fb.physics_time_s = i;
      lock.store(fb);
      std::this_thread::yield();  // a real writer (the physics) publishes once per step
    }
  });
  int torn = 0, seen = 0;
  const auto until = std::chrono::steady_clock::now() + std::chrono::milliseconds(300);
  while (seen < 20000 && std::chrono::steady_clock::now() < until)
    if (lock.load(out)) {
      ++seen;
      if (out.reaction_N[0] != out.reaction_N[2] || out.reaction_N[0] != out.physics_time_s) ++torn;
    }
  stop.store(true);
  writer.join();
  EXPECT_GT(seen, 0);
  EXPECT_EQ(torn, 0);
}

// The scripted device pulls the liver's inferior edge 10 mm down; every tick the device gets
// the core's tool_reaction (shaped: ramp then clamp). After the ramp, below the clamp, the
// force on the device must equal the reaction exactly, and while held the organ pulls the tool
// back up (+z).
TEST(Haptics, ScriptedPullFeedbackIsTheCoresReactionForce) {
  const io::OrganSet set = io::read_organ_set(test::atlas_dir());
  AtlasScene scene(set, {"liver"}, {}, PhysicsSettings{});
  const int v = scene.view_index("liver");
  const auto verts = scene.global_vertices(v, scene.region_vertices(v, "inferior", 12.0));
  ASSERT_GT(verts.size(), 5u);
  ScriptedDevice device({{0.0, {0, 0, 0}}, {0.2, {0, 0, -0.010}}, {0.3, {0, 0, -0.010}}}, false, 4.0);
  ForceShaper shaper{4.0, 0.02};
  const double dt = scene.model.dt_s;
  double max_mismatch = 0;
  Vec3d reaction{0, 0, 0};
  for (int k = 0; k < 300; ++k) {
    const double t = (k + 1) * dt;
    const ToolCommand c = device.read(t);
    if (k == 0)
      sim::attach(scene.model, scene.state, verts, c.offset_m, 1);
    else
      sim::move_attachment(scene.state, c.offset_m);
    sim::step(scene.model, scene.state, scene.work);
    reaction = sim::tool_reaction(scene.state);
    device.write_force(shaper.shape(reaction, true, t));
    if (t > 0.03 && norm(reaction) < 4.0)
      for (int i = 0; i < 3; ++i)
        max_mismatch = std::max(max_mismatch, std::abs(device.last_sent_N()[i] - reaction[i]));
  }
  EXPECT_LT(max_mismatch, 1e-12);
  EXPECT_NEAR(scene.mean_displacement_mm(verts), 10.0, 0.5);
  EXPECT_GT(norm(reaction), 1e-4);
  EXPECT_GT(reaction[2], 0.0) << "held 10 mm down, the liver must pull the tool back up";
  for (int i = 0; i < 3; ++i) EXPECT_DOUBLE_EQ(device.last_sent_N()[i], reaction[i]);
}

TEST(Haptics, LoopRunsNearOneKilohertzAndKeepsTheLastForce) {
  ScriptedDevice device({{0.0, {0, 0, 0}}, {10.0, {0, 0, -0.01}}}, false, 1.0);
  HapticLoop loop(device, ForceShaper{1.0, 0.0}, 5000);
  ToolFeedback fb;
  fb.reaction_N = {0, 0, 3.0};  // above the 1 N device limit
  fb.contact = true;
  loop.publish(fb);
  loop.start(false);
  std::this_thread::sleep_for(std::chrono::milliseconds(400));
  ToolCommand cmd;
  EXPECT_TRUE(loop.latest_command(cmd));
  EXPECT_LT(cmd.offset_m[2], 0.0);
  loop.stop();
  const HapticStats s = loop.stats();
  EXPECT_GT(s.cycles, 250);  // 400 ms at 1 kHz, with slack for a loaded 2-core machine
  EXPECT_LT(s.cycles, 450);
  EXPECT_NEAR(s.period_us_p50, 1000.0, 250.0);
  EXPECT_NEAR(device.last_sent_N()[2], 1.0, 1e-12);  // clamped, and never stalled to zero
  EXPECT_NEAR(s.peak_force_N, 1.0, 1e-12);
}

TEST(Haptics, CpuPlanGivesTheHapticLoopOneCoreAndTheRendererTheRest) {
  cpu_set_t set;
  CPU_ZERO(&set);
  ASSERT_EQ(sched_getaffinity(0, sizeof set, &set), 0);
  const int allowed = CPU_COUNT(&set);
  const CpuPlan plan = plan_cpus();
  if (allowed < 2) {
    EXPECT_EQ(plan.haptic_cpu, -1);
    EXPECT_TRUE(plan.render_cpus.empty());
    return;
  }
  ASSERT_GE(plan.haptic_cpu, 0);
  EXPECT_TRUE(CPU_ISSET(plan.haptic_cpu, &set));
  EXPECT_EQ(static_cast<int>(plan.render_cpus.size()), allowed - 1);
  for (int c : plan.render_cpus) {
    EXPECT_NE(c, plan.haptic_cpu);
    EXPECT_TRUE(CPU_ISSET(c, &set));
  }
  // A loop started on the haptic core runs there, and the calling thread is not moved.
  ScriptedDevice device({{0.0, {0, 0, 0}}, {1.0, {0, 0, 0}}}, false, 1.0);
  HapticLoop loop(device, ForceShaper{1.0, 0.0}, 1000);
  loop.start(false, plan.haptic_cpu);
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  loop.stop();
  EXPECT_GT(loop.stats().cycles, 10);
  cpu_set_t after;
  CPU_ZERO(&after);
  ASSERT_EQ(sched_getaffinity(0, sizeof after, &after), 0);
  EXPECT_EQ(CPU_COUNT(&after), allowed);
  // pinning a thread to the render cores takes effect
  std::thread t([&] {
    EXPECT_TRUE(pin_current_thread(plan.render_cpus));
    cpu_set_t mine;
    CPU_ZERO(&mine);
    pthread_getaffinity_np(pthread_self(), sizeof mine, &mine);
    EXPECT_EQ(CPU_COUNT(&mine), static_cast<int>(plan.render_cpus.size()));
    EXPECT_FALSE(CPU_ISSET(plan.haptic_cpu, &mine));
  });
  t.join();
}

}  // namespace
}  // namespace softatlas::app
