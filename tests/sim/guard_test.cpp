// Stiff and extreme cases: the guard keeps every run finite and says what it did.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "softatlas/sim/sim.hpp"
#include "test_meshes.hpp"

namespace softatlas {
namespace {

bool all_finite(const sim::State& s) {
  for (size_t v = 0; v < s.x.size(); ++v)
    if (!std::isfinite(s.x[v]) || !std::isfinite(s.y[v]) || !std::isfinite(s.z[v]) || !std::isfinite(s.vx[v]) ||
        !std::isfinite(s.vy[v]) || !std::isfinite(s.vz[v]))
      return false;
  return true;
}

sim::SceneDesc liver_scene(double k, double dt, sim::Integrator integ, sim::ModelKind model) {
  sim::SceneDesc s;
  s.organs.push_back(test::organ("liver", test::read_obj(test::project_data("meshes/liver_1000.obj")), 1e-3));
  s.organs[0].material.model = model;
  s.organs[0].material.stiffness = k;
  for (int v = 0; v < 10; ++v) s.organs[0].fixed.push_back(v);
  s.integrator = integ;
  s.dt_s = dt;
  s.gravity = false;  // a soft liver hanging from 10 vertices sags by metres: not the point here
  s.allow_sleep = false;
  return s;
}

struct Outcome {
  bool finite;
  int64_t guard_actions;
  double max_disp;
};

Outcome pull_liver(double k, double dt, sim::Integrator integ, sim::ModelKind model, bool guard, double pull_m,
                   int steps) {
  sim::SceneDesc scene = liver_scene(k, dt, integ, model);
  scene.guard = guard;
  const sim::Model m = sim::compile(scene);
  sim::State s = sim::make_state(m);
  sim::Work w = sim::make_work(m);
  sim::attach(m, s, {sim::global_vertex(m, 0, 300)}, {0, pull_m, pull_m}, 30);
  for (int i = 0; i < steps; ++i) sim::step(m, s, w);
  return {all_finite(s), s.guard_actions, sim::max_displacement(m, s)};
}

TEST(Guard, StiffLargeStepsStayFiniteForEveryModelAndIntegrator) {
  for (sim::ModelKind model : {sim::ModelKind::tmsm, sim::ModelKind::cmsm, sim::ModelKind::nmsm})
    for (sim::Integrator integ : {sim::Integrator::verlet, sim::Integrator::semi_implicit, sim::Integrator::implicit})
      for (double k : {1.0, 1e3, 1e6})
        for (double dt : {1e-4, 1e-2, 0.1}) {
          const Outcome o = pull_liver(k, dt, integ, model, true, 0.1, 60);
          EXPECT_TRUE(o.finite) << sim::to_string(model) << " " << sim::to_string(integ) << " k=" << k << " dt=" << dt;
          EXPECT_LT(o.max_disp, 1.0) << "a 100 mm pull must not throw vertices a metre away";
        }
}

TEST(Guard, WithoutTheGuardTheStiffCaseDiverges) {
  const Outcome off = pull_liver(1e6, 0.01, sim::Integrator::semi_implicit, sim::ModelKind::tmsm, false, 0.1, 60);
  EXPECT_TRUE(!off.finite || off.max_disp > 1.0) << "the sweep must reach a case that needs the guard";
  const Outcome on = pull_liver(1e6, 0.01, sim::Integrator::semi_implicit, sim::ModelKind::tmsm, true, 0.1, 60);
  EXPECT_TRUE(on.finite);
  EXPECT_GT(on.guard_actions, 0) << "the guard must report what it did";
}

TEST(Guard, NonFiniteStateIsRestoredAndReported) {
  sim::SceneDesc scene = liver_scene(100.0, 1e-3, sim::Integrator::semi_implicit, sim::ModelKind::nmsm);
  const sim::Model m = sim::compile(scene);
  sim::State s = sim::make_state(m);
  sim::Work w = sim::make_work(m);
  for (int i = 0; i < 40; ++i) sim::step(m, s, w);
  s.x[17] = std::numeric_limits<double>::quiet_NaN();
  const sim::StepReport r = sim::step(m, s, w);
  EXPECT_EQ(r.status, sim::StepStatus::restored);
  EXPECT_NE(std::string(r.message).find("restored"), std::string::npos);
  EXPECT_TRUE(all_finite(s));
  EXPECT_EQ(s.guard_restores, 1);
  for (int i = 0; i < 40; ++i) EXPECT_NE(sim::step(m, s, w).status, sim::StepStatus::restored);
  EXPECT_TRUE(all_finite(s));
}

TEST(Guard, ToolForceIsClamped) {
  sim::SceneDesc scene = liver_scene(100.0, 1e-3, sim::Integrator::semi_implicit, sim::ModelKind::nmsm);
  scene.max_tool_force_N = 5.0;
  const sim::Model m = sim::compile(scene);
  sim::State s = sim::make_state(m);
  sim::Work w = sim::make_work(m);
  sim::pull_force(m, s, {sim::global_vertex(m, 0, 250)}, {0, 0, 1000.0});
  const sim::StepReport r = sim::step(m, s, w);
  EXPECT_TRUE(r.tool_clamped);
  for (int i = 0; i < 200; ++i) sim::step(m, s, w);
  EXPECT_TRUE(all_finite(s));
}

TEST(Guard, SliversAndNearZeroEdgesStayFinite) {
  test::Mesh mesh = test::icosphere(2, 0.05);
  // collapse one edge to 1e-12 m and flatten a triangle into a sliver
  const int a = mesh.F[0], b = mesh.F[1], c = mesh.F[2];
  for (int k = 0; k < 3; ++k) mesh.V[3 * a + k] = mesh.V[3 * b + k] + 1e-12;
  for (int k = 0; k < 3; ++k) mesh.V[3 * c + k] = 0.5 * (mesh.V[3 * a + k] + mesh.V[3 * b + k]);
  for (sim::ModelKind model : {sim::ModelKind::tmsm, sim::ModelKind::nmsm, sim::ModelKind::flexion})
    for (sim::Integrator integ : {sim::Integrator::semi_implicit, sim::Integrator::implicit}) {
      sim::SceneDesc scene;
      scene.organs.push_back(test::organ("sliver", mesh));
      scene.organs[0].material.model = model;
      scene.organs[0].material.flexion_stiffness = 1e-3;
      scene.organs[0].material.volume_stiffness = 0.5;
      scene.integrator = integ;
      scene.dt_s = 1e-3;
      const sim::Model m = sim::compile(scene);
      sim::State s = sim::make_state(m);
      sim::Work w = sim::make_work(m);
      sim::pull_force(m, s, {sim::global_vertex(m, 0, 40)}, {0, 0, 5.0});
      for (int i = 0; i < 500; ++i) sim::step(m, s, w);
      EXPECT_TRUE(all_finite(s)) << sim::to_string(model) << " " << sim::to_string(integ);
    }
}

}  // namespace
}  // namespace softatlas
