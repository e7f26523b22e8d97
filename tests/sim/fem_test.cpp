// The FEM reference against closed forms: a compressed block (uniaxial stress, exact for linear
// tetrahedra), a cantilever (Timoshenko beam, converging under refinement), rotation invariance
// of the corotational formulation, dynamics settling on the static solution, and the Gmsh reader
// on the SOFA liver.
#include "softatlas/sim/fem.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <set>

#include "softatlas/sim/error.hpp"

namespace fem = softatlas::sim::fem;

namespace {

std::vector<int32_t> nodes_where(const fem::TetMesh& mesh, int axis, double value) {
  std::vector<int32_t> out;
  for (int32_t i = 0; i < mesh.nnode(); ++i)
    if (std::abs(mesh.nodes[3 * i + axis] - value) < 1e-12) out.push_back(i);
  return out;
}

// Consistent nodal forces of a uniform traction on the boundary faces lying in plane axis=value.
void add_traction(const fem::TetMesh& mesh, fem::Load& load, int axis, double value,
                  const std::array<double, 3>& traction_pa) {
  const std::vector<int32_t> faces = fem::boundary_faces(mesh);
  for (size_t f = 0; f < faces.size() / 3; ++f) {
    bool on = true;
    for (int k = 0; k < 3; ++k) on = on && std::abs(mesh.nodes[3 * faces[3 * f + k] + axis] - value) < 1e-12;
    if (!on) continue;
    double e1[3], e2[3];
    for (int c = 0; c < 3; ++c) {
      e1[c] = mesh.nodes[3 * faces[3 * f + 1] + c] - mesh.nodes[3 * faces[3 * f] + c];
      e2[c] = mesh.nodes[3 * faces[3 * f + 2] + c] - mesh.nodes[3 * faces[3 * f] + c];
    }
    const double cx = e1[1] * e2[2] - e1[2] * e2[1], cy = e1[2] * e2[0] - e1[0] * e2[2],
                 cz = e1[0] * e2[1] - e1[1] * e2[0];
    const double area = 0.5 * std::sqrt(cx * cx + cy * cy + cz * cz);
    for (int k = 0; k < 3; ++k)
      for (int c = 0; c < 3; ++c) load.force[3 * faces[3 * f + k] + c] += traction_pa[c] * area / 3.0;
  }
}

double cantilever_tip_deflection(int n, fem::Elasticity elasticity, double P, double* analytic) {
  const double L = 0.1, h = 0.01, E = 1e5, nu = 0.3;
  const fem::TetMesh mesh = fem::box_mesh(L, h, h, 10 * n, n, n);
  fem::Material mat;
  mat.young_modulus_pa = E;
  mat.poisson_ratio = nu;
  mat.elasticity = elasticity;
  const fem::Model model = fem::compile(mesh, mat);
  fem::Load load = fem::make_load(model);
  fem::fix_nodes(load, nodes_where(mesh, 0, 0.0), {0, 0, 0});
  add_traction(mesh, load, 0, L, {0, 0, -P / (h * h)});
  std::vector<double> x = model.rest;
  fem::StaticOptions opt;
  opt.load_steps = 2;
  EXPECT_TRUE(fem::solve_static(model, load, x, opt).converged);
  const std::vector<int32_t> tip = nodes_where(mesh, 0, L);
  double uz = 0.0;
  for (int32_t i : tip) uz += x[3 * i + 2] - model.rest[3 * i + 2];
  const double I = h * h * h * h / 12.0, G = E / (2 * (1 + nu));
  *analytic = P * L * L * L / (3 * E * I) + P * L / (5.0 / 6.0 * G * h * h);  // Timoshenko
  return -uz / static_cast<double>(tip.size());
}

}  // namespace

TEST(Fem, CompressedBlockMatchesUniaxialStressExactly) {
  const double lx = 0.02, ly = 0.02, lz = 0.04, E = 4000.0, nu = 0.45, p = 50.0;
  const fem::TetMesh mesh = fem::box_mesh(lx, ly, lz, 2, 3, 4);
  fem::Material mat;
  mat.young_modulus_pa = E;
  mat.poisson_ratio = nu;
  mat.elasticity = fem::Elasticity::linear;
  const fem::Model model = fem::compile(mesh, mat);
  fem::Load load = fem::make_load(model);
  // Symmetry planes: u_x = 0 on x = 0, u_y = 0 on y = 0, u_z = 0 on z = 0.
  for (int axis = 0; axis < 3; ++axis)
    for (int32_t i : nodes_where(mesh, axis, 0.0)) load.dof_fixed[3 * i + axis] = 1;
  add_traction(mesh, load, 2, lz, {0, 0, -p});
  std::vector<double> x = model.rest;
  ASSERT_TRUE(fem::solve_static(model, load, x).converged);
  for (int32_t i = 0; i < model.nnode; ++i) {
    const double* X = &model.rest[3 * i];
    // u_z = -p z / E, u_x = nu p x / E, u_y = nu p y / E
    EXPECT_NEAR(x[3 * i + 2] - X[2], -p * X[2] / E, 1e-12);
    EXPECT_NEAR(x[3 * i + 0] - X[0], nu * p * X[0] / E, 1e-12);
    EXPECT_NEAR(x[3 * i + 1] - X[1], nu * p * X[1] / E, 1e-12);
  }
}

TEST(Fem, CantileverConvergesToTimoshenkoUnderRefinement) {
  double analytic = 0.0;
  double prev_err = 1.0;
  for (int n : {1, 2, 3}) {
    const double d = cantilever_tip_deflection(n, fem::Elasticity::linear, 1e-3, &analytic);
    const double err = std::abs(d - analytic) / analytic;
    EXPECT_LT(err, prev_err) << "n = " << n;  // linear tets lock in bending: error falls with n
    EXPECT_LT(d, analytic * 1.01);            // and the stiff elements under-estimate deflection
    prev_err = err;
  }
  EXPECT_LT(prev_err, 0.35);
}

TEST(Fem, CorotationalMatchesLinearForSmallLoadsAndIsRotationInvariant) {
  double analytic = 0.0;
  const double lin = cantilever_tip_deflection(1, fem::Elasticity::linear, 1e-5, &analytic);
  const double cor = cantilever_tip_deflection(1, fem::Elasticity::corotational, 1e-5, &analytic);
  EXPECT_NEAR(cor, lin, 1e-3 * lin);

  const fem::TetMesh mesh = fem::box_mesh(0.03, 0.02, 0.01, 3, 2, 1);
  fem::Material mat;
  const fem::Model cmodel = fem::compile(mesh, mat);
  mat.elasticity = fem::Elasticity::linear;
  const fem::Model lmodel = fem::compile(mesh, mat);
  // Rotate the rest shape by 60 degrees about z: no corotational force, a large linear one.
  std::vector<double> x = cmodel.rest;
  const double c = std::cos(M_PI / 3), s = std::sin(M_PI / 3);
  for (int32_t i = 0; i < cmodel.nnode; ++i) {
    const double px = x[3 * i], py = x[3 * i + 1];
    x[3 * i] = c * px - s * py;
    x[3 * i + 1] = s * px + c * py;
  }
  std::vector<double> fc, fl;
  fem::internal_forces(cmodel, x, fc);
  fem::internal_forces(lmodel, x, fl);
  double nc = 0, nl = 0;
  for (size_t k = 0; k < fc.size(); ++k) {
    nc = std::max(nc, std::abs(fc[k]));
    nl = std::max(nl, std::abs(fl[k]));
  }
  EXPECT_LT(nc, 1e-10 * nl);
  EXPECT_GT(nl, 1e-3);
}

TEST(Fem, DampedDynamicsSettlesOnTheStaticSolution) {
  const fem::TetMesh mesh = fem::box_mesh(0.04, 0.01, 0.01, 8, 2, 2);
  fem::Material mat;
  mat.young_modulus_pa = 2e4;
  mat.rayleigh_mass = 5.0;
  mat.rayleigh_stiffness = 0.01;
  const fem::Model model = fem::compile(mesh, mat);
  fem::Load load = fem::make_load(model);
  fem::fix_nodes(load, nodes_where(mesh, 0, 0.0), {0, 0, 0});
  fem::add_force(load, nodes_where(mesh, 0, 0.04), {0, 0, -2e-3});
  std::vector<double> xs = model.rest;
  ASSERT_TRUE(fem::solve_static(model, load, xs).converged);
  fem::State st = fem::make_state(model);
  for (int i = 0; i < 400; ++i) fem::step_implicit(model, load, st, 5e-3);
  double err = 0, mag = 0;
  for (size_t k = 0; k < xs.size(); ++k) {
    err = std::max(err, std::abs(st.x[k] - xs[k]));
    mag = std::max(mag, std::abs(xs[k] - model.rest[k]));
  }
  EXPECT_GT(mag, 1e-4);
  EXPECT_LT(err, 1e-3 * mag);
  // At equilibrium the held end carries the applied load.
  const auto r = fem::reaction_force(model, xs, nodes_where(mesh, 0, 0.0));
  EXPECT_NEAR(r[2], -2e-3, 1e-9);
}

TEST(Fem, ReadsTheSofaLiverGmshMesh) {
  const std::string path = std::string(SOFTATLAS_SHARED_DATA) + "/meshes/sofa/liver.msh";
  const fem::TetMesh mesh = fem::read_gmsh(path);
  EXPECT_EQ(mesh.nnode(), 181);
  EXPECT_EQ(mesh.ntet(), 596);
  const std::vector<int32_t> faces = fem::boundary_faces(mesh);
  // A closed, oriented surface: every directed edge appears once and its reverse once.
  std::map<std::pair<int32_t, int32_t>, int> directed;
  std::set<int32_t> surface_nodes;
  for (size_t f = 0; f < faces.size() / 3; ++f)
    for (int k = 0; k < 3; ++k) {
      directed[{faces[3 * f + k], faces[3 * f + (k + 1) % 3]}] += 1;
      surface_nodes.insert(faces[3 * f + k]);
    }
  for (const auto& [edge, count] : directed) {
    EXPECT_EQ(count, 1);
    EXPECT_EQ(directed.count({edge.second, edge.first}), 1u);
  }
  // Euler characteristic 2 (genus 0, as the README says of liver.obj).
  const long V = static_cast<long>(surface_nodes.size()), E = static_cast<long>(directed.size() / 2),
             F = static_cast<long>(faces.size() / 3);
  EXPECT_EQ(V - E + F, 2);
  // Closed, outward surface: its enclosed volume equals the tetrahedra's total volume.
  double vs = 0.0;
  for (size_t f = 0; f < faces.size() / 3; ++f) {
    const double* a = &mesh.nodes[3 * faces[3 * f]];
    const double* b = &mesh.nodes[3 * faces[3 * f + 1]];
    const double* c = &mesh.nodes[3 * faces[3 * f + 2]];
    vs +=
        (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0])) /
        6.0;
  }
  fem::Material mat;
  const fem::Model model = fem::compile(mesh, mat);  // also reorients tetrahedra
  double vt = 0.0;
  for (double v : model.tet_volume) vt += v;
  EXPECT_GT(vt, 0.0);
  EXPECT_NEAR(vs, vt, 1e-9 * vt);
}

TEST(Fem, GmshReaderRejectsBadInputWithFileAndLine) {
  const std::string path = std::string(SOFTATLAS_BINARY_DIR) + "/fem_test_bad.msh";
  {
    std::ofstream out(path);
    out << "$NOD\n2\n1 0 0 0\n2 1 zero 0\n$ENDNOD\n";
  }
  try {
    fem::read_gmsh(path);
    FAIL() << "expected InputError";
  } catch (const softatlas::InputError& e) {
    EXPECT_EQ(e.where(), path + ":4");
  }
  EXPECT_THROW(fem::read_gmsh(path + ".missing"), softatlas::InputError);
}

TEST(Fem, EmbeddingReproducesLinearFields) {
  const fem::TetMesh mesh = fem::box_mesh(0.02, 0.02, 0.02, 3, 3, 3);
  const fem::Model model = fem::compile(mesh, fem::Material{});
  std::vector<double> pts = {0.013, 0.004, 0.017, 0.0, 0.0, 0.0, 0.021, 0.01, 0.01};
  const fem::Embedding emb = fem::embed_points(model, pts);
  EXPECT_LT(emb.distance[0], 1e-15);
  // Outside by 1 mm: clamped onto the face x = 0.02 (clamped barycentrics, not the orthogonal
  // projection, so the distance is at least 1 mm and not much more).
  EXPECT_GE(emb.distance[2], 0.001 - 1e-15);
  EXPECT_LT(emb.distance[2], 0.0015);
  std::vector<double> x = model.rest;
  for (int32_t i = 0; i < model.nnode; ++i) x[3 * i + 1] += 0.5 * model.rest[3 * i] + 0.001;  // u_y = 0.5 x + 1 mm
  std::vector<double> u;
  fem::interpolate(model, emb, x, u);
  EXPECT_NEAR(u[1], 0.5 * 0.013 + 0.001, 1e-12);
  EXPECT_NEAR(u[4], 0.001, 1e-12);
  EXPECT_NEAR(u[7], 0.5 * 0.02 + 0.001, 1e-12);
}
