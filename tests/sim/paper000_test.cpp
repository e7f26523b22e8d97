// Paper 000's experiments with its settings, as tests of physical invariants (the numbers next
// to the paper's tables are produced by `softatlas bench accuracy`, docs/results.md).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "softatlas/sim/sim.hpp"
#include "test_meshes.hpp"

namespace softatlas {
namespace {

std::vector<int32_t> lowest(const sim::OrganDesc& d, size_t n) {
  std::vector<int32_t> ids(d.vertices.size() / 3);
  for (size_t i = 0; i < ids.size(); ++i) ids[i] = static_cast<int32_t>(i);
  std::sort(ids.begin(), ids.end(),
            [&](int32_t a, int32_t b) { return d.vertices[3 * a + 2] < d.vertices[3 * b + 2]; });
  ids.resize(n);
  return ids;
}

// The face with the highest centroid: the "top surface" the paper loads.
std::vector<int32_t> top_face(const sim::OrganDesc& d) {
  size_t best = 0;
  double bz = -1e300;
  for (size_t f = 0; f < d.faces.size() / 3; ++f) {
    const double z = d.vertices[3 * d.faces[3 * f] + 2] + d.vertices[3 * d.faces[3 * f + 1] + 2] +
                     d.vertices[3 * d.faces[3 * f + 2] + 2];
    if (z > bz) bz = z, best = f;
  }
  return {d.faces[3 * best], d.faces[3 * best + 1], d.faces[3 * best + 2]};
}

std::vector<int32_t> to_global(const sim::Model& m, const std::vector<int32_t>& local) {
  std::vector<int32_t> g;
  for (int32_t v : local) g.push_back(sim::global_vertex(m, 0, v));
  return g;
}

// Sphere of paper 000 section III.A: 162 v / 320 f, radius 1, point masses 1, k = 30, d = 100,
// tensile forces [0, f, f] on the same vertex; bottom vertices held.
TEST(Paper000, SphereTensileTestReachesEquilibriumWithMatchingFeedback) {
  for (sim::ModelKind model : {sim::ModelKind::tmsm, sim::ModelKind::nmsm}) {
    double prev_disp = 0;
    for (double f : {1.0, 4.0, 10.0}) {
      sim::SceneDesc s;
      s.organs.push_back(test::organ("sphere", test::icosphere(2, 1.0)));
      sim::OrganDesc& o = s.organs[0];
      o.material.model = model;
      o.material.stiffness = 30.0;
      o.material.damping = 100.0;
      o.material.vertex_mass_kg = 1.0;
      o.material.elastica_a = 1.0;
      o.material.elastica_b = 0.5;
      o.material.elastica_p = 2;           // p = 2 for the sphere (section III)
      o.material.elastica_literal = true;  // the paper's form of 000 eq 5
      o.material.curvature_unit_m = 1.0;   // dimensionless sphere
      o.fixed = lowest(o, 10);
      // Paper's Verlet scheme; the guard sub-steps the stiff damping (d = 100 on unit masses).
      s.integrator = sim::Integrator::verlet;
      s.dt_s = 0.01;
      s.max_tool_force_N = 100.0;  // dimensionless sphere: forces up to |[0, 10, 10]| = 14
      s.allow_sleep = false;
      const sim::Model m = sim::compile(s);
      sim::State st = sim::make_state(m);
      sim::Work w = sim::make_work(m);
      const std::vector<int32_t> top = to_global(m, top_face(o));
      sim::pull_force(m, st, {top[0]}, {0, f, f});
      sim::StepReport rep;
      // The paper's stopping rule: 20,000 iterations or sum |a| < 1e-6.
      const int64_t n = sim::run_to_rest(m, st, w, 20000, 1e-6, &rep);
      const auto r = sim::tool_reaction(st);
      std::printf("sphere %s f=%g: %lld steps, reaction %g %g %g, max disp %g\n", sim::to_string(model), f,
                  (long long)n, r[0], r[1], r[2], sim::max_displacement(m, st));
      EXPECT_NEAR(-r[1], f, 0.02 * f) << sim::to_string(model);
      EXPECT_NEAR(-r[2], f, 0.02 * f) << sim::to_string(model);
      const double disp = std::hypot(st.x[top[0]] - m.vert_rest_x[top[0]], st.y[top[0]] - m.vert_rest_y[top[0]],
                                     st.z[top[0]] - m.vert_rest_z[top[0]]);
      std::printf("sphere %s f=%g: loaded vertex moved %g\n", sim::to_string(model), f, disp);
      // Hooke springs: monotone. Elastica springs are not conservative (eq 6 acts along the
      // spring only) and the capped curvature term can make a larger load end in a blunter,
      // shorter cone: docs/physics.md reports the curve instead of asserting it.
      if (model == sim::ModelKind::tmsm) {
        EXPECT_GT(disp, prev_disp) << "the loaded vertex moves further";
      }
      prev_disp = disp;
    }
  }
}

sim::SceneDesc liver1000(sim::ModelKind model, double b) {
  sim::SceneDesc s;
  s.organs.push_back(test::organ("liver", test::read_obj(test::project_data("meshes/liver_1000.obj")), 1e-3));
  sim::OrganDesc& o = s.organs[0];
  o.material.model = model;
  o.material.young_modulus_pa = 300.0;  // soft enough that 1 mN moves the top face visibly
  o.material.thickness_m = 1e-3;        // t of eq 9 as in the paper
  o.material.elastica_a = 1.0;
  o.material.elastica_b = b;
  o.material.elastica_p = 1;           // p = 1 for the liver
  o.material.elastica_literal = true;  // the paper's form of 000 eq 5
  o.material.tau_s = model == sim::ModelKind::cmsm ? 0.0 : -1.0;
  o.fixed = lowest(o, 20);
  s.integrator = sim::Integrator::semi_implicit;
  s.dt_s = 5e-3;
  s.allow_sleep = false;
  return s;
}

// Table I: forces [1,0,0], [1,1,0], [1,1,1] x 1e-3 N on the top surface; at equilibrium the
// feedback force equals the applied force (within 2 %).
TEST(Paper000, LiverFeedbackForceEqualsAppliedForceAtEquilibrium) {
  for (sim::ModelKind model : {sim::ModelKind::tmsm, sim::ModelKind::cmsm, sim::ModelKind::nmsm})
    for (const std::array<double, 3> dir : {std::array<double, 3>{1, 0, 0}, {1, 1, 0}, {1, 1, 1}}) {
      const sim::SceneDesc s = liver1000(model, 0.5);
      const sim::Model m = sim::compile(s);
      sim::State st = sim::make_state(m);
      sim::Work w = sim::make_work(m);
      const std::array<double, 3> F{1e-3 * dir[0], 1e-3 * dir[1], 1e-3 * dir[2]};
      sim::pull_force(m, st, to_global(m, top_face(s.organs[0])), F);
      sim::StepReport rep;
      const int64_t n = sim::run_to_rest(m, st, w, 20000, 1e-6, &rep);
      const auto r = sim::tool_reaction(st);
      std::printf("liver %s F=[%g %g %g] mN: %lld steps, sum|a| %g, feedback %g %g %g mN\n", sim::to_string(model),
                  1e3 * F[0], 1e3 * F[1], 1e3 * F[2], (long long)n, rep.accel_sum, -1e3 * r[0], -1e3 * r[1],
                  -1e3 * r[2]);
      const double fnorm = 1e-3 * std::sqrt(dir[0] + dir[1] + dir[2]);
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(-r[k], F[k], 0.02 * fnorm) << sim::to_string(model) << " component " << k;
      EXPECT_GT(sim::max_displacement(m, st), 1e-5) << "the load must move the liver";
      const double vc = sim::total_volume(m, st) / s.organs[0].material.thickness_m;
      EXPECT_TRUE(std::isfinite(vc));
    }
}

// Table II: position attachment of one face by [0, 20, 20] and [0, 30, 30] mm in 30 iterations
// (b = 0.5 for 1000 faces, tau_s = 0 for CMSM).
TEST(Paper000, LiverPositionAttachmentMovesTheFaceExactly) {
  for (sim::ModelKind model : {sim::ModelKind::tmsm, sim::ModelKind::cmsm, sim::ModelKind::nmsm})
    for (double mm : {20.0, 30.0}) {
      sim::SceneDesc s = liver1000(model, 0.5);
      s.integrator = sim::Integrator::verlet;
      s.dt_s = 1e-3;
      const sim::Model m = sim::compile(s);
      sim::State st = sim::make_state(m);
      sim::Work w = sim::make_work(m);
      const std::vector<int32_t> face = to_global(m, top_face(s.organs[0]));
      const double v0 = sim::total_volume(m, st);
      sim::attach(m, st, face, {0, mm * 1e-3, mm * 1e-3}, 30);
      for (int i = 0; i < 30; ++i) sim::step(m, st, w);
      for (int32_t v : face) {
        EXPECT_NEAR(st.y[v] - m.vert_rest_y[v], mm * 1e-3, 1e-12);
        EXPECT_NEAR(st.z[v] - m.vert_rest_z[v], mm * 1e-3, 1e-12);
      }
      const auto r = sim::tool_reaction(st);
      const double vc = 100.0 * (sim::total_volume(m, st) - v0) / v0;
      std::printf("attach %s %g mm: reaction %g %g %g mN, volume change %.3f %%\n", sim::to_string(model), mm,
                  1e3 * r[0], 1e3 * r[1], 1e3 * r[2], vc);
      // CMSM holds the load through its position projection, whose impulses are not a force on
      // the tool (docs/physics.md): its Hooke springs stay near rest, so no sign check there.
      if (model != sim::ModelKind::cmsm) {
        EXPECT_LT(r[1] + r[2], 0.0) << "the liver pulls the tool back";
      }
      // Paper Table II: 0.4-1.3 %. Our TMSM/NMSM land there; CMSM's position projection on a
      // surface mesh loses more (the paper notes CMSM suits tetrahedral meshes).
      EXPECT_LT(std::abs(vc), model == sim::ModelKind::cmsm ? 15.0 : 3.0)
          << sim::to_string(model) << " volume change " << vc << " %";
    }
}

}  // namespace
}  // namespace softatlas
