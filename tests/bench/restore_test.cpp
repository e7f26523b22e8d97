// bench restore on a tiny organ set: a sphere of 162 vertices held at its top.
#include <gtest/gtest.h>

#include <cmath>

#include "../sim/test_meshes.hpp"
#include "softatlas/bench/restore.hpp"

namespace softatlas {
namespace {

sim::SceneDesc ball_scene(sim::ModelKind model) {
  sim::SceneDesc s;
  s.organs.push_back(test::organ("ball", test::icosphere(2, 20.0), 1e-3));  // 20 mm radius
  sim::OrganDesc& o = s.organs[0];
  o.material.model = model;
  o.material.volume_stiffness = 0.5;
  for (size_t v = 0; v < o.vertices.size() / 3; ++v)  // the top cap is held (superior, +z)
    if (o.vertices[3 * v + 2] > 0.017) o.fixed.push_back(static_cast<int32_t>(v));
  return s;
}

bench::RestoreOptions short_protocol() {
  bench::RestoreOptions o;
  o.rest_s = 1.0, o.pull_s = 0.2, o.hold_s = 0.2, o.after_s = 2.0, o.residual_at_s = 1.5;
  o.pull_m = 0.005;
  return o;
}

TEST(BenchRestore, PullsTheAnteriorInferiorRegionAndMeasuresTheReturn) {
  const bench::RestoreResult r = bench::run_restore(ball_scene(sim::ModelKind::tmsm), "ball", short_protocol());
  EXPECT_TRUE(r.finite);
  EXPECT_EQ(r.organ, "ball");
  EXPECT_EQ(r.model, "tmsm");
  EXPECT_GT(r.grasped_vertices, 0);
  EXPECT_LT(r.rest_drift_mm, 0.01);                   // TMSM is conservative: nothing drifts
  EXPECT_NEAR(r.pull_reached_mm, 5.0, 0.5);           // position attachment reaches its target
  EXPECT_LT(r.residual_mm, 0.5 * r.pull_reached_mm);  // it comes back (the rigid part removed)
  EXPECT_LT(std::abs(r.volume_change_pct), 20.0);
  EXPECT_NEAR(r.simulated_s, 1.0 + 0.2 + 0.2 + 2.0, 1e-9);
}

TEST(BenchRestore, SameRunGivesTheSameNumbers) {
  const auto a = bench::run_restore(ball_scene(sim::ModelKind::nmsm), "ball", short_protocol());
  const auto b = bench::run_restore(ball_scene(sim::ModelKind::nmsm), "ball", short_protocol());
  EXPECT_EQ(a.rest_drift_mm, b.rest_drift_mm);
  EXPECT_EQ(a.residual_mm, b.residual_mm);
  EXPECT_EQ(a.volume_change_pct, b.volume_change_pct);
}

TEST(BenchRestore, RigidResidualIgnoresRigidMotionOnly) {
  const sim::Model m = sim::compile(ball_scene(sim::ModelKind::tmsm));
  sim::State s = sim::make_state(m);
  const double c = std::cos(0.3), sn = std::sin(0.3);
  for (int32_t v = 0; v < m.nvert; ++v) {  // rotate about z and translate 7 cm
    const double x = s.x[v], y = s.y[v];
    s.x[v] = c * x - sn * y + 0.07, s.y[v] = sn * x + c * y - 0.02, s.z[v] += 0.03;
  }
  EXPECT_LT(bench::rigid_residual(m, s, 0), 1e-12);
  s = sim::make_state(m);
  s.x[5] += 0.004;  // one vertex out by 4 mm: most of it stays after the best fit
  const double r = bench::rigid_residual(m, s, 0);
  EXPECT_GT(r, 0.0035);
  EXPECT_LE(r, 0.004 + 1e-12);
}

TEST(BenchRestore, UnknownOrganIsAnInputError) {
  EXPECT_THROW(bench::run_restore(ball_scene(sim::ModelKind::tmsm), "spleen", short_protocol()), InputError);
}

}  // namespace
}  // namespace softatlas
