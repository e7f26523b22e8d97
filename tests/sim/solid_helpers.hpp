// Shared helpers of the solid model's tests (solid_test.cpp, solid_slow_test.cpp).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
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

}  // namespace softatlas::solid_test
