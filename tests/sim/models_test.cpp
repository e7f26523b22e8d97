// Model-specific behaviour: elastica lengths (eq 5), compensation bounds (CMSM), flexion and
// volume constraint (paper 003).
#include <gtest/gtest.h>

#include <cmath>

#include "softatlas/sim/sim.hpp"
#include "test_meshes.hpp"

namespace softatlas {
namespace {

TEST(Nmsm, RestElasticaLengthUsesRestCurvature) {
  // On a sphere of radius r every vertex has H = 1/r, so l_e0 = l0 (a + b (L/r)) for p = 1.
  sim::SceneDesc s;
  const double r = 0.05;
  s.organs.push_back(test::organ("sphere", test::icosphere(4, r)));
  s.organs[0].material.elastica_a = 1.0;
  s.organs[0].material.elastica_b = 0.2;
  s.organs[0].material.curvature_unit_m = 1e-3;
  s.organs[0].material.elastica_literal = true;
  const sim::Model m = sim::compile(s);
  double worst = 0, mean = 0;
  for (int32_t q = 0; q < m.nspring; ++q) {
    const double e = std::abs(m.spring_rest[q] / m.spring_length0[q] - (1.0 + 0.2 * 1e-3 / r)) / (0.2 * 1e-3 / r);
    worst = std::max(worst, e);
    mean += e / m.nspring;
  }
  // The cotangent formula is exact only in the limit: valence-5 vertices of the icosphere are
  // off by a few per cent at this resolution.
  EXPECT_LT(mean, 0.02) << "curvature term within 2 % of b L / r on average";
  EXPECT_LT(worst, 0.10);
  // The conservative form keeps the same factor as the stiffness of a Hooke spring at l0.
  s.organs[0].material.elastica_literal = false;
  const sim::Model c = sim::compile(s);
  ASSERT_EQ(c.nspring, m.nspring);
  for (int32_t q = 0; q < m.nspring; q += 17) {
    EXPECT_DOUBLE_EQ(c.spring_rest[q], c.spring_length0[q]);
    EXPECT_NEAR(c.spring_k[q] / m.spring_k[q], m.spring_rest[q] / m.spring_length0[q], 1e-12);
  }
  EXPECT_FALSE(c.organs[0].curvature);
  EXPECT_TRUE(c.organs[0].elastica_frozen);
}

TEST(Cmsm, CompensationKeepsSpringsWithinTheirRatios) {
  sim::SceneDesc s;
  s.organs.push_back(test::organ("sphere", test::icosphere(2, 0.05)));
  s.organs[0].material.model = sim::ModelKind::cmsm;
  s.organs[0].material.tau_s = 0.01;
  s.organs[0].material.tau_c = 0.01;
  s.organs[0].material.compensation_iterations = 50;
  s.organs[0].material.stiffness = 1.0;  // very soft: plain springs would stretch a lot
  s.integrator = sim::Integrator::semi_implicit;
  s.dt_s = 1e-3;
  const sim::Model m = sim::compile(s);
  sim::State st = sim::make_state(m);
  sim::Work w = sim::make_work(m);
  sim::pull_force(m, st, {0}, {0, 0, 0.2});
  for (int i = 0; i < 300; ++i) sim::step(m, st, w);
  double worst = 0;
  for (int32_t q = 0; q < m.nspring; ++q) {
    const int32_t a = m.spring_a[q], b = m.spring_b[q];
    const double l =
        std::sqrt(std::pow(st.x[b] - st.x[a], 2) + std::pow(st.y[b] - st.y[a], 2) + std::pow(st.z[b] - st.z[a], 2));
    worst = std::max(worst, std::abs(l / m.spring_length0[q] - 1.0));
  }
  EXPECT_LT(worst, 0.03) << "springs must stay near (1 +/- tau) l0";
}

TEST(Flexion, VolumeConstraintHoldsVolumeUnderLoad) {
  auto volume_change = [](double volume_stiffness) {
    sim::SceneDesc s;
    s.organs.push_back(test::organ("sphere", test::icosphere(2, 0.05)));
    s.organs[0].material.model = sim::ModelKind::flexion;
    s.organs[0].material.stiffness = 5.0;
    s.organs[0].material.flexion_stiffness = 1e-4;
    s.organs[0].material.volume_stiffness = volume_stiffness;
    for (int v = 0; v < 5; ++v) s.organs[0].fixed.push_back(v);
    s.dt_s = 1e-3;
    const sim::Model m = sim::compile(s);
    sim::State st = sim::make_state(m);
    sim::Work w = sim::make_work(m);
    const double v0 = sim::total_volume(m, st);
    sim::pull_force(m, st, {sim::global_vertex(m, 0, 100)}, {0.05, 0.05, 0.0});
    for (int i = 0; i < 2000; ++i) sim::step(m, st, w);
    return std::abs(sim::total_volume(m, st) - v0) / v0;
  };
  const double free_vc = volume_change(0.0), held_vc = volume_change(1.0);
  EXPECT_LT(held_vc, 0.2 * free_vc) << "free " << free_vc << " held " << held_vc;
  EXPECT_LT(held_vc, 1e-3);
}

TEST(Flexion, DihedralSpringsRestoreABentShape) {
  sim::SceneDesc s;
  s.organs.push_back(test::organ("sphere", test::icosphere(2, 0.05)));
  s.organs[0].material.model = sim::ModelKind::flexion;
  s.organs[0].material.stiffness = 2.0;
  s.organs[0].material.flexion_stiffness = 5e-3;
  for (int v = 0; v < 5; ++v) s.organs[0].fixed.push_back(v);
  s.dt_s = 1e-3;
  const sim::Model m = sim::compile(s);
  ASSERT_GT(m.nflex, 0);
  sim::State st = sim::make_state(m);
  sim::Work w = sim::make_work(m);
  sim::attach(m, st, {sim::global_vertex(m, 0, 100)}, {0.0, 0.0, 0.02}, 30);
  for (int i = 0; i < 100; ++i) sim::step(m, st, w);
  const double deformed = sim::max_displacement(m, st);
  sim::release(st);
  for (int i = 0; i < 5000; ++i) sim::step(m, st, w);
  EXPECT_LT(sim::max_displacement(m, st), 0.05 * deformed);
}

}  // namespace
}  // namespace softatlas
