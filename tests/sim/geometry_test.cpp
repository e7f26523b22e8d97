// Geometry kernels against closed forms: sphere curvature 1/r, plane curvature 0, volumes.
#include <gtest/gtest.h>

#include <cmath>

#include "softatlas/sim/geometry.hpp"
#include "test_meshes.hpp"

namespace softatlas {
namespace {

double mean_abs_error_of_curvature(int level, double r) {
  const test::Mesh m = test::icosphere(level, r);
  const std::vector<double> k = sim::mean_curvature(m.V, m.F);
  double err = 0;
  for (double v : k) err += std::abs(v - 1.0 / r);
  return err / k.size();
}

TEST(Curvature, PaperSphereHas162VerticesAnd320Faces) {
  const test::Mesh m = test::icosphere(2, 1.0);
  EXPECT_EQ(m.V.size() / 3, 162u);
  EXPECT_EQ(m.F.size() / 3, 320u);
}

TEST(Curvature, ConvergesToInverseRadiusUnderRefinement) {
  for (double r : {0.5, 1.0, 3.0}) {
    double prev = 1e300;
    for (int level = 1; level <= 5; ++level) {
      const double e = mean_abs_error_of_curvature(level, r) * r;  // relative error
      EXPECT_LE(e, prev + 1e-12) << "level " << level << " r " << r;
      prev = e;
    }
    EXPECT_LT(prev, 0.01) << "finest icosphere must be within 1 % of 1/r, r = " << r;
  }
}

TEST(Curvature, PlaneInteriorIsFlat) {
  const test::Mesh m = test::plane_grid(8, 2.0);
  const std::vector<double> k = sim::mean_curvature(m.V, m.F);
  for (int j = 1; j < 8; ++j)
    for (int i = 1; i < 8; ++i) EXPECT_NEAR(k[j * 9 + i], 0.0, 1e-12);
}

TEST(Curvature, ObtuseAndDegenerateTrianglesStayFinite) {
  // A sphere with one vertex pulled onto its neighbour (near-zero edge, slivers) and one face
  // flattened to zero area.
  test::Mesh m = test::icosphere(2, 1.0);
  const int a = m.F[0], b = m.F[1];
  for (int c = 0; c < 3; ++c) m.V[3 * a + c] = m.V[3 * b + c] + 1e-13;
  const std::vector<double> k = sim::mean_curvature(m.V, m.F);
  for (double v : k) EXPECT_TRUE(std::isfinite(v));
  test::Mesh flat = test::plane_grid(2, 1.0);
  flat.V[3 * 4 + 0] = 0.0, flat.V[3 * 4 + 1] = 0.0;  // centre vertex onto a corner
  for (double v : sim::mean_curvature(flat.V, flat.F)) EXPECT_TRUE(std::isfinite(v));
}

TEST(Volume, CubeAndSphere) {
  EXPECT_NEAR(sim::enclosed_volume(test::cube(2.0).V, test::cube(2.0).F), 8.0, 1e-12);
  const test::Mesh s = test::icosphere(5, 2.0);
  EXPECT_NEAR(sim::enclosed_volume(s.V, s.F), 4.0 / 3.0 * M_PI * 8.0, 0.002 * 4.0 / 3.0 * M_PI * 8.0);
}

TEST(Normals, PointOutwardOnSphere) {
  const test::Mesh s = test::icosphere(3, 1.0);
  const size_t n = s.V.size() / 3;
  std::vector<double> x(n), y(n), z(n), N(3 * n);
  for (size_t i = 0; i < n; ++i) x[i] = s.V[3 * i], y[i] = s.V[3 * i + 1], z[i] = s.V[3 * i + 2];
  sim::vertex_normals(n, x.data(), y.data(), z.data(), s.F.size() / 3, s.F.data(), N.data());
  for (size_t i = 0; i < n; ++i) EXPECT_GT(N[3 * i] * x[i] + N[3 * i + 1] * y[i] + N[3 * i + 2] * z[i], 0.99);
}

TEST(Mass, AreaMassesSumToTotalAndFollowArea) {
  const test::Mesh s = test::icosphere(2, 1.0);
  const size_t n = s.V.size() / 3;
  std::vector<double> x(n), y(n), z(n), mass(n, 0.0);
  for (size_t i = 0; i < n; ++i) x[i] = s.V[3 * i], y[i] = s.V[3 * i + 1], z[i] = s.V[3 * i + 2];
  sim::area_masses(x.data(), y.data(), z.data(), s.F.data(), 0, s.F.size() / 3, 2.5, mass.data());
  double total = 0;
  for (double m : mass) total += m;
  EXPECT_NEAR(total, 2.5, 1e-12);
}

TEST(Stiffness, Eq9ForAnEquilateralPairIsTwiceEtSqrt3Over4) {
  // Two equilateral faces at an edge: sum A_j / A_0 = 2, so k = E t 2 sqrt(3)/4 (eq 9).
  const double l = 0.01, A0 = std::sqrt(3.0) / 4 * l * l;
  EXPECT_NEAR(sim::lloyd_stiffness(5000.0, 1e-3, 2 * A0, l), 5000.0 * 1e-3 * 2 * std::sqrt(3.0) / 4, 1e-12);
}

}  // namespace
}  // namespace softatlas
