// Triangular tensor-mass model (paper 002) against closed forms: the strain energy of a uniform
// plane strain, rigid motions, membrane behaviour, and an implicit run to equilibrium.
#include "softatlas/sim/tmm.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "softatlas/sim/error.hpp"

namespace tmm = softatlas::sim::tmm;

namespace {

// n x n grid of squares in the plane z = 0, [0, L]^2, two triangles per square (CCW from +z).
void flat_grid(int n, double L, std::vector<double>& V, std::vector<int32_t>& F) {
  V.clear();
  F.clear();
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) V.insert(V.end(), {L * i / n, L * j / n, 0.0});
  auto id = [&](int i, int j) { return i + (n + 1) * j; };
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      F.insert(F.end(), {id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      F.insert(F.end(), {id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
}

// Icosphere: icosahedron subdivided `level` times, projected on the sphere of radius r.
void icosphere(int level, double r, std::vector<double>& V, std::vector<int32_t>& F) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  V = {-1, t,  0,  1, t, 0,  -1, -t, 0,  1, -t, 0, 0,  -1, t,  0,  1, t,
       0,  -1, -t, 0, 1, -t, t,  0,  -1, t, 0,  1, -t, 0,  -1, -t, 0, 1};
  F = {0, 11, 5, 0, 5, 1, 0, 1, 7, 0, 7, 10, 0, 10, 11, 1, 5, 9, 5, 11, 4,  11, 10, 2,  10, 7, 6, 7, 1, 8,
       3, 9,  4, 3, 4, 2, 3, 2, 6, 3, 6, 8,  3, 8,  9,  4, 9, 5, 2, 4,  11, 6,  2,  10, 8,  6, 7, 9, 8, 1};
  for (int l = 0; l < level; ++l) {
    std::map<std::pair<int32_t, int32_t>, int32_t> mid;
    auto midpoint = [&](int32_t a, int32_t b) {
      auto key = std::make_pair(std::min(a, b), std::max(a, b));
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      const int32_t id = static_cast<int32_t>(V.size() / 3);
      for (int c = 0; c < 3; ++c) V.push_back(0.5 * (V[3 * a + c] + V[3 * b + c]));
      mid.emplace(key, id);
      return id;
    };
    std::vector<int32_t> out;
    for (size_t f = 0; f < F.size() / 3; ++f) {
      const int32_t a = F[3 * f], b = F[3 * f + 1], c = F[3 * f + 2];
      const int32_t ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
      out.insert(out.end(), {a, ab, ca, b, bc, ab, c, ca, bc, ab, bc, ca});
    }
    F = out;
  }
  for (size_t i = 0; i < V.size() / 3; ++i) {
    const double n = std::sqrt(V[3 * i] * V[3 * i] + V[3 * i + 1] * V[3 * i + 1] + V[3 * i + 2] * V[3 * i + 2]);
    for (int c = 0; c < 3; ++c) V[3 * i + c] *= r / n;
  }
}

double dot(const std::vector<double>& a, const std::vector<double>& b) {
  double s = 0;
  for (size_t k = 0; k < a.size(); ++k) s += a[k] * b[k];
  return s;
}

}  // namespace

TEST(Tmm, UniformPlaneStrainEnergyMatchesPlaneStressFormula) {
  std::vector<double> V;
  std::vector<int32_t> F;
  const double L = 0.05;
  flat_grid(4, L, V, F);
  tmm::Params p;
  p.young_modulus_pa = 5000.0;
  p.poisson_ratio = 0.3;
  p.thickness_m = 2e-3;
  p.total_mass_kg = 0.1;
  const tmm::Model m = tmm::compile(V, F, {}, p);
  const double exx = 0.01, eyy = -0.004, exy = 0.003;  // symmetric in-plane strain
  std::vector<double> x = V;
  for (size_t i = 0; i < V.size() / 3; ++i) {
    x[3 * i] += exx * V[3 * i] + exy * V[3 * i + 1];
    x[3 * i + 1] += exy * V[3 * i] + eyy * V[3 * i + 1];
  }
  std::vector<double> f;
  tmm::internal_forces(m, x, f);
  std::vector<double> u(x.size());
  for (size_t k = 0; k < x.size(); ++k) u[k] = x[k] - V[k];
  const double energy = -0.5 * dot(u, f);
  // Plane stress: W = t A (mu eps:eps + lambda*/2 tr(eps)^2), lambda* = E nu / (1 - nu^2).
  const double E = p.young_modulus_pa, nu = p.poisson_ratio, mu = E / (2 * (1 + nu));
  const double lam = E * nu / (1 - nu * nu);
  const double expected =
      p.thickness_m * L * L * (mu * (exx * exx + eyy * eyy + 2 * exy * exy) + 0.5 * lam * (exx + eyy) * (exx + eyy));
  EXPECT_NEAR(energy, expected, 1e-12 * expected);
  // Interior nodes carry no force under a uniform strain (patch test).
  const int32_t interior = 2 + 5 * 2;  // node (2, 2) of the 5 x 5 grid
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(f[3 * interior + c], 0.0, 1e-14);
}

TEST(Tmm, RigidTranslationAndOutOfPlaneMotionCostNothing) {
  std::vector<double> V;
  std::vector<int32_t> F;
  flat_grid(3, 0.03, V, F);
  tmm::Params p;
  p.total_mass_kg = 0.01;
  const tmm::Model m = tmm::compile(V, F, {}, p);
  std::vector<double> x = V, f;
  for (size_t i = 0; i < V.size() / 3; ++i) {
    x[3 * i] += 0.01;
    x[3 * i + 2] += 0.002 * V[3 * i] / 0.03;  // tilt out of the plane: a membrane ignores it
  }
  tmm::internal_forces(m, x, f);
  for (double v : f) EXPECT_NEAR(v, 0.0, 1e-15);
}

TEST(Tmm, ImplicitStepsReachEquilibriumUnderAPull) {
  std::vector<double> V;
  std::vector<int32_t> F;
  icosphere(2, 0.05, V, F);
  ASSERT_EQ(V.size() / 3, 162u);
  ASSERT_EQ(F.size() / 3, 320u);
  std::vector<int32_t> bottom, top;
  for (int32_t i = 0; i < static_cast<int32_t>(V.size() / 3); ++i) {
    if (V[3 * i + 2] < -0.045) bottom.push_back(i);
    if (V[3 * i + 2] > 0.049) top.push_back(i);
  }
  ASSERT_FALSE(bottom.empty());
  ASSERT_FALSE(top.empty());
  tmm::Params p;
  p.total_mass_kg = 0.5;
  p.rayleigh_mass = 2.0;
  const tmm::Model m = tmm::compile(V, F, bottom, p);
  tmm::State s = tmm::make_state(m);
  tmm::Work w = tmm::make_work(m);
  tmm::pull_force(s, top, {0.0, 0.0, 1e-3});
  const double e0 = tmm::volume(m, s.x);
  tmm::StepInfo info;
  for (int i = 0; i < 600; ++i) info = tmm::step(m, s, w, 0.02);
  EXPECT_TRUE(info.finite);
  const auto r = tmm::tool_reaction(m, s, w);
  // At rest the organ pulls back on the tool with minus the applied force.
  EXPECT_NEAR(r[2], -1e-3, 1e-6);
  EXPECT_NEAR(r[0], 0.0, 1e-6);
  double up = 0.0;
  for (int32_t v : top) up += s.x[3 * v + 2] - V[3 * v + 2];
  EXPECT_GT(up, 0.0);
  EXPECT_GT(tmm::energy(m, s, w), 0.0);
  EXPECT_NE(tmm::volume(m, s.x), e0);
}

TEST(Tmm, LargeStepsStayFiniteAndAttachmentReachesItsTarget) {
  std::vector<double> V;
  std::vector<int32_t> F;
  icosphere(2, 0.05, V, F);
  std::vector<int32_t> bottom;
  for (int32_t i = 0; i < static_cast<int32_t>(V.size() / 3); ++i)
    if (V[3 * i + 2] < -0.045) bottom.push_back(i);
  tmm::Params p;
  p.young_modulus_pa = 1e6;  // stiff: an explicit step at this dt would explode
  p.total_mass_kg = 0.05;
  const tmm::Model m = tmm::compile(V, F, bottom, p);
  tmm::State s = tmm::make_state(m);
  tmm::Work w = tmm::make_work(m);
  tmm::attach(s, {0}, {0.0, 0.02, 0.02}, 30);
  for (int i = 0; i < 60; ++i) EXPECT_TRUE(tmm::step(m, s, w, 0.1).finite);
  EXPECT_NEAR(s.x[1], V[1] + 0.02, 1e-12);
  EXPECT_NEAR(s.x[2], V[2] + 0.02, 1e-12);
}

TEST(Tmm, RejectsDegenerateTrianglesAndBadParameters) {
  std::vector<double> V = {0, 0, 0, 1, 0, 0, 2, 0, 0};
  std::vector<int32_t> F = {0, 1, 2};
  EXPECT_THROW(tmm::compile(V, F, {}, tmm::Params{}), softatlas::InputError);
  V = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  tmm::Params p;
  p.poisson_ratio = 0.5;
  EXPECT_THROW(tmm::compile(V, F, {}, p), softatlas::InputError);
  EXPECT_THROW(tmm::compile(V, {0, 1, 3}, {}, tmm::Params{}), softatlas::InputError);
}
