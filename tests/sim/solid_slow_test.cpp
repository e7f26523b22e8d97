// The solid model's grasp stiffness against the static FEM reference (quadratic tetrahedra,
// neo-Hookean: sim/fem_quadratic.hpp) on a voxel mesh of the same surface (ctest label `slow`).
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "softatlas/sim/fem.hpp"
#include "softatlas/sim/fem_quadratic.hpp"
#include "softatlas/sim/sim.hpp"
#include "softatlas/sim/solid.hpp"
#include "solid_helpers.hpp"
#include "test_meshes.hpp"

namespace softatlas {
namespace {

using namespace solid_test;

// The static FEM reference (fem_quadratic.cpp) on a voxel mesh of the same surface: cells
// of `cell_m` whose centre is inside, boundary nodes in the support slab fixed, boundary nodes
// within `radius` of the grasp point moved by `disp`. Returns the reaction's magnitude / |disp|.
double fem_grasp_stiffness(const sim::OrganDesc& o, double cell_m, const std::array<double, 3>& centre, double radius,
                           const std::array<double, 3>& disp, int* nodes = nullptr) {
  const sim::SolidLattice L = sim::solid_lattice(o.vertices, o.faces, cell_m);
  sim::fem::TetMesh mesh;
  std::vector<int32_t> remap(L.mesh.nnode(), -1);
  for (int32_t t = 0; t < L.mesh.ntet(); ++t) {
    if (L.tet_fraction[t] < 0.5) continue;
    for (int i = 0; i < 4; ++i) {
      int32_t& r = remap[L.mesh.tets[4 * t + i]];
      if (r < 0) {
        r = mesh.nnode();
        for (int c = 0; c < 3; ++c) mesh.nodes.push_back(L.mesh.nodes[3 * L.mesh.tets[4 * t + i] + c]);
      }
      mesh.tets.push_back(r);
    }
  }
  sim::fem::Material material;  // the organ's own E and nu
  material.young_modulus_pa = o.material.young_modulus_pa;
  material.poisson_ratio = o.material.poisson_ratio;
  const sim::fem::QuadraticModel fm = sim::fem::compile_quadratic(mesh, material);
  std::vector<uint8_t> boundary(mesh.nnode(), 0);
  for (int32_t v : sim::fem::boundary_faces(mesh)) boundary[v] = 1;
  double lo = INFINITY, hi = -INFINITY;
  for (size_t i = 0; i < o.vertices.size() / 3; ++i)
    lo = std::min(lo, o.vertices[3 * i + 1]), hi = std::max(hi, o.vertices[3 * i + 1]);
  std::vector<int32_t> fixed, grasp;
  for (int32_t n = 0; n < mesh.nnode(); ++n) {
    if (!boundary[n]) continue;
    const double* p = &mesh.nodes[3 * n];
    if (p[1] <= lo + 0.1 * (hi - lo)) fixed.push_back(n);
    const double d2 = std::pow(p[0] - centre[0], 2) + std::pow(p[1] - centre[1], 2) + std::pow(p[2] - centre[2], 2);
    if (d2 <= radius * radius) grasp.push_back(n);
  }
  fixed = sim::fem::quadratic_region(fm, fixed);
  grasp = sim::fem::quadratic_region(fm, grasp);
  sim::fem::Load load = sim::fem::make_load(fm);
  sim::fem::fix_nodes(load, fixed, {0, 0, 0});
  sim::fem::fix_nodes(load, grasp, disp);
  std::vector<double> x = fm.rest;
  sim::fem::StaticOptions opt;
  opt.load_steps = 2;
  opt.tolerance = 1e-8;
  EXPECT_TRUE(sim::fem::solve_static(fm, load, x, opt).converged);
  const auto F = sim::fem::reaction_force(fm, x, grasp);
  if (nodes) *nodes = fm.nnode;
  return std::sqrt(F[0] * F[0] + F[1] * F[1] + F[2] * F[2]) /
         std::sqrt(disp[0] * disp[0] + disp[1] * disp[1] + disp[2] * disp[2]);
}

// (d) The grasp stiffness of a liver with E = 4 kPa against the static quadratic FEM on a voxel
// mesh of the same surface (same support, same grasp radius, 10 mm displacement), at two cell
// sizes to show the reference is converged.
TEST(SolidModel, GraspStiffnessMatchesTheFemReference) {
  sim::SceneDesc scene = liver_scene("meshes/liver_2000.obj", 5e-3);
  std::array<double, 3> centre;
  const double radius = 0.015;
  const std::vector<int32_t> src = region(scene.organs[0], {0, 1, 0}, radius, &centre);
  for (const std::array<double, 3>& disp : std::vector<std::array<double, 3>>{{0, 0.01, 0}, {0.01, 0, 0}}) {
    int ref_nodes = 0;
    const double k_ref = fem_grasp_stiffness(scene.organs[0], 0.008, centre, radius, disp, &ref_nodes);
    const double k_ref_coarse = fem_grasp_stiffness(scene.organs[0], 0.012, centre, radius, disp);
    const char* budget = std::getenv("SOLID_NODES");
    if (budget) scene.organs[0].material.solid_nodes = std::atoi(budget);
    const sim::Model m = sim::compile(scene);
    sim::State s = sim::make_state(m);
    sim::Work w = sim::make_work(m);
    sim::attach(m, s, global(m, src), disp, 100);
    for (int k = 0; k < 800; ++k) sim::step(m, s, w);
    const auto F = sim::tool_reaction(s);
    const double k_solid = std::sqrt(F[0] * F[0] + F[1] * F[1] + F[2] * F[2]) / 0.01;
    std::printf(
        "grasp stiffness disp (%g %g %g) mm: solid (%d nodes) %.1f N/m, FEM reference %.1f N/m (%d nodes), "
        "%.1f N/m (12 mm cells); solid / reference %.2f\n",
        1e3 * disp[0], 1e3 * disp[1], 1e3 * disp[2], m.solids[0].nnode, k_solid, k_ref, ref_nodes, k_ref_coarse,
        k_solid / k_ref);
    // Measured against this reference (8 mm cells: 41.6 / 24.4 N/m; 12 mm: 39.8 / 24.0) with the
    // default budget (386 nodes), the grasp one constraint per lattice tetrahedron on the mean of
    // its held vertices: 2.38x / 2.39x. One constraint per held vertex: 2.86x / 2.63x (it fixed
    // every cell the patch touches); one on the whole patch's mean: 1.88x / 1.87x, but the thin
    // pancreas then came back too slowly (bench restore residual 1.10 mm). The rest is the coarse
    // lattice (docs/physics.md).
    EXPECT_GT(k_solid, 0.8 * k_ref);
    EXPECT_LT(k_solid, 2.7 * k_ref);
  }
}

// The three pulls of SolidModel.ReturnsAfterPullAndKeepsVolume with the other support (fixed where
// the fast test has it free and the reverse).
TEST(SlowSolidModel, ReturnsAfterPullInEveryDirectionFixedAndFree) {
  const double s2 = std::sqrt(0.5);
  expect_returns_after_pull({0, 1, 0}, false);
  expect_returns_after_pull({0, s2, s2}, true);
  expect_returns_after_pull({s2, 0, -s2}, false);
}

}  // namespace
}  // namespace softatlas
