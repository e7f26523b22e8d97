// Shared helpers of the solid model's tests (solid_test.cpp, solid_slow_test.cpp).
#pragma once

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

#include "softatlas/sim/sim.hpp"
#include "test_meshes.hpp"

namespace softatlas::solid_test {

constexpr double kPi = 3.14159265358979323846;

// Organ vertices in the lowest `fraction` of the y extent (the support, as the evidence does).
inline std::vector<int32_t> support(const sim::OrganDesc& o, double fraction) {
  double lo = INFINITY, hi = -INFINITY;
  for (size_t i = 0; i < o.vertices.size() / 3; ++i)
    lo = std::min(lo, o.vertices[3 * i + 1]), hi = std::max(hi, o.vertices[3 * i + 1]);
  std::vector<int32_t> out;
  for (size_t i = 0; i < o.vertices.size() / 3; ++i)
    if (o.vertices[3 * i + 1] <= lo + fraction * (hi - lo)) out.push_back(static_cast<int32_t>(i));
  return out;
}

// Source vertex farthest along `dir` and the source vertices within `radius` of it.
inline std::vector<int32_t> region(const sim::OrganDesc& o, const std::array<double, 3>& dir, double radius,
                                   std::array<double, 3>* centre = nullptr) {
  const size_t n = o.vertices.size() / 3;
  size_t best = 0;
  double bd = -INFINITY;
  for (size_t i = 0; i < n; ++i) {
    const double d = dir[0] * o.vertices[3 * i] + dir[1] * o.vertices[3 * i + 1] + dir[2] * o.vertices[3 * i + 2];
    if (d > bd) bd = d, best = i;
  }
  std::vector<int32_t> out;
  for (size_t i = 0; i < n; ++i) {
    double d2 = 0;
    for (int c = 0; c < 3; ++c) d2 += std::pow(o.vertices[3 * i + c] - o.vertices[3 * best + c], 2);
    if (d2 <= radius * radius) out.push_back(static_cast<int32_t>(i));
  }
  if (centre) *centre = {o.vertices[3 * best], o.vertices[3 * best + 1], o.vertices[3 * best + 2]};
  return out;
}

inline sim::SceneDesc liver_scene(const std::string& mesh, double dt, double young = 4000.0, bool fixed = true) {
  sim::SceneDesc s;
  sim::OrganDesc o = test::organ("liver", test::read_obj(test::project_data(mesh)), 1e-3);
  o.material.model = sim::ModelKind::solid;
  o.material.young_modulus_pa = young;
  if (fixed) o.fixed = support(o, 0.1);
  s.organs.push_back(o);
  s.integrator = sim::Integrator::implicit;
  s.dt_s = dt;
  s.allow_sleep = false;
  return s;
}

// One solid organ of a CT-built set (data/meshes, mm) with its build's fixed vertices, implicit at
// the atlas's dt 8 ms, never asleep.
inline sim::SceneDesc ct_solid_scene(const std::string& name, const std::string& mesh, std::vector<int32_t> fixed) {
  sim::SceneDesc scene;
  sim::OrganDesc o = test::organ(name, test::read_obj(test::project_data(mesh)), 1e-3);
  o.material.model = sim::ModelKind::solid;
  o.fixed = std::move(fixed);
  scene.organs.push_back(o);
  scene.integrator = sim::Integrator::implicit;
  scene.dt_s = 8e-3;
  scene.allow_sleep = false;
  return scene;
}

inline std::vector<int32_t> global(const sim::Model& m, const std::vector<int32_t>& src) {
  std::vector<int32_t> out;
  for (int32_t v : src) {
    const int32_t g = sim::global_vertex(m, 0, v);
    if (g >= 0 && m.vert_inv_mass[g] > 0) out.push_back(g);
  }
  return out;
}

// Largest distance of a vertex from its rest position after removing the best-fit rigid motion
// (Kabsch), m.
inline double residual_after_rigid(const sim::Model& m, const sim::State& s) {
  const int n = m.nvert;
  Eigen::Vector3d cr = Eigen::Vector3d::Zero(), cx = Eigen::Vector3d::Zero();
  for (int v = 0; v < n; ++v)
    cr += Eigen::Vector3d(m.vert_rest_x[v], m.vert_rest_y[v], m.vert_rest_z[v]),
        cx += Eigen::Vector3d(s.x[v], s.y[v], s.z[v]);
  cr /= n, cx /= n;
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  for (int v = 0; v < n; ++v)
    H += (Eigen::Vector3d(s.x[v], s.y[v], s.z[v]) - cx) *
         (Eigen::Vector3d(m.vert_rest_x[v], m.vert_rest_y[v], m.vert_rest_z[v]) - cr).transpose();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  if ((svd.matrixV() * svd.matrixU().transpose()).determinant() < 0) D(2, 2) = -1;
  const Eigen::Matrix3d R = svd.matrixV() * D * svd.matrixU().transpose();  // maps current to rest
  double worst = 0;
  for (int v = 0; v < n; ++v) {
    const Eigen::Vector3d p = R * (Eigen::Vector3d(s.x[v], s.y[v], s.z[v]) - cx) + cr;
    worst = std::max(worst, (p - Eigen::Vector3d(m.vert_rest_x[v], m.vert_rest_y[v], m.vert_rest_z[v])).norm());
  }
  return worst;
}

struct PullResult {
  double reached_mm = 0, residual_mm = 0, residual_end_mm = 0, peak_force_N = 0;
  double volume_change_pct = 0;      // largest |change| while held (pull and hold)
  double volume_change_run_pct = 0;  // largest |change| over the whole run, as `bench restore` reports it
  size_t grasped = 0;
  bool finite = true;
};

// Called with step -1 at rest (before the grasp) and then after every step.
using OnStep = std::function<void(const sim::Model&, const sim::State&, int step)>;

// Grasp the free vertices within grasp_radius_m of the organ's extreme vertex along grasp_dir
// (default: the region at the top), pull `pull_m` along dir over 0.5 s, hold 1 s, release, 5 s more.
inline PullResult pull_release(const sim::SceneDesc& scene, double pull_m, const std::array<double, 3>& dir,
                               const std::array<double, 3>& grasp_dir = {0, 1, 0}, double grasp_radius_m = 0.012,
                               const OnStep& on_step = {}) {
  const sim::Model m = sim::compile(scene);
  sim::State s = sim::make_state(m);
  sim::Work w = sim::make_work(m);
  const std::vector<int32_t> grasp = global(m, region(scene.organs[0], grasp_dir, grasp_radius_m));
  const double v0 = sim::organ_volume(m, s, 0), dt = m.dt_s;
  if (on_step) on_step(m, s, -1);
  PullResult r;
  r.grasped = grasp.size();
  sim::attach(m, s, grasp, {0, 0, 0}, 1);
  const int pull = static_cast<int>(std::lround(0.5 / dt)), hold = static_cast<int>(std::lround(1.0 / dt));
  const int after = static_cast<int>(std::lround(5.0 / dt));
  for (int k = 0; k < pull + hold + after; ++k) {
    if (k < pull) {
      const double f = static_cast<double>(k + 1) / pull;
      sim::move_attachment(s, {dir[0] * pull_m * f, dir[1] * pull_m * f, dir[2] * pull_m * f});
    }
    if (k == pull + hold) sim::release(s);
    sim::step(m, s, w);
    if (on_step) on_step(m, s, k);
    const auto F = sim::tool_reaction(s);
    r.peak_force_N = std::max(r.peak_force_N, std::sqrt(F[0] * F[0] + F[1] * F[1] + F[2] * F[2]));
    const double volume_pct = 100.0 * std::fabs(sim::organ_volume(m, s, 0) / v0 - 1.0);
    r.volume_change_run_pct = std::max(r.volume_change_run_pct, volume_pct);
    if (k < pull + hold) {
      r.volume_change_pct = std::max(r.volume_change_pct, volume_pct);
      if (k == pull + hold - 1) {
        double d = 0;
        for (int32_t v : grasp)
          d += std::sqrt(std::pow(s.x[v] - m.vert_rest_x[v], 2) + std::pow(s.y[v] - m.vert_rest_y[v], 2) +
                         std::pow(s.z[v] - m.vert_rest_z[v], 2));
        r.reached_mm = 1e3 * d / grasp.size();
      }
    }
    for (double x : s.solid_x) r.finite = r.finite && std::isfinite(x);
    // the contract's residual: 2 s after release
    if (k == pull + hold + static_cast<int>(std::lround(2.0 / dt))) r.residual_mm = 1e3 * residual_after_rigid(m, s);
  }
  r.residual_end_mm = 1e3 * residual_after_rigid(m, s);
  return r;
}

// One pull of the 2,000-face liver (E 4 kPa, 5 ms implicit steps), 30 mm along dir, and the checks
// of SolidModel.ReturnsAfterPullAndKeepsVolume.
inline void expect_returns_after_pull(const std::array<double, 3>& dir, bool fixed) {
  const PullResult r = pull_release(liver_scene("meshes/liver_2000.obj", 5e-3, 4000.0, fixed), 0.030, dir);
  std::printf(
      "solid pull 30 mm dir (%.2f %.2f %.2f) fixed %d: reached %.1f mm, residual %.3f mm 2 s and %.3f mm 5 s "
      "after release, volume %.2f %%, peak %.3f N\n",
      dir[0], dir[1], dir[2], fixed, r.reached_mm, r.residual_mm, r.residual_end_mm, r.volume_change_pct,
      r.peak_force_N);
  EXPECT_TRUE(r.finite);
  EXPECT_GE(r.reached_mm, 20.0);
  EXPECT_LT(r.residual_end_mm, 1.0);
  EXPECT_LE(r.volume_change_pct, 2.0);
}

}  // namespace softatlas::solid_test
