// Implicit Euler: the CG (float vectors, float blocks) solves the Baraff-Witkin system of
// docs/physics.md. Checked against a dense double-precision solve of the same system assembled
// here from the model's springs, independently of sim/src/step.cpp.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <random>

#include "softatlas/sim/sim.hpp"
#include "test_meshes.hpp"

namespace softatlas {
namespace {

struct Solved {
  double rel_error = 0.0;  // |dv - dv_ref| / |dv_ref| over the free vertices
  double norm_ref = 0.0;
};

// One implicit step from a perturbed, moving state; the step's dv against the dense solve.
Solved implicit_step_against_dense(int cg_iterations, double dt, double k, bool with_connection) {
  sim::SceneDesc scene;
  scene.organs.push_back(test::organ("a", test::icosphere(2, 0.05)));
  if (with_connection) {
    test::Mesh b = test::icosphere(1, 0.03);
    for (size_t i = 0; i < b.V.size(); i += 3) b.V[i] += 0.1;
    scene.organs.push_back(test::organ("b", b));
    sim::ConnectionDesc c;
    c.organ_a = 0, c.vertex_a = 0, c.organ_b = 1, c.vertex_b = 3;
    c.rest_length_m = 0.02, c.stiffness = 2 * k;
    scene.connections.push_back(c);
  }
  for (sim::OrganDesc& o : scene.organs) {
    o.material.model = sim::ModelKind::tmsm;
    o.material.stiffness = k;
    o.material.vertex_mass_kg = 1e-3;
    o.material.volume_stiffness = 0.0;
    o.fixed = {1, 2};
  }
  scene.integrator = sim::Integrator::implicit;
  scene.dt_s = dt;
  scene.gravity = true;
  scene.cg_iterations = cg_iterations;
  scene.cg_tolerance = 0.0;
  scene.allow_sleep = false;
  const sim::Model m = sim::compile(scene);
  sim::State s = sim::make_state(m);
  sim::Work w = sim::make_work(m);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int32_t v = 0; v < m.nvert; ++v) {
    if (m.vert_inv_mass[v] == 0) continue;
    s.x[v] += 2e-3 * u(rng), s.y[v] += 2e-3 * u(rng), s.z[v] += 2e-3 * u(rng);
    s.vx[v] = 0.05 * u(rng), s.vy[v] = 0.05 * u(rng), s.vz[v] = 0.05 * u(rng);
  }
  const sim::State s0 = s;
  const sim::StepReport rep = sim::step(m, s, w);
  EXPECT_EQ(rep.status, sim::StepStatus::ok) << rep.message;

  // Dense system over all 3n unknowns; fixed vertices get identity rows (dv = 0).
  const int n = m.nvert;
  const double h = dt;
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(3 * n, 3 * n);
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(3 * n);
  auto pos = [&](int v) { return Eigen::Vector3d(s0.x[v], s0.y[v], s0.z[v]); };
  auto vel = [&](int v) { return Eigen::Vector3d(s0.vx[v], s0.vy[v], s0.vz[v]); };
  auto spring = [&](int i, int j, double ks, double L, double d) {
    const Eigen::Vector3d e = pos(j) - pos(i);
    const double l = e.norm();
    const Eigen::Vector3d uu = e / l;
    const Eigen::Vector3d dv = vel(j) - vel(i);
    const double f = ks * (l - L) + d * dv.dot(uu);
    const double alpha = h * h * ks * std::max(0.0, 1.0 - L / l);
    const double kbeta = h * h * ks - alpha;
    const Eigen::Vector3d g = h * f * uu + alpha * dv + kbeta * uu * uu.dot(dv);
    rhs.segment<3>(3 * i) += g;
    rhs.segment<3>(3 * j) -= g;
    const Eigen::Matrix3d B = alpha * Eigen::Matrix3d::Identity() + (kbeta + h * d) * uu * uu.transpose();
    A.block<3, 3>(3 * i, 3 * i) += B, A.block<3, 3>(3 * j, 3 * j) += B;
    A.block<3, 3>(3 * i, 3 * j) -= B, A.block<3, 3>(3 * j, 3 * i) -= B;
  };
  for (int32_t q = 0; q < m.nspring; ++q)
    spring(m.spring_a[q], m.spring_b[q], m.spring_k[q], m.spring_rest[q], m.spring_d[q]);
  for (int32_t q = 0; q < m.nconn; ++q) spring(m.conn_a[q], m.conn_b[q], m.conn_k[q], m.conn_rest[q], m.conn_d[q]);
  for (int v = 0; v < n; ++v) {
    for (int a = 0; a < 3; ++a) {
      A(3 * v + a, 3 * v + a) += m.vert_mass[v];
      rhs(3 * v + a) += h * m.vert_mass[v] * m.gravity_m_s2[a];
    }
    if (m.vert_inv_mass[v] == 0) {
      for (int a = 0; a < 3; ++a) {
        A.row(3 * v + a).setZero(), A.col(3 * v + a).setZero();
        A(3 * v + a, 3 * v + a) = 1.0, rhs(3 * v + a) = 0.0;
      }
    }
  }
  const Eigen::VectorXd ref = A.llt().solve(rhs);
  Eigen::VectorXd got(3 * n);
  for (int v = 0; v < n; ++v)
    got.segment<3>(3 * v) = Eigen::Vector3d(s.vx[v] - s0.vx[v], s.vy[v] - s0.vy[v], s.vz[v] - s0.vz[v]);
  Solved r;
  r.norm_ref = ref.norm();
  r.rel_error = (got - ref).norm() / ref.norm();
  return r;
}

TEST(Implicit, ConvergedCgMatchesADenseDoubleSolve) {
  // Converged, the float CG is as good as float allows: 1e-5 relative covers the rounding of
  // blocks, vectors and the condition number of this system.
  const Solved r = implicit_step_against_dense(2000, 1e-3, 50.0, /*with_connection=*/true);
  EXPECT_GT(r.norm_ref, 0.0);
  EXPECT_LT(r.rel_error, 1e-5) << "relative error " << r.rel_error;
}

TEST(Implicit, StiffLargeStepStillMatchesWhenConverged) {
  const Solved r = implicit_step_against_dense(4000, 1e-2, 1e4, /*with_connection=*/false);
  EXPECT_LT(r.rel_error, 1e-4) << "relative error " << r.rel_error;
}

TEST(Implicit, TwentyFiveIterationsReduceTheErrorOfTheDenseSolve) {
  // A truncated CG is not converged; its error must still be well below the size of dv.
  const Solved r5 = implicit_step_against_dense(5, 1e-3, 50.0, true);
  const Solved r25 = implicit_step_against_dense(25, 1e-3, 50.0, true);
  EXPECT_LT(r25.rel_error, r5.rel_error);
  EXPECT_LT(r25.rel_error, 0.1) << "relative error " << r25.rel_error;
}

TEST(Implicit, ReportsTheIterationsDoneAndStopsAtTheFloatFloorUnlessAskedForAll) {
  sim::SceneDesc scene;
  scene.organs.push_back(test::organ("a", test::icosphere(2, 0.05)));
  scene.organs[0].material.model = sim::ModelKind::tmsm;
  scene.organs[0].material.stiffness = 50.0;
  scene.organs[0].fixed = {0, 1, 2};
  scene.integrator = sim::Integrator::implicit;
  scene.dt_s = 1e-4;  // mass-dominated: CG converges in a few iterations
  scene.gravity = true;
  scene.allow_sleep = false;
  scene.cg_iterations = 25;
  for (double tol : {1e-8, 0.0}) {
    scene.cg_tolerance = tol;
    const sim::Model m = sim::compile(scene);
    sim::State s = sim::make_state(m);
    sim::Work w = sim::make_work(m);
    for (int k = 0; k < 20; ++k) {
      const sim::StepReport rep = sim::step(m, s, w);
      ASSERT_EQ(rep.status, sim::StepStatus::ok);
      if (tol > 0) {
        EXPECT_GE(rep.cg_iterations, 1);
        EXPECT_LT(rep.cg_iterations, 25) << "the float CG stops at its floor";
      } else {
        EXPECT_EQ(rep.cg_iterations, 25) << "cg_tolerance 0: every iteration is done (restarts count)";
      }
    }
    EXPECT_TRUE(std::isfinite(s.z[m.nvert - 1]));
    EXPECT_LT(s.z[m.nvert - 1], m.vert_rest_z[m.nvert - 1] + 1e-3);
  }
}

}  // namespace
}  // namespace softatlas
