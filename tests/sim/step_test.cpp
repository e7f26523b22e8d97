// The step: force-free rest shapes, forces as energy gradients, Newton's third law, no
// allocation.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>
#include <random>

#include "softatlas/sim/sim.hpp"
#include "test_meshes.hpp"

// Counts every allocation in this test binary, so that the step can be shown not to allocate.
static std::atomic<long> g_allocations{0};
void* operator new(std::size_t n) {
  ++g_allocations;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) { return operator new(n); }
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  ++g_allocations;
  return std::malloc(n ? n : 1);
}
void* operator new[](std::size_t n, const std::nothrow_t& t) noexcept { return operator new(n, t); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }

namespace softatlas {
namespace {

struct Config {
  sim::ModelKind model;
  int p;
  sim::Integrator integrator;
};

sim::SceneDesc sphere_scene(const Config& c, double radius = 0.05) {
  sim::SceneDesc s;
  s.organs.push_back(test::organ("sphere", test::icosphere(2, radius)));
  sim::Material& m = s.organs[0].material;
  m.model = c.model;
  m.elastica_p = c.p;
  m.elastica_b = c.p == 2 ? 1.0 : 0.5;
  if (c.model == sim::ModelKind::flexion) m.flexion_stiffness = 1e-3, m.volume_stiffness = 0.5;
  s.integrator = c.integrator;
  s.dt_s = 1e-3;
  s.gravity = false;
  s.allow_sleep = false;
  return s;
}

const Config kConfigs[] = {
    {sim::ModelKind::tmsm, 1, sim::Integrator::verlet},
    {sim::ModelKind::tmsm, 1, sim::Integrator::semi_implicit},
    {sim::ModelKind::tmsm, 1, sim::Integrator::implicit},
    {sim::ModelKind::cmsm, 1, sim::Integrator::semi_implicit},
    {sim::ModelKind::nmsm, 1, sim::Integrator::verlet},
    {sim::ModelKind::nmsm, 1, sim::Integrator::semi_implicit},
    {sim::ModelKind::nmsm, 2, sim::Integrator::semi_implicit},
    {sim::ModelKind::nmsm, 1, sim::Integrator::implicit},
    {sim::ModelKind::flexion, 1, sim::Integrator::semi_implicit},
    {sim::ModelKind::flexion, 1, sim::Integrator::implicit},
};

void perturb(sim::State& s, double amount, unsigned seed);  // below

// Every model starts 1 um off its rest shape (each coordinate, random, fixed seed): a model that
// feeds energy in drifts away (the paper's literal elastica drifts 1-5 mm from 1 um).
TEST(Step, RestShapeStaysAtRestFromAPerturbedStateForEveryModelAndIntegrator) {
  for (const Config& c : kConfigs) {
    const sim::Model m = sim::compile(sphere_scene(c));
    sim::State s = sim::make_state(m);
    sim::Work w = sim::make_work(m);
    perturb(s, 1e-6, 3);
    for (int k = 0; k < 10000; ++k) sim::step(m, s, w);
    EXPECT_LT(sim::max_displacement(m, s), 5e-6)
        << sim::to_string(c.model) << " p=" << c.p << " " << sim::to_string(c.integrator);
  }
}

TEST(Step, RestShapeOfARealLiverIsForceFreeWithTheLiteralElastica) {
  test::Mesh liver = test::read_obj(test::project_data("meshes/liver_1000.obj"));
  sim::SceneDesc s;
  s.organs.push_back(test::organ("liver", liver, 1e-3));
  s.organs[0].material.elastica_b = 0.5;
  s.organs[0].material.elastica_literal = true;
  s.allow_sleep = false;
  const sim::Model m = sim::compile(s);
  sim::State st = sim::make_state(m);
  sim::Work w = sim::make_work(m);
  for (int k = 0; k < 10000; ++k) sim::step(m, st, w);
  EXPECT_LT(sim::max_displacement(m, st), 1e-9 * m.size_m);
}

TEST(Step, ConservativeElasticaLiverStaysPutFromAPerturbedRest) {
  test::Mesh liver = test::read_obj(test::project_data("meshes/liver_1000.obj"));
  sim::SceneDesc s;
  s.organs.push_back(test::organ("liver", liver, 1e-3));
  s.organs[0].material.elastica_b = 0.5;
  s.allow_sleep = false;
  const sim::Model m = sim::compile(s);
  sim::State st = sim::make_state(m);
  sim::Work w = sim::make_work(m);
  perturb(st, 1e-6, 5);
  for (int k = 0; k < 10000; ++k) sim::step(m, st, w);
  EXPECT_LT(sim::max_displacement(m, st), 5e-6);
}

// E = sum 1/2 k (l - l0)^2 + sum 1/2 kf (theta - theta0)^2
double potential(const sim::Model& m, const sim::State& s) {
  sim::State z = s;
  std::fill(z.vx.begin(), z.vx.end(), 0.0);
  std::fill(z.vy.begin(), z.vy.end(), 0.0);
  std::fill(z.vz.begin(), z.vz.end(), 0.0);
  double e = sim::total_energy(m, z);
  for (int32_t f = 0; f < m.nflex; ++f) {
    auto P = [&](int32_t v) { return std::array<double, 3>{s.x[v], s.y[v], s.z[v]}; };
    const auto a = P(m.flex_a[f]), b = P(m.flex_b[f]), c = P(m.flex_c[f]), d = P(m.flex_d[f]);
    const double t = sim::dihedral_angle(a.data(), b.data(), c.data(), d.data()) - m.flex_rest_angle[f];
    e += 0.5 * m.flex_k[f] * t * t;
  }
  return e;
}

void perturb(sim::State& s, double amount, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-amount, amount);
  for (size_t v = 0; v < s.x.size(); ++v) s.x[v] += u(rng), s.y[v] += u(rng), s.z[v] += u(rng);
}

TEST(Step, SpringForcesAreMinusTheEnergyGradient) {
  for (sim::ModelKind kind : {sim::ModelKind::tmsm, sim::ModelKind::flexion}) {
    sim::SceneDesc scene = sphere_scene({kind, 1, sim::Integrator::semi_implicit});
    scene.organs[0].material.damping = 0.0;
    scene.organs[0].material.volume_stiffness = 0.0;
    const sim::Model m = sim::compile(scene);
    sim::State s = sim::make_state(m);
    sim::Work w = sim::make_work(m);
    perturb(s, 0.004, 7);
    sim::compute_internal_forces(m, s, w);
    double max_err = 0, max_f = 0;
    for (int32_t v = 0; v < m.nvert; v += 7) {
      for (int c = 0; c < 3; ++c) {
        std::vector<double>& X = c == 0 ? s.x : c == 1 ? s.y : s.z;
        const double h = 1e-7, x0 = X[v];
        X[v] = x0 + h;
        const double ep = potential(m, s);
        X[v] = x0 - h;
        const double em = potential(m, s);
        X[v] = x0;
        const double fd = -(ep - em) / (2 * h);
        const double f = c == 0 ? w.fx[v] : c == 1 ? w.fy[v] : w.fz[v];
        max_err = std::max(max_err, std::abs(fd - f));
        max_f = std::max(max_f, std::abs(f));
      }
    }
    EXPECT_LT(max_err, 1e-5 * max_f) << sim::to_string(kind) << " max |f| " << max_f;
  }
}

double kinetic(const sim::Model& m, const sim::State& s) {
  double e = 0;
  for (int32_t v = 0; v < m.nvert; ++v)
    e += 0.5 * m.vert_mass[v] * (s.vx[v] * s.vx[v] + s.vy[v] * s.vy[v] + s.vz[v] * s.vz[v]);
  return e;
}

// The conservative models (Hooke, the conservative elastica, flexion springs) with their damping:
// over a long unloaded run from a perturbed shape the energy never rises above where it started
// (no external work), and the damping takes nearly all of it away.
TEST(Step, ConservativeModelsNeverGainEnergyWithoutExternalWork) {
  for (sim::ModelKind kind : {sim::ModelKind::tmsm, sim::ModelKind::nmsm, sim::ModelKind::flexion})
    for (sim::Integrator integ : {sim::Integrator::semi_implicit, sim::Integrator::implicit}) {
      sim::SceneDesc scene = sphere_scene({kind, 1, integ});
      scene.organs[0].material.volume_stiffness = 0.0;  // a projection, not a potential
      const sim::Model m = sim::compile(scene);
      sim::State s = sim::make_state(m);
      sim::Work w = sim::make_work(m);
      perturb(s, 1e-3, 11);
      const double e0 = potential(m, s);
      double e_max = 0, e = e0;
      for (int k = 0; k < 20000; ++k) {
        sim::step(m, s, w);
        if (k % 10 == 0) e = potential(m, s) + kinetic(m, s), e_max = std::max(e_max, e);
      }
      EXPECT_LE(e_max, e0 * (1 + 1e-6)) << sim::to_string(kind) << " " << sim::to_string(integ);
      EXPECT_LT(e, 1e-3 * e0) << sim::to_string(kind) << " " << sim::to_string(integ);
    }
}

TEST(Step, InternalForcesHaveZeroSumAndZeroTorque) {
  for (const Config& c : kConfigs) {
    sim::SceneDesc scene = sphere_scene(c);
    scene.organs.push_back(test::organ("moon", test::icosphere(1, 0.01)));
    for (double& x : scene.organs[1].vertices) x += 0.08;
    scene.connections.push_back({0, 3, 1, 5, 0.02, 10.0});
    const sim::Model m = sim::compile(scene);
    sim::State s = sim::make_state(m);
    sim::Work w = sim::make_work(m);
    perturb(s, 0.005, 11);
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-0.1, 0.1);
    for (size_t v = 0; v < s.vx.size(); ++v) s.vx[v] = u(rng), s.vy[v] = u(rng), s.vz[v] = u(rng);
    std::array<double, 3> F, T;
    sim::internal_force_and_torque(m, s, w, F, T);
    double scale = 0;
    for (int32_t v = 0; v < m.nvert; ++v) scale += std::abs(w.fx[v]) + std::abs(w.fy[v]) + std::abs(w.fz[v]);
    for (int k = 0; k < 3; ++k) {
      EXPECT_LT(std::abs(F[k]), 1e-12 * scale) << sim::to_string(c.model);
      EXPECT_LT(std::abs(T[k]), 1e-12 * scale) << sim::to_string(c.model);
    }
  }
}

TEST(Step, DoesNotAllocate) {
  for (const Config& c : kConfigs) {
    sim::SceneDesc scene = sphere_scene(c);
    const sim::Model m = sim::compile(scene);
    sim::State s = sim::make_state(m);
    sim::Work w = sim::make_work(m);
    sim::attach(m, s, {0, 1, 2}, {0.0, 0.01, 0.01}, 30);
    sim::step(m, s, w);  // first step may size the attachment buffer
    const long before = g_allocations.load();
    for (int k = 0; k < 100; ++k) sim::step(m, s, w);  // attached
    const long after_attach = g_allocations.load();
    sim::pull_force(m, s, {5, 6}, {0.0, 0.0, 1e-3});  // starting a pull may allocate
    const long mid = g_allocations.load();
    for (int k = 0; k < 100; ++k) sim::step(m, s, w);  // pulling
    EXPECT_EQ(after_attach - before, 0) << sim::to_string(c.model) << " " << sim::to_string(c.integrator);
    EXPECT_EQ(g_allocations.load() - mid, 0) << sim::to_string(c.model) << " " << sim::to_string(c.integrator);
  }
}

TEST(Step, RestingOrganSleepsAndTheToolWakesIt) {
  sim::SceneDesc scene = sphere_scene({sim::ModelKind::tmsm, 1, sim::Integrator::semi_implicit});
  scene.allow_sleep = true;
  scene.sleep_steps = 10;
  const sim::Model m = sim::compile(scene);
  sim::State s = sim::make_state(m);
  sim::Work w = sim::make_work(m);
  for (int k = 0; k < 20; ++k) sim::step(m, s, w);
  EXPECT_EQ(s.organ_awake[0], 0);
  sim::pull_force(m, s, {0}, {0, 0, 1e-2});
  EXPECT_EQ(s.organ_awake[0], 1);
  for (int k = 0; k < 20; ++k) sim::step(m, s, w);
  EXPECT_GT(sim::max_displacement(m, s), 0.0);
}

}  // namespace
}  // namespace softatlas

namespace softatlas {
namespace {

TEST(Step, TwoThreadsGiveBitwiseTheSameStateAndDoNotAllocate) {
  sim::SceneDesc scene = sphere_scene({sim::ModelKind::nmsm, 1, sim::Integrator::semi_implicit});
  scene.organs.push_back(test::organ("moon", test::icosphere(2, 0.02)));
  for (double& x : scene.organs[1].vertices) x += 0.08;
  scene.organs.push_back(test::organ("star", test::icosphere(1, 0.02)));
  for (double& x : scene.organs[2].vertices) x -= 0.08;
  scene.connections.push_back({0, 3, 1, 5, 0.02, 10.0});
  scene.gravity = true;
  scene.organs[0].fixed = {0, 1, 2};
  scene.organs[1].fixed = {0};
  scene.organs[2].fixed = {0};
  auto run = [&](int threads, long* allocations) {
    sim::SceneDesc sc = scene;
    sc.threads = threads;
    const sim::Model m = sim::compile(sc);
    sim::State s = sim::make_state(m);
    sim::Work w = sim::make_work(m);
    sim::pull_force(m, s, {sim::global_vertex(m, 0, 40)}, {0, 0, 0.05});
    sim::step(m, s, w);
    const long before = g_allocations.load();
    for (int k = 0; k < 500; ++k) sim::step(m, s, w);
    *allocations = g_allocations.load() - before;
    return s;
  };
  // explicit (organs on the workers) and implicit (setup per organ with per-thread scratch, one
  // CG per connected component on the workers)
  for (sim::Integrator integ : {sim::Integrator::semi_implicit, sim::Integrator::implicit}) {
    scene.integrator = integ;
    long a1 = 0, a2 = 0;
    const sim::State one = run(1, &a1), two = run(2, &a2);
    EXPECT_EQ(one.x, two.x) << sim::to_string(integ);
    EXPECT_EQ(one.vz, two.vz) << sim::to_string(integ);
    EXPECT_EQ(a2, 0) << sim::to_string(integ);
  }
}

}  // namespace
}  // namespace softatlas
