// The scene compiler: only what the scene needs, and one clear error per bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "softatlas/sim/sim.hpp"
#include "test_meshes.hpp"

namespace softatlas {
namespace {

sim::SceneDesc three_organs() {
  sim::SceneDesc s;
  s.organs.push_back(test::organ("liver", test::icosphere(1, 0.05)));
  s.organs.push_back(test::organ("gallbladder", test::icosphere(1, 0.02)));
  s.organs.push_back(test::organ("spleen", test::icosphere(1, 0.03)));
  for (auto& o : s.organs) o.shown = false;
  s.organs[0].shown = true;
  // liver-gallbladder connected; spleen alone
  s.connections.push_back({0, 0, 1, 0, 0.01, 5.0});
  s.connections.push_back({2, 0, 1, 1, 0.01, 5.0});
  return s;
}

std::string error_of(const sim::SceneDesc& s) {
  try {
    sim::compile(s);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(Compile, KeepsShownAndConnectedOrgansOnly) {
  sim::SceneDesc s = three_organs();
  s.connections.pop_back();  // spleen now unconnected
  const sim::Model m = sim::compile(s);
  ASSERT_EQ(m.organs.size(), 2u);
  EXPECT_EQ(m.organs[0].name, "liver");
  EXPECT_EQ(m.organs[1].name, "gallbladder");
  EXPECT_EQ(sim::find_organ(m, "spleen"), -1);
  EXPECT_EQ(m.nconn, 1);
  EXPECT_NE(sim::explain(m).find("spleen"), std::string::npos);
}

TEST(Compile, ConnectionsToAbsentOrgansAreDropped) {
  sim::SceneDesc s = three_organs();
  s.connections.pop_back();
  s.connections.push_back({2, 0, 2, 1, 0.01, 5.0});  // spleen-internal, spleen not kept
  const sim::Model m = sim::compile(s);
  EXPECT_EQ(m.nconn, 1);
  EXPECT_NE(sim::explain(m).find("connection springs"), std::string::npos);
}

TEST(Compile, NoCurvatureWithoutBNoDampingWithoutDNoGravityWhenOff) {
  sim::SceneDesc s;
  s.organs.push_back(test::organ("liver", test::icosphere(1, 0.05)));
  s.organs[0].material.model = sim::ModelKind::nmsm;
  s.organs[0].material.elastica_b = 0.0;
  s.organs[0].material.damping = 0.0;
  s.gravity = false;
  const sim::Model m = sim::compile(s);
  EXPECT_FALSE(m.organs[0].curvature);
  EXPECT_FALSE(m.organs[0].damping);
  EXPECT_FALSE(m.gravity);
  const std::string plan = sim::explain(m);
  EXPECT_NE(plan.find("no curvature pass"), std::string::npos) << plan;
  EXPECT_NE(plan.find("no damping pass"), std::string::npos) << plan;
  EXPECT_NE(plan.find("no gravity pass"), std::string::npos) << plan;
  s.organs[0].material.elastica_b = 0.1;
  s.organs[0].material.damping = -1;
  s.gravity = true;
  EXPECT_FALSE(sim::compile(s).organs[0].curvature);  // conservative elastica: factor at rest
  s.organs[0].material.elastica_literal = true;
  const sim::Model m2 = sim::compile(s);
  EXPECT_TRUE(m2.organs[0].curvature);
  EXPECT_TRUE(m2.organs[0].damping);
  EXPECT_TRUE(m2.gravity);
}

TEST(Compile, DampingRatioGivesCriticalDampingOfEachSpringsTwoVertexMode) {
  sim::SceneDesc s;
  s.organs.push_back(test::organ("liver", test::icosphere(2, 0.05)));
  s.organs[0].material.model = sim::ModelKind::tmsm;
  s.organs[0].material.damping_ratio = 0.5;
  const sim::Model m = sim::compile(s);
  for (int32_t q = 0; q < m.nspring; q += 13) {
    const double ma = m.vert_mass[m.spring_a[q]], mb = m.vert_mass[m.spring_b[q]];
    EXPECT_NEAR(m.spring_d[q], 0.5 * 2.0 * std::sqrt(m.spring_k[q] * ma * mb / (ma + mb)), 1e-12 * m.spring_d[q]);
  }
  s.organs[0].material.damping_ratio = -2.0;
  EXPECT_THROW(sim::compile(s), InputError);
}

TEST(Compile, TmsmHasNoCurvaturePass) {
  sim::SceneDesc s;
  s.organs.push_back(test::organ("liver", test::icosphere(1, 0.05)));
  s.organs[0].material.model = sim::ModelKind::tmsm;
  EXPECT_FALSE(sim::compile(s).organs[0].curvature);
}

TEST(Compile, SpringsAreUniqueEdgesAndMassesSumToTotal) {
  sim::SceneDesc s;
  s.organs.push_back(test::organ("sphere", test::icosphere(2, 1.0)));
  s.organs[0].material.total_mass_kg = 3.0;
  const sim::Model m = sim::compile(s);
  EXPECT_EQ(m.nspring, 480);  // E = 3F/2 on a closed mesh
  double total = 0;
  for (double x : m.vert_mass) total += x;
  EXPECT_NEAR(total, 3.0, 1e-12);
}

TEST(Compile, SourceVertexOrderIsRecoverable) {
  sim::SceneDesc s;
  const test::Mesh mesh = test::icosphere(2, 1.0);
  s.organs.push_back(test::organ("sphere", mesh));
  const sim::Model m = sim::compile(s);
  const sim::State st = sim::make_state(m);
  std::vector<double> pos;
  sim::organ_positions(m, st, 0, pos);
  ASSERT_EQ(pos.size(), mesh.V.size());
  for (size_t i = 0; i < pos.size(); ++i) EXPECT_EQ(pos[i], mesh.V[i]);
  for (int32_t v = 0; v < 162; ++v) EXPECT_EQ(m.vert_source[sim::global_vertex(m, 0, v)], v);
}

TEST(Compile, BadInputGivesOneClearError) {
  sim::SceneDesc base;
  base.organs.push_back(test::organ("liver", test::icosphere(1, 0.05)));
  {
    sim::SceneDesc s = base;
    s.organs[0].faces.clear();
    EXPECT_NE(error_of(s).find("empty mesh"), std::string::npos) << error_of(s);
  }
  {
    sim::SceneDesc s = base;
    s.organs[0].faces.push_back(1);  // not a multiple of 3: non-triangle
    EXPECT_NE(error_of(s).find("triangles only"), std::string::npos) << error_of(s);
  }
  {
    sim::SceneDesc s = base;
    s.organs[0].vertices[4] = std::numeric_limits<double>::quiet_NaN();
    EXPECT_NE(error_of(s).find("non-finite coordinate at vertex 1"), std::string::npos) << error_of(s);
  }
  {
    sim::SceneDesc s = base;
    s.organs[0].faces[2] = 9999;
    EXPECT_NE(error_of(s).find("vertex index 9999"), std::string::npos) << error_of(s);
  }
  {
    sim::SceneDesc s = base;
    s.organs[0].material.stiffness = -5;
    const std::string e = error_of(s);
    EXPECT_NE(e.find("organ 'liver': material.stiffness"), std::string::npos) << e;
    EXPECT_NE(e.find("-5"), std::string::npos) << e;
  }
  {
    sim::SceneDesc s = base;
    s.organs[0].material.elastica_p = 3;
    EXPECT_NE(error_of(s).find("p = 1 or 2"), std::string::npos);
  }
  {
    sim::SceneDesc s = base;
    s.dt_s = -1;
    EXPECT_NE(error_of(s).find("dt_s"), std::string::npos);
  }
  sim::ModelKind k;
  EXPECT_FALSE(sim::parse_model_kind("fem-ish", k));
  EXPECT_TRUE(sim::parse_model_kind("nmsm", k));
  EXPECT_EQ(k, sim::ModelKind::nmsm);
}

TEST(Compile, GuardPlansSubstepsOrImplicitForLargeSteps) {
  sim::SceneDesc s;
  s.organs.push_back(test::organ("sphere", test::icosphere(2, 0.05)));
  s.organs[0].material.stiffness = 1e3;
  s.integrator = sim::Integrator::semi_implicit;
  s.dt_s = 1e-5;
  sim::Model m = sim::compile(s);
  EXPECT_EQ(m.substeps, 1);
  s.dt_s = 4 * m.stable_dt_s;
  m = sim::compile(s);
  EXPECT_GT(m.substeps, 1);
  EXPECT_EQ(m.effective_integrator, sim::Integrator::semi_implicit);
  s.dt_s = 1000 * m.stable_dt_s;
  m = sim::compile(s);
  EXPECT_EQ(m.effective_integrator, sim::Integrator::implicit);
}

}  // namespace
}  // namespace softatlas
