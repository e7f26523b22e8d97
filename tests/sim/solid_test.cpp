// The solid organ model (sim/solid.hpp): lattice and embedding, rest without drift, return after
// a pull, volume, energy, extreme cases (the grasp stiffness against the FEM reference: solid_slow_test.cpp).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <cstdlib>

#include "softatlas/sim/fem.hpp"
#include "softatlas/sim/sim.hpp"
#include "softatlas/sim/solid.hpp"
#include "solid_helpers.hpp"
#include "test_meshes.hpp"

namespace softatlas {
namespace {

using namespace solid_test;

TEST(SolidLattice, EmbedsEverySurfaceVertexExactly) {
  for (const char* name : {"meshes/liver_2000.obj", "meshes/liver_10000.obj"}) {
    const test::Mesh mesh = test::read_obj(test::project_data(name));
    std::vector<double> V = mesh.V;
    for (double& x : V) x *= 1e-3;
    const sim::SolidLattice L = sim::solid_lattice_budget(V, mesh.F, 300);
    EXPECT_LE(L.mesh.nnode(), 300);
    EXPECT_GE(L.mesh.nnode(), 100);
    const sim::fem::Model fm = sim::fem::compile(L.mesh, {});  // throws on a degenerate tetrahedron
    double inside = 0;
    for (int32_t t = 0; t < L.mesh.ntet(); ++t) inside += fm.tet_volume[t] * L.tet_fraction[t];
    double vol = 0;  // enclosed volume of the surface
    for (size_t f = 0; f < mesh.F.size(); f += 3) {
      const double* a = &V[3 * mesh.F[f]];
      const double* b = &V[3 * mesh.F[f + 1]];
      const double* c = &V[3 * mesh.F[f + 2]];
      vol += (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
              a[2] * (b[0] * c[1] - b[1] * c[0])) /
             6;
    }
    EXPECT_NEAR(inside / std::fabs(vol), 1.0, 0.05) << name;
    for (size_t v = 0; v < V.size() / 3; ++v) {
      ASSERT_GE(L.embed_tet[v], 0);
      const int32_t* n = &L.mesh.tets[4 * L.embed_tet[v]];
      double wsum = 0;
      for (int c = 0; c < 3; ++c) {
        double p = 0;
        for (int i = 0; i < 4; ++i) p += L.embed_w[4 * v + i] * L.mesh.nodes[3 * n[i] + c];
        EXPECT_NEAR(p, V[3 * v + c], 1e-12);
      }
      for (int i = 0; i < 4; ++i) {
        EXPECT_GE(L.embed_w[4 * v + i], -1e-12);
        wsum += L.embed_w[4 * v + i];
      }
      EXPECT_NEAR(wsum, 1.0, 1e-12);
    }
  }
}

TEST(SolidLattice, RejectsBadInput) {
  EXPECT_THROW(sim::solid_lattice({}, {}, 0.01), InputError);
  const test::Mesh cube = test::cube(0.1);
  EXPECT_THROW(sim::solid_lattice(cube.V, cube.F, 0.0), InputError);
  EXPECT_THROW(sim::solid_lattice(cube.V, cube.F, -1.0), InputError);
  sim::SceneDesc s;
  s.organs.push_back(test::organ("cube", cube));
  s.organs[0].material.model = sim::ModelKind::solid;
  s.organs[0].material.poisson_ratio = 0.5;
  EXPECT_THROW(sim::compile(s), InputError);
}

// (b) From rest plus a 1e-6 m random perturbation, nothing drifts: at most 0.01 mm over 10 s.
TEST(SolidModel, PerturbedRestDoesNotDrift) {
  for (double dt : {4e-3, 16e-3}) {
    const sim::Model m = sim::compile(liver_scene("meshes/liver_2000.obj", dt));
    sim::State s = sim::make_state(m);
    sim::Work w = sim::make_work(m);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (double& x : s.solid_x) x += 1e-6 * u(rng);
    double worst = 0;
    for (int k = 0; k < static_cast<int>(10.0 / dt); ++k) {
      sim::step(m, s, w);
      worst = std::max(worst, sim::max_displacement(m, s));
    }
    std::printf("solid rest drift dt %g: %.4f mm\n", dt, 1e3 * worst);
    EXPECT_LE(worst, 1e-5) << "dt " << dt;
  }
}

// (a) and (c): after a 30 mm pull and release the liver returns (residual < 1 mm 5 s after the
// release, once the rigid motion is removed; the value 2 s after is printed: docs/physics.md); the
// volume changes by at most 2 % during the pull. Three pull directions, each with the liver's
// support fixed or free in turn; the other three pulls are in the slow suite
// (SlowSolidModel.ReturnsAfterPullInEveryDirectionFixedAndFree).
TEST(SolidModel, ReturnsAfterPullAndKeepsVolume) {
  const double s2 = std::sqrt(0.5);
  expect_returns_after_pull({0, 1, 0}, true);
  expect_returns_after_pull({0, s2, s2}, false);
  expect_returns_after_pull({s2, 0, -s2}, true);
}

// An organ in two pieces (two spheres 60 mm apart) has a zero mode per piece: the Rayleigh
// damping's lowest shear mode must be the pieces' elastic one, not zero (which left it undamped).
TEST(SolidModel, OrganInTwoPiecesIsDamped) {
  test::Mesh a = test::icosphere(3, 0.02), b = a;
  const int32_t n = static_cast<int32_t>(a.V.size() / 3);
  for (size_t i = 0; i < b.V.size(); i += 3) b.V[i] += 0.06;
  a.V.insert(a.V.end(), b.V.begin(), b.V.end());
  for (int32_t f : b.F) a.F.push_back(f + n);
  sim::SceneDesc scene;
  sim::OrganDesc o = test::organ("two", a);
  o.material.model = sim::ModelKind::solid;
  scene.organs.push_back(o);
  const sim::Model m = sim::compile(scene);
  ASSERT_EQ(m.solids.size(), 1u);
  EXPECT_GT(m.solids[0].omega1_rad_s, 2 * kPi * 1.0) << sim::solid_plan(m.solids[0]);
  EXPECT_GT(m.solids[0].beta_s, 0.0);
}

double piece_volume(const sim::Model& m, const sim::State& s, size_t face_begin, size_t face_end) {
  double v = 0;
  for (size_t f = face_begin; f < face_end; ++f) {
    const int32_t a = m.face_vert[3 * f], b = m.face_vert[3 * f + 1], c = m.face_vert[3 * f + 2];
    v += (s.x[a] * (s.y[b] * s.z[c] - s.z[b] * s.y[c]) - s.y[a] * (s.x[b] * s.z[c] - s.z[b] * s.x[c]) +
          s.z[a] * (s.x[b] * s.y[c] - s.y[b] * s.x[c])) /
         6;
  }
  return v;
}

// A thin organ in two pieces keeps each piece's volume: the portal and splenic vein of the CT
// abdomen slab (data/meshes/ct_portal_vein.obj: 1,408 + 90 faces, 10-20 mm across, its organ set's
// 6 fixed vertices), pulled 30 mm anterior-inferior at its anterior-inferior end as `bench
// restore` does. Its lattice has 1-2 cells across; the cells' mean dilatation alone let it change
// by +6 %, and one constraint for the whole organ made the 90-face piece take up the large one's
// change (it did not come back: 2.9 mm). Within 2 % (the band is 0.5 %), and it comes back.
TEST(SolidModel, ThinOrganInTwoPiecesKeepsEachPiecesVolume) {
  const sim::SceneDesc scene =
      ct_solid_scene("portal_vein", "meshes/ct_portal_vein.obj", {24, 299, 329, 412, 558, 721});
  std::vector<int32_t> piece;  // each face's piece (the 90-face piece is the one the first face is not in)
  double v0[2] = {0, 0}, worst[2] = {0, 0};
  std::string plan;
  auto volumes = [&](const sim::Model& m, const sim::State& s, double out[2]) {
    out[0] = out[1] = 0;
    for (size_t f = 0; f < piece.size(); ++f)
      if (piece[f] >= 0) out[piece[f]] += piece_volume(m, s, f, f + 1);
  };
  auto on_step = [&](const sim::Model& m, const sim::State& s, int step) {
    if (step < 0) {
      ASSERT_EQ(m.solids.size(), 1u);
      EXPECT_EQ(m.solids[0].npiece, 2);
      plan = sim::solid_plan(m.solids[0]);
      piece.resize(m.face_vert.size() / 3);
      for (size_t f = 0; f < piece.size(); ++f) piece[f] = m.solids[0].vert_piece[m.face_vert[3 * f]];
      volumes(m, s, v0);
      return;
    }
    double v[2];
    volumes(m, s, v);
    for (int p = 0; p < 2; ++p) worst[p] = std::max(worst[p], std::fabs(v[p] / v0[p] - 1));
  };
  const double s2 = std::sqrt(0.5);
  const PullResult r = pull_release(scene, 0.030, {0, s2, -s2}, {0, s2, -s2}, 0.010, on_step);
  std::printf(
      "CT portal vein (%s): %zu grasped, volume change %.2f %% and %.2f %%, residual %.3f mm 2 s and %.3f mm 5 s "
      "after release\n",
      plan.c_str(), r.grasped, 100 * worst[0], 100 * worst[1], r.residual_mm, r.residual_end_mm);
  ASSERT_GT(r.grasped, 0u);
  EXPECT_TRUE(r.finite);
  EXPECT_LE(worst[0], 0.02);
  EXPECT_LE(worst[1], 0.02);
  EXPECT_LT(r.residual_mm, 1.0);
}

// A small thin organ held by two vertices keeps its volume: the right adrenal gland of the CT
// abdomen slab's `--organs all` build (data/meshes/ct_adrenal_gland_right.obj: 998 faces, 13 x 27
// x 23 mm, 2.4 mL, its build's 4 anchors), pulled 30 mm anterior-inferior by the two vertices of
// `bench restore`'s region (5 % of the box diagonal). Each step's local/global iterations took
// 4-9 % of its volume and the constraint gave it back; with at most 0.3 cell per node and step
// the constraint fell short in one step of the hold (bench restore: -4.15 %). Within 2 %, and it
// comes back.
TEST(SolidModel, SmallThinOrganHeldByTwoVerticesKeepsItsVolume) {
  const double s2 = std::sqrt(0.5);
  const PullResult r =
      pull_release(ct_solid_scene("adrenal_gland_right", "meshes/ct_adrenal_gland_right.obj", {72, 259, 363, 500}),
                   0.030, {0, s2, -s2}, {0, s2, -s2}, 0.00188);
  std::printf(
      "CT adrenal gland: %zu grasped, reached %.1f mm, volume change %.2f %%, residual %.3f mm 2 s after "
      "release\n",
      r.grasped, r.reached_mm, r.volume_change_run_pct, r.residual_mm);
  ASSERT_EQ(r.grasped, 2u);
  EXPECT_TRUE(r.finite);
  EXPECT_LE(r.volume_change_run_pct, 2.0);
  EXPECT_LT(r.residual_mm, 1.0);
}

// A hold next to an anchor: the CT pancreas (a slab 9 mm thick, its build's five anchors) pushed
// 20 mm along the outward normal at the vertex nearest the portal vein, every free vertex within
// 10 mm held, two of them 1.9 mm from an anchor (bench contact's push). Exact holds a tetrahedron
// from an anchor flung the slab's far side: 39 mm alone, 120 mm in its organ set; the vertices at
// the anchors are not held now (grasp_rows), and nothing moves much more than the push (21 mm).
TEST(SolidModel, HoldNextToAnAnchorDoesNotFling) {
  const sim::SceneDesc scene = ct_solid_scene("pancreas", "meshes/ct_pancreas.obj", {217, 224, 237, 340, 376});
  const sim::Model m = sim::compile(scene);
  ASSERT_EQ(m.solids.size(), 1u);
  const int32_t va = 370;  // nearest the portal vein
  auto rest = [&](int32_t v) { return Eigen::Vector3d(m.vert_rest_x[v], m.vert_rest_y[v], m.vert_rest_z[v]); };
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  for (size_t f = 0; f < m.face_vert.size() / 3; ++f) {
    const int32_t* fv = &m.face_vert[3 * f];
    if (fv[0] == va || fv[1] == va || fv[2] == va)
      normal += (rest(fv[1]) - rest(fv[0])).cross(rest(fv[2]) - rest(fv[0]));
  }
  normal *= m.organs[0].rest_volume_m3 < 0 ? -1.0 : 1.0;
  normal.normalize();
  std::vector<int32_t> patch;
  double nearest_anchor = INFINITY;
  for (int32_t v = 0; v < m.nvert; ++v) {
    if (m.vert_inv_mass[v] == 0 || (rest(v) - rest(va)).norm() > 0.010) continue;
    patch.push_back(v);
    for (int32_t f : scene.organs[0].fixed) nearest_anchor = std::min(nearest_anchor, (rest(v) - rest(f)).norm());
  }
  ASSERT_GT(patch.size(), 50u);
  EXPECT_LT(nearest_anchor, 2.5e-3);
  sim::State s = sim::make_state(m);
  sim::Work w = sim::make_work(m);
  const double push = 0.020;
  sim::attach(m, s, patch, {push * normal.x(), push * normal.y(), push * normal.z()}, 62);
  double worst = 0.0;
  for (int k = 0; k < 125; ++k) {
    sim::step(m, s, w);
    for (int32_t v = 0; v < m.nvert; ++v)
      worst = std::max(worst, (Eigen::Vector3d(s.x[v], s.y[v], s.z[v]) - rest(v)).norm());
  }
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (int32_t v : patch) mean += Eigen::Vector3d(s.x[v], s.y[v], s.z[v]) - rest(v);
  mean /= static_cast<double>(patch.size());
  std::printf(
      "CT pancreas pushed 20 mm next to two anchors: held patch moved %.1f mm along the push, "
      "largest displacement %.1f mm\n",
      1e3 * mean.dot(normal), 1e3 * worst);
  EXPECT_GT(mean.dot(normal), 0.5 * push);  // the patch follows the push
  EXPECT_LT(worst, 1.5 * push);             // and nothing is flung (39 mm with the exact holds there)
}

// The supported paper liver at dt 5 ms, with the region at its top to grasp.
struct LiverRun {
  sim::SceneDesc scene = liver_scene("meshes/liver_2000.obj", 5e-3);
  sim::Model m = sim::compile(scene);
  sim::State s = sim::make_state(m);
  sim::Work w = sim::make_work(m);
  std::vector<int32_t> grasp = global(m, region(scene.organs[0], {0, 1, 0}, 0.012));
};

// (e) Without external work the energy never grows: a pulled liver released, 6 s unloaded.
TEST(SolidModel, EnergyNeverGrowsUnloaded) {
  LiverRun run;
  auto& [scene, m, s, w, grasp] = run;
  sim::attach(m, s, grasp, {0.0, 0.02, 0.02}, 60);
  for (int k = 0; k < 100; ++k) sim::step(m, s, w);
  sim::release(s);
  double prev = sim::total_energy(m, s);
  const double e0 = prev;
  int grew = 0;
  double worst = 0;
  for (int k = 0; k < 1200; ++k) {
    sim::step(m, s, w);
    const double e = sim::total_energy(m, s);
    if (e > prev + 1e-9 * e0) ++grew, worst = std::max(worst, (e - prev) / e0);
    prev = e;
  }
  std::printf("solid energy: start %.4g J, end %.4g J, %d growing steps (worst %.3g of start)\n", e0, prev, grew,
              worst);
  EXPECT_GT(e0, 0);
  EXPECT_EQ(grew, 0);
  EXPECT_LT(prev, 1e-3 * e0);
}

// (f) Stiff and extreme cases stay finite: E = 1 MPa, dt = 16 ms, a 100 mm pull.
TEST(SolidModel, ExtremeCasesStayFinite) {
  for (const auto& [young, dt] : std::vector<std::pair<double, double>>{{4000.0, 16e-3}, {1e6, 16e-3}, {1e6, 4e-3}}) {
    const PullResult r = pull_release(liver_scene("meshes/liver_2000.obj", dt, young), 0.100, {0, 1, 0});
    std::printf("solid E %g dt %g 100 mm: reached %.1f mm, residual %.3f mm, volume %.2f %%, peak %.3f N\n", young, dt,
                r.reached_mm, r.residual_mm, r.volume_change_pct, r.peak_force_N);
    EXPECT_TRUE(r.finite);
    EXPECT_GE(r.reached_mm, 80.0);
    EXPECT_LT(r.residual_end_mm, 2.0);
  }
}

// Organs solved on two worker threads give the same states as one thread (every organ's loads
// are gathered before any organ moves), with a connection between the two organs. Not bit for
// bit: with -march=native on AVX-512 the vectorised reductions (Eigen on std::vector memory)
// peel by the heap address's alignment, so even two one-thread runs differ in the last bits
// (4 of 6 repeats, up to 1e-12 of the motion after 60 steps; never in a build without
// SOFTATLAS_NATIVE); 1e-9 of the motion (20 pm) is far above
// that and far below anything a race between organs would leave.
TEST(SolidModel, TwoThreadsMatchOneThread) {
  std::vector<std::vector<double>> result;
  for (int threads : {1, 2}) {
    sim::SceneDesc scene = liver_scene("meshes/liver_2000.obj", 8e-3);
    sim::OrganDesc second = scene.organs[0];
    second.name = "liver_copy";
    for (size_t i = 0; i < second.vertices.size(); i += 3) second.vertices[i] += 0.2;
    scene.organs.push_back(second);
    sim::ConnectionDesc c;
    c.organ_a = 0, c.vertex_a = 0, c.organ_b = 1, c.vertex_b = 0, c.rest_length_m = 0.2, c.stiffness = 50.0;
    scene.connections.push_back(c);
    scene.threads = threads;
    const sim::Model m = sim::compile(scene);
    sim::State s = sim::make_state(m);
    sim::Work w = sim::make_work(m);
    sim::attach(m, s, global(m, region(scene.organs[0], {0, 1, 0}, 0.012)), {0, 0.02, 0}, 30);
    if (threads == 1) result.resize(3), result[2] = s.solid_x;  // rest, for the motion's size
    for (int k = 0; k < 60; ++k) sim::step(m, s, w);
    result[threads - 1] = s.solid_x;
  }
  ASSERT_EQ(result[0].size(), result[1].size());
  double motion = 0.0;
  for (size_t i = 0; i < result[2].size(); ++i) motion = std::max(motion, std::abs(result[0][i] - result[2][i]));
  ASSERT_GT(motion, 1e-3) << "the pull moved the lattice";
  for (size_t i = 0; i < result[0].size(); ++i) ASSERT_NEAR(result[0][i], result[1][i], 1e-9 * motion) << i;
}

// The tool's force mode moves the organ towards the force and the reaction is its opposite.
TEST(SolidModel, ForcePullMovesAlongTheForce) {
  LiverRun run;
  auto& [scene, m, s, w, grasp] = run;
  sim::pull_force(m, s, grasp, {0, 0.2, 0});
  for (int k = 0; k < 600; ++k) sim::step(m, s, w);
  double dy = 0;
  for (int32_t v : grasp) dy += s.y[v] - m.vert_rest_y[v];
  dy /= grasp.size();
  const auto F = sim::tool_reaction(s);
  std::printf("solid force 0.2 N: grasp moved %.2f mm (%.1f N/m)\n", 1e3 * dy, 0.2 / dy);
  EXPECT_GT(dy, 1e-3);
  EXPECT_NEAR(F[1], -0.2, 1e-12);
}

}  // namespace
}  // namespace softatlas
