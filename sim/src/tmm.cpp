// Triangular tensor-mass model (paper 002); see tmm.hpp.
#include "softatlas/sim/tmm.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <map>
#include <string>

#include "softatlas/sim/error.hpp"

namespace softatlas::sim::tmm {

namespace {

using Mat3 = Eigen::Matrix3d;
using Vec3 = Eigen::Vector3d;
using RMat3 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;

Vec3 at(const std::vector<double>& x, int32_t i) { return Vec3(x[3 * i], x[3 * i + 1], x[3 * i + 2]); }

[[noreturn]] void bad(const std::string& field, const std::string& what) {
  throw InputError("tensor-mass" + (field.empty() ? std::string() : ": " + field), what);
}

// y = K p over all vertices (node tensors + edge tensors, K_ba = K_ab^T).
void stiffness_times(const Model& m, const double* p, double* y) {
  for (int32_t i = 0; i < m.nvert; ++i) {
    const Eigen::Map<const RMat3> K(&m.node_tensor[9 * i]);
    Eigen::Map<Vec3>(y + 3 * i) = K * Eigen::Map<const Vec3>(p + 3 * i);
  }
  for (int32_t e = 0; e < m.nedge; ++e) {
    const int32_t a = m.edge_a[e], b = m.edge_b[e];
    const Eigen::Map<const RMat3> K(&m.edge_tensor[9 * e]);
    Eigen::Map<Vec3>(y + 3 * a) += K * Eigen::Map<const Vec3>(p + 3 * b);
    Eigen::Map<Vec3>(y + 3 * b) += K.transpose() * Eigen::Map<const Vec3>(p + 3 * a);
  }
}

}  // namespace

Model compile(const std::vector<double>& V, const std::vector<int32_t>& F, const std::vector<int32_t>& fixed,
              const Params& p) {
  if (V.empty() || F.empty() || V.size() % 3 || F.size() % 3)
    bad("mesh", "expected vertices (#V*3) and triangles (#F*3), got an empty or ragged mesh");
  if (!(p.young_modulus_pa > 0) || !std::isfinite(p.young_modulus_pa))
    bad("young_modulus_pa", "expected a positive number");
  if (!(p.poisson_ratio > -1.0 && p.poisson_ratio < 0.5)) bad("poisson_ratio", "expected a value in (-1, 0.5)");
  if (!(p.thickness_m > 0)) bad("thickness_m", "expected a positive number");
  if (p.total_mass_kg < 0 || !(p.density_kg_m3 > 0)) bad("mass", "expected total_mass_kg >= 0 and density_kg_m3 > 0");
  if (p.rayleigh_mass < 0 || p.rayleigh_stiffness < 0) bad("rayleigh", "expected non-negative coefficients");
  if (p.cg_iterations < 1) bad("cg_iterations", "expected at least 1");
  Model m;
  m.params = p;
  m.nvert = static_cast<int32_t>(V.size() / 3);
  m.rest = V;
  m.faces = F;
  for (double c : V)
    if (!std::isfinite(c)) bad("mesh", "non-finite vertex coordinate");
  for (int32_t v : F)
    if (v < 0 || v >= m.nvert)
      bad("mesh", "face index " + std::to_string(v) + " outside [0, " + std::to_string(m.nvert) + ")");
  // Plane stress: lambda* = 2 lambda mu / (lambda + 2 mu) = E nu / (1 - nu^2), mu = E / (2 (1 + nu)).
  const double E = p.young_modulus_pa, nu = p.poisson_ratio;
  m.lame_mu = E / (2.0 * (1.0 + nu));
  m.lame_lambda_plane = E * nu / (1.0 - nu * nu);
  m.node_tensor.assign(9 * static_cast<size_t>(m.nvert), 0.0);
  m.vert_mass.assign(m.nvert, 0.0);
  m.vert_fixed.assign(m.nvert, 0);
  for (int32_t v : fixed) {
    if (v < 0 || v >= m.nvert) bad("fixed", "vertex " + std::to_string(v) + " outside the mesh");
    m.vert_fixed[v] = 1;
  }
  std::map<std::pair<int32_t, int32_t>, int32_t> edge_id;
  std::vector<double> edge_tensor;
  double area_total = 0.0, volume = 0.0;
  std::vector<double> area_at(m.nvert, 0.0);
  for (size_t f = 0; f < F.size() / 3; ++f) {
    const int32_t n[3] = {F[3 * f], F[3 * f + 1], F[3 * f + 2]};
    const Vec3 X[3] = {at(V, n[0]), at(V, n[1]), at(V, n[2])};
    const Vec3 c = (X[1] - X[0]).cross(X[2] - X[0]);
    const double area = 0.5 * c.norm();
    const double scale = std::max((X[1] - X[0]).squaredNorm(), (X[2] - X[0]).squaredNorm());
    if (!(area > 1e-12 * scale)) bad("mesh", "triangle " + std::to_string(f) + " is degenerate (zero area)");
    const Vec3 normal = c / (2.0 * area);
    volume += X[0].dot(X[1].cross(X[2])) / 6.0;
    area_total += area;
    // In-plane gradients of the barycentric coordinates: g_i = n x (X_{i+2} - X_{i+1}) / (2A).
    Vec3 g[3];
    for (int i = 0; i < 3; ++i) g[i] = normal.cross(X[(i + 2) % 3] - X[(i + 1) % 3]) / (2.0 * area);
    const Mat3 P = Mat3::Identity() - normal * normal.transpose();
    const double w = area * p.thickness_m;
    auto block = [&](int i, int j) -> Mat3 {
      // Paper 002 eq 10 with the isotropic plane-stress E of eq 5 (membrane): the 3-D formula
      // K_ij = V (lambda g_i g_j^T + mu g_j g_i^T + mu (g_i.g_j) I) restricted to the plane.
      return w * (m.lame_lambda_plane * g[i] * g[j].transpose() + m.lame_mu * g[j] * g[i].transpose() +
                  m.lame_mu * g[i].dot(g[j]) * P);
    };
    for (int i = 0; i < 3; ++i) {
      Eigen::Map<RMat3>(&m.node_tensor[9 * n[i]]) += block(i, i);
      area_at[n[i]] += area / 3.0;
    }
    for (int i = 0; i < 3; ++i) {
      const int j = (i + 1) % 3;
      int32_t a = n[i], b = n[j];
      Mat3 K = block(i, j);  // couples a (row) with b (column)
      if (a > b) {
        std::swap(a, b);
        K.transposeInPlace();
      }
      auto it = edge_id.find({a, b});
      int32_t e;
      if (it == edge_id.end()) {
        e = static_cast<int32_t>(m.edge_a.size());
        edge_id.emplace(std::make_pair(a, b), e);
        m.edge_a.push_back(a);
        m.edge_b.push_back(b);
        edge_tensor.resize(edge_tensor.size() + 9, 0.0);
      } else {
        e = it->second;
      }
      Eigen::Map<RMat3>(&edge_tensor[9 * e]) += K;
    }
  }
  m.nedge = static_cast<int32_t>(m.edge_a.size());
  m.edge_tensor = std::move(edge_tensor);
  const double total_mass = p.total_mass_kg > 0 ? p.total_mass_kg : p.density_kg_m3 * std::abs(volume);
  if (!(total_mass > 0)) bad("mass", "the mesh encloses no volume; give total_mass_kg");
  // Lumped mass in proportion to the area around each vertex (paper 002 eq 13, paper 000 eq 8).
  for (int32_t i = 0; i < m.nvert; ++i) m.vert_mass[i] = total_mass * area_at[i] / area_total;
  for (int32_t i = 0; i < m.nvert; ++i)
    if (!(m.vert_mass[i] > 0)) m.vert_mass[i] = total_mass / m.nvert * 1e-3;  // isolated vertex
  return m;
}

State make_state(const Model& m) {
  State s;
  s.x = m.rest;
  s.v.assign(m.rest.size(), 0.0);
  return s;
}

Work make_work(const Model& m) {
  Work w;
  const size_t n = 3 * static_cast<size_t>(m.nvert);
  for (auto* b : {&w.f, &w.r, &w.d, &w.q, &w.s, &w.diag, &w.kv}) b->assign(n, 0.0);
  w.constrained.assign(m.nvert, 0);
  return w;
}

void pull_force(State& s, const std::vector<int32_t>& verts, const std::array<double, 3>& force_N) {
  s.tool = Tool{};
  s.tool.mode = Tool::force;
  s.tool.verts = verts;
  s.tool.force_N = force_N;
}

void attach(State& s, const std::vector<int32_t>& verts, const std::array<double, 3>& offset_m, int iterations) {
  s.tool = Tool{};
  s.tool.mode = Tool::attach;
  s.tool.verts = verts;
  s.tool.offset_m = offset_m;
  s.tool.iterations = std::max(1, iterations);
  for (int32_t v : verts)
    for (int c = 0; c < 3; ++c) s.tool.anchor.push_back(s.x[3 * v + c]);
}

void release(State& s) { s.tool = Tool{}; }

void internal_forces(const Model& m, const std::vector<double>& x, std::vector<double>& f) {
  f.resize(x.size());
  for (size_t k = 0; k < x.size(); ++k) f[k] = x[k] - m.rest[k];
  std::vector<double> u = f;
  stiffness_times(m, u.data(), f.data());
  for (double& v : f) v = -v;
}

StepInfo step(const Model& m, State& s, Work& w, double h) {
  StepInfo info;
  const Params& p = m.params;
  const size_t n = 3 * static_cast<size_t>(m.nvert);
  // Constrained vertices: fixed ones and the attached ones (moved along their path here).
  for (int32_t i = 0; i < m.nvert; ++i) w.constrained[i] = m.vert_fixed[i];
  if (s.tool.mode == Tool::attach) {
    s.tool.progress = std::min(s.tool.progress + 1, s.tool.iterations);
    const double lam = static_cast<double>(s.tool.progress) / s.tool.iterations;
    for (size_t k = 0; k < s.tool.verts.size(); ++k) {
      const int32_t v = s.tool.verts[k];
      w.constrained[v] = 1;
      for (int c = 0; c < 3; ++c) {
        const double target = s.tool.anchor[3 * k + c] + lam * s.tool.offset_m[c];
        s.v[3 * v + c] = (target - s.x[3 * v + c]) / h;
        s.x[3 * v + c] = target;
      }
    }
  }
  // r = h (f_ext - K u - C v - h K v), C = alpha M + beta K (paper 002 eqs 16, 22).
  for (size_t k = 0; k < n; ++k) w.d[k] = s.x[k] - m.rest[k];
  stiffness_times(m, w.d.data(), w.f.data());   // K u
  stiffness_times(m, s.v.data(), w.kv.data());  // K v
  for (size_t k = 0; k < n; ++k) {
    const double mass = m.vert_mass[k / 3];
    w.r[k] = h * (-w.f[k] - p.rayleigh_mass * mass * s.v[k] - (p.rayleigh_stiffness + h) * w.kv[k]);
  }
  if (s.tool.mode == Tool::force && !s.tool.verts.empty()) {
    const double share = 1.0 / static_cast<double>(s.tool.verts.size());
    for (int32_t v : s.tool.verts)
      for (int c = 0; c < 3; ++c) w.r[3 * v + c] += h * s.tool.force_N[c] * share;
  }
  // A = (1 + h alpha) M + (h beta + h^2) K; Jacobi preconditioner from the node tensors.
  const double am = 1.0 + h * p.rayleigh_mass, ak = h * p.rayleigh_stiffness + h * h;
  for (int32_t i = 0; i < m.nvert; ++i)
    for (int c = 0; c < 3; ++c) {
      w.diag[3 * i + c] = w.constrained[i] ? 1.0 : 1.0 / (am * m.vert_mass[i] + ak * m.node_tensor[9 * i + 4 * c]);
      if (w.constrained[i]) w.r[3 * i + c] = 0.0;
    }
  // Preconditioned CG on dv (w.s), constrained rows projected out.
  double rr0 = 0.0;
  for (size_t k = 0; k < n; ++k) {
    w.s[k] = 0.0;
    rr0 += w.r[k] * w.r[k];
  }
  double rz = 0.0;
  for (size_t k = 0; k < n; ++k) {
    w.d[k] = w.diag[k] * w.r[k];
    rz += w.r[k] * w.d[k];
  }
  const double stop = p.cg_tolerance * p.cg_tolerance * rr0;
  double rr = rr0;
  int it = 0;
  while (it < p.cg_iterations && rr > stop && rr0 > 0) {
    stiffness_times(m, w.d.data(), w.q.data());
    double dq = 0.0;
    for (size_t k = 0; k < n; ++k) {
      w.q[k] = w.constrained[k / 3] ? 0.0 : am * m.vert_mass[k / 3] * w.d[k] + ak * w.q[k];
      dq += w.d[k] * w.q[k];
    }
    if (!(dq > 0)) break;
    const double alpha = rz / dq;
    double rz_new = 0.0;
    rr = 0.0;
    for (size_t k = 0; k < n; ++k) {
      w.s[k] += alpha * w.d[k];
      w.r[k] -= alpha * w.q[k];
      rr += w.r[k] * w.r[k];
      rz_new += w.r[k] * w.diag[k] * w.r[k];
    }
    const double beta = rz_new / rz;
    rz = rz_new;
    for (size_t k = 0; k < n; ++k) w.d[k] = w.diag[k] * w.r[k] + beta * w.d[k];
    ++it;
  }
  info.cg_iterations = it;
  info.cg_residual = rr0 > 0 ? std::sqrt(rr / rr0) : 0.0;
  for (int32_t i = 0; i < m.nvert; ++i) {
    if (w.constrained[i]) {
      if (m.vert_fixed[i])
        for (int c = 0; c < 3; ++c) s.v[3 * i + c] = 0.0;
      continue;
    }
    double a2 = 0.0;
    for (int c = 0; c < 3; ++c) {
      const size_t k = 3 * static_cast<size_t>(i) + c;
      s.v[k] += w.s[k];
      s.x[k] += h * s.v[k];
      a2 += (w.s[k] / h) * (w.s[k] / h);
      info.finite = info.finite && std::isfinite(s.x[k]);
    }
    info.accel_sum += std::sqrt(a2);
  }
  s.time_s += h;
  return info;
}

std::array<double, 3> tool_reaction(const Model& m, const State& s, Work& w) {
  const size_t n = 3 * static_cast<size_t>(m.nvert);
  for (size_t k = 0; k < n; ++k) w.d[k] = s.x[k] - m.rest[k];
  stiffness_times(m, w.d.data(), w.f.data());
  std::array<double, 3> r{0, 0, 0};
  for (int32_t v : s.tool.verts)
    for (int c = 0; c < 3; ++c) r[c] -= w.f[3 * v + c];
  return r;
}

double energy(const Model& m, const State& s, Work& w) {
  const size_t n = 3 * static_cast<size_t>(m.nvert);
  for (size_t k = 0; k < n; ++k) w.d[k] = s.x[k] - m.rest[k];
  stiffness_times(m, w.d.data(), w.f.data());
  double e = 0.0;
  for (size_t k = 0; k < n; ++k) e += 0.5 * w.d[k] * w.f[k] + 0.5 * m.vert_mass[k / 3] * s.v[k] * s.v[k];
  return e;
}

double volume(const Model& m, const std::vector<double>& x) {
  double v = 0.0;
  for (size_t f = 0; f < m.faces.size() / 3; ++f)
    v += at(x, m.faces[3 * f]).dot(at(x, m.faces[3 * f + 1]).cross(at(x, m.faces[3 * f + 2]))) / 6.0;
  return v;
}

}  // namespace softatlas::sim::tmm
