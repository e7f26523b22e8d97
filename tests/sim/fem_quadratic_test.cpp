// The quadratic neo-Hookean reference (fem_quadratic.hpp): forces are the energy's gradient and
// the tangent its Hessian (finite differences), the compressed block is exact, the cantilever is
// within 2 % of Timoshenko at 2 cells through the thickness also at nu = 0.49 (no locking), and a
// large prescribed pull converges quadratically to a tiny residual.
#include "softatlas/sim/fem_quadratic.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "softatlas/sim/error.hpp"

namespace fem = softatlas::sim::fem;

namespace {

std::vector<int32_t> nodes_where(const std::vector<double>& nodes, int axis, double value) {
  std::vector<int32_t> out;
  for (int32_t i = 0; i < static_cast<int32_t>(nodes.size() / 3); ++i)
    if (std::abs(nodes[3 * i + axis] - value) < 1e-12) out.push_back(i);
  return out;
}

// Boundary faces of the corner mesh lying in the plane axis = value.
std::vector<int32_t> faces_where(const fem::TetMesh& mesh, int axis, double value) {
  const std::vector<int32_t> all = fem::boundary_faces(mesh);
  std::vector<int32_t> out;
  for (size_t f = 0; f + 2 < all.size(); f += 3) {
    bool on = true;
    for (int k = 0; k < 3; ++k) on = on && std::abs(mesh.nodes[3 * all[f + k] + axis] - value) < 1e-12;
    if (on) out.insert(out.end(), all.begin() + static_cast<long>(f), all.begin() + static_cast<long>(f) + 3);
  }
  return out;
}

fem::Material material(double E, double nu) {
  fem::Material m;
  m.young_modulus_pa = E;
  m.poisson_ratio = nu;
  return m;
}

// A slightly deformed state of a small block (random displacements of 3 % of the cell).
std::vector<double> jiggled(const fem::QuadraticModel& q, double amplitude, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-amplitude, amplitude);
  std::vector<double> x = q.rest;
  for (double& c : x) c += u(rng);
  return x;
}

double cantilever_error(int n, double nu, double P, int* iterations = nullptr) {
  const double L = 0.1, h = 0.01, E = 1e5;
  const fem::TetMesh mesh = fem::box_mesh(L, h, h, 10 * n, n, n);
  const fem::QuadraticModel q = fem::compile_quadratic(mesh, material(E, nu));
  fem::Load load = fem::make_load(q);
  // The clamped end as beam theory has it: the section stays plane (u_x = 0) and free to
  // contract; the neutral lines hold it in place (u_z = 0 on z = h/2, u_y = 0 on y = h/2).
  for (int32_t i : nodes_where(q.rest, 0, 0.0)) {
    load.dof_fixed[3 * i] = 1;
    if (std::abs(q.rest[3 * i + 2] - h / 2) < 1e-12) load.dof_fixed[3 * i + 2] = 1;
    if (std::abs(q.rest[3 * i + 1] - h / 2) < 1e-12) load.dof_fixed[3 * i + 1] = 1;
  }
  fem::add_traction(q, load, faces_where(mesh, 0, L), {0, 0, -P / (h * h)});
  std::vector<double> x = q.rest;
  const fem::StaticReport rep = fem::solve_static(q, load, x);
  EXPECT_TRUE(rep.converged) << "residual " << rep.residual;
  if (iterations) *iterations = rep.iterations;
  const std::vector<int32_t> tip = nodes_where(q.rest, 0, L);
  double uz = 0.0;
  for (int32_t i : tip) uz += x[3 * i + 2] - q.rest[3 * i + 2];
  uz = -uz / static_cast<double>(tip.size());
  const double I = h * h * h * h / 12.0, G = E / (2 * (1 + nu));
  const double analytic = P * L * L * L / (3 * E * I) + P * L / (5.0 / 6.0 * G * h * h);
  return (uz - analytic) / analytic;
}

}  // namespace

TEST(FemQuadratic, NodesAreCornersThenEdgeMidpoints) {
  const fem::TetMesh mesh = fem::box_mesh(0.02, 0.01, 0.01, 2, 1, 1);
  const fem::QuadraticModel q = fem::compile_quadratic(mesh, material(4000, 0.45));
  EXPECT_EQ(q.nvertex, mesh.nnode());
  EXPECT_EQ(q.nnode - q.nvertex, static_cast<int32_t>(q.edge_ends.size() / 2));
  for (int32_t e = 0; e < q.nnode - q.nvertex; ++e) {
    const int32_t a = q.edge_ends[2 * e], b = q.edge_ends[2 * e + 1];
    EXPECT_EQ(fem::edge_node(q, a, b), q.nvertex + e);
    EXPECT_EQ(fem::edge_node(q, b, a), q.nvertex + e);
    for (int c = 0; c < 3; ++c)
      EXPECT_DOUBLE_EQ(q.rest[3 * (q.nvertex + e) + c], 0.5 * (q.rest[3 * a + c] + q.rest[3 * b + c]));
  }
  EXPECT_EQ(fem::edge_node(q, 0, 0), -1);
  // The region of two adjacent corners holds their edge node too.
  const std::vector<int32_t> reg = fem::quadratic_region(q, {q.edge_ends[0], q.edge_ends[1]});
  EXPECT_EQ(reg.size(), 3u);
}

TEST(FemQuadratic, ForcesAreTheEnergyGradientAndTheTangentItsHessian) {
  const fem::TetMesh mesh = fem::box_mesh(0.02, 0.01, 0.01, 2, 1, 1);
  const fem::QuadraticModel q = fem::compile_quadratic(mesh, material(4000, 0.45));
  const std::vector<double> x = jiggled(q, 4e-4, 7);
  std::vector<double> f, fp, fm, v(x.size()), kv;
  fem::internal_forces(q, x, f);
  std::mt19937 rng(3);
  std::normal_distribution<double> nd;
  for (double& c : v) c = nd(rng);
  const double h = 1e-7;
  std::vector<double> xp = x, xm = x;
  for (size_t d = 0; d < x.size(); ++d) {
    xp[d] = x[d] + h * v[d];
    xm[d] = x[d] - h * v[d];
  }
  // Directional derivative of the energy = -f . v
  const double de = (fem::elastic_energy(q, xp) - fem::elastic_energy(q, xm)) / (2 * h);
  double fv = 0.0;
  for (size_t d = 0; d < x.size(); ++d) fv += f[d] * v[d];
  EXPECT_NEAR(de, -fv, 1e-6 * std::abs(fv));
  // K v = -(f(x + h v) - f(x - h v)) / 2h
  fem::internal_forces(q, xp, fp);
  fem::internal_forces(q, xm, fm);
  fem::tangent_times(q, x, v, kv);
  double err = 0.0, ref = 0.0;
  for (size_t d = 0; d < x.size(); ++d) {
    const double fd = -(fp[d] - fm[d]) / (2 * h);
    err = std::max(err, std::abs(fd - kv[d]));
    ref = std::max(ref, std::abs(kv[d]));
  }
  EXPECT_LT(err, 1e-6 * ref);
  // An inverted element has infinite energy.
  std::vector<double> inv = q.rest;
  for (int32_t i = 0; i < q.nnode; ++i) inv[3 * i] = -inv[3 * i];
  EXPECT_TRUE(std::isinf(fem::elastic_energy(q, inv)));
}

TEST(FemQuadratic, CompressedBlockMatchesUniaxialStress) {
  // Small load (strain 1.2e-5): the neo-Hookean solid is linear elastic up to terms of the order
  // of the strain; quadratic elements are exact for the (linear) uniaxial displacement field.
  const double lx = 0.02, ly = 0.02, lz = 0.04, E = 4000.0, nu = 0.45, p = 0.05;
  const fem::TetMesh mesh = fem::box_mesh(lx, ly, lz, 2, 2, 3);
  const fem::QuadraticModel q = fem::compile_quadratic(mesh, material(E, nu));
  fem::Load load = fem::make_load(q);
  for (int axis = 0; axis < 3; ++axis)
    for (int32_t i : nodes_where(q.rest, axis, 0.0)) load.dof_fixed[3 * i + axis] = 1;
  fem::add_traction(q, load, faces_where(mesh, 2, lz), {0, 0, -p});
  std::vector<double> x = q.rest;
  fem::StaticOptions opt;
  opt.tolerance = 1e-8;
  const fem::StaticReport rep = fem::solve_static(q, load, x, opt);
  ASSERT_TRUE(rep.converged) << rep.residual << " after " << rep.iterations;
  const double scale = p * lz / E;
  for (int32_t i = 0; i < q.nnode; ++i) {
    const double* X = &q.rest[3 * i];
    EXPECT_NEAR(x[3 * i + 2] - X[2], -p * X[2] / E, 1e-4 * scale);
    EXPECT_NEAR(x[3 * i + 0] - X[0], nu * p * X[0] / E, 1e-4 * scale);
  }
}

TEST(FemQuadratic, CantileverWithinTwoPercentOfTimoshenkoWithoutLocking) {
  // 2 cells through the thickness; linear tetrahedra are 50 % too stiff here (fem_test.cpp).
  // Also a bound at 1 cell (nu = 0.49): a locking element would be far off.
  EXPECT_LT(std::abs(cantilever_error(1, 0.49, 1e-4)), 0.02);
  // Measured: nu 0.3 / 0.45 / 0.49 at n = 1: -0.31 / -0.69 / -1.04 %; n = 2: -0.04 / -0.14 / -0.22 %.
  for (double nu : {0.3, 0.45, 0.49}) {
    const double err = cantilever_error(2, nu, 1e-4);
    EXPECT_LT(std::abs(err), 0.02) << "nu = " << nu << ": relative error " << err;
  }
}

TEST(FemQuadratic, LargePullConvergesQuadratically) {
  // A 40 x 20 x 20 mm block of E = 4 kPa, nu = 0.49, clamped at x = 0, the far face pulled 20 mm
  // along x and 10 mm sideways (50 % stretch): Newton with the consistent tangent converges to a
  // relative residual of 1e-10 in a handful of iterations per increment.
  const fem::TetMesh mesh = fem::box_mesh(0.04, 0.02, 0.02, 4, 2, 2);
  const fem::QuadraticModel q = fem::compile_quadratic(mesh, material(4000, 0.49));
  fem::Load load = fem::make_load(q);
  fem::fix_nodes(load, nodes_where(q.rest, 0, 0.0), {0, 0, 0});
  const std::vector<int32_t> far = nodes_where(q.rest, 0, 0.04);
  fem::fix_nodes(load, far, {0.02, 0.01, 0});
  std::vector<double> x = q.rest;
  fem::StaticOptions opt;
  opt.load_steps = 4;
  opt.max_iterations = 30;
  opt.tolerance = 1e-10;
  std::vector<double> fractions, pulls;  // the quasi-static path, one state per increment
  std::vector<double> last;
  opt.on_increment = [&](double f, const std::vector<double>& xs) {
    fractions.push_back(f);
    pulls.push_back(-fem::reaction_force(q, xs, fem::quadratic_region(q, far))[0]);
    last = xs;
  };
  const fem::StaticReport rep = fem::solve_static(q, load, x, opt);
  EXPECT_TRUE(rep.converged) << "residual " << rep.residual;
  EXPECT_LE(rep.iterations, 4 * 8);
  ASSERT_EQ(fractions.size(), 4u);
  for (int s = 0; s < 4; ++s) EXPECT_DOUBLE_EQ(fractions[s], (s + 1) / 4.0);
  for (int s = 1; s < 4; ++s) EXPECT_GT(pulls[s], pulls[s - 1]);  // the force grows along the path
  EXPECT_EQ(last, x);
  EXPECT_TRUE(std::isfinite(fem::elastic_energy(q, x)));  // nothing inverted
  // Nearly incompressible: the volume of the corner mesh changes by little under a 50 % stretch.
  const double v0 = fem::deformed_volume(q, q.rest), v1 = fem::deformed_volume(q, x);
  EXPECT_NEAR(v0, 0.04 * 0.02 * 0.02, 1e-15);
  EXPECT_LT(std::abs(v1 - v0) / v0, 0.03);
  // The pulled face feels a restoring force against the pull.
  const std::array<double, 3> r = fem::reaction_force(q, x, fem::quadratic_region(q, far));
  EXPECT_LT(r[0], 0.0);
}

TEST(FemQuadratic, InterpolationReproducesTheNodalField) {
  const fem::TetMesh mesh = fem::box_mesh(0.02, 0.02, 0.02, 2, 2, 2);
  const fem::QuadraticModel q = fem::compile_quadratic(mesh, material(4000, 0.45));
  // A quadratic displacement field u = (x^2, x y, z) is represented exactly.
  std::vector<double> x = q.rest;
  auto field = [](const double* p, double* u) {
    u[0] = p[0] * p[0];
    u[1] = p[0] * p[1];
    u[2] = 0.1 * p[2];
  };
  for (int32_t i = 0; i < q.nnode; ++i) {
    double u[3];
    field(&q.rest[3 * i], u);
    for (int c = 0; c < 3; ++c) x[3 * i + c] += u[c];
  }
  const std::vector<double> pts = {0.003, 0.007, 0.011, 0.015, 0.002, 0.019, 0.01, 0.01, 0.01};
  const fem::Embedding emb = fem::embed_points(q.linear, pts);
  std::vector<double> out;
  fem::interpolate(q, emb, x, out);
  for (size_t p = 0; p < pts.size() / 3; ++p) {
    double u[3];
    field(&pts[3 * p], u);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(out[3 * p + c], u[c], 1e-15);
  }
}

TEST(FemQuadratic, BadInputIsAnInputError) {
  fem::TetMesh mesh = fem::box_mesh(0.02, 0.01, 0.01, 1, 1, 1);
  EXPECT_THROW(fem::compile_quadratic(mesh, material(-1, 0.45)), softatlas::InputError);
  const fem::QuadraticModel q = fem::compile_quadratic(mesh, material(4000, 0.45));
  fem::Load load = fem::make_load(q);
  std::vector<double> wrong(3);
  EXPECT_THROW(fem::solve_static(q, load, wrong), softatlas::InputError);
}
