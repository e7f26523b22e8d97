// Measurements of a state: volumes, displacement, energy, force and torque balance, positions in
// the source meshes' order. Used by tests, benchmarks and reports; may allocate.
#include <algorithm>
#include <cmath>

#include "engine.hpp"

namespace softatlas::sim {

double organ_volume(const Model& m, const State& s, int32_t organ) {
  const OrganRange& r = m.organs[organ];
  return enclosed_volume(s.x.data(), s.y.data(), s.z.data(), m.face_vert.data(), r.face_begin, r.face_end);
}

double total_volume(const Model& m, const State& s) {
  double v = 0;
  for (size_t o = 0; o < m.organs.size(); ++o) v += organ_volume(m, s, static_cast<int32_t>(o));
  return v;
}

double max_displacement(const Model& m, const State& s) {
  double d2 = 0;
  for (int32_t v = 0; v < m.nvert; ++v) {
    const double dx = s.x[v] - m.vert_rest_x[v], dy = s.y[v] - m.vert_rest_y[v], dz = s.z[v] - m.vert_rest_z[v];
    d2 = std::max(d2, dx * dx + dy * dy + dz * dz);
  }
  return std::sqrt(d2);
}

double total_energy(const Model& m, const State& s) {
  double e = solid_energy(m, s);  // solid organs: their lattice's energy, not their surface's
  for (int32_t v = 0; v < m.nvert; ++v)
    if (!solid_vertex(m, v)) e += 0.5 * m.vert_mass[v] * (s.vx[v] * s.vx[v] + s.vy[v] * s.vy[v] + s.vz[v] * s.vz[v]);
  for (int32_t q = 0; q < m.nspring; ++q) {
    const int32_t a = m.spring_a[q], b = m.spring_b[q];
    const double dx = s.x[b] - s.x[a], dy = s.y[b] - s.y[a], dz = s.z[b] - s.z[a];
    const double l = std::sqrt(dx * dx + dy * dy + dz * dz) - m.spring_length0[q];
    e += 0.5 * m.spring_k[q] * l * l;
  }
  for (int32_t q = 0; q < m.nconn; ++q) {
    const int32_t a = m.conn_a[q], b = m.conn_b[q];
    const double dx = s.x[b] - s.x[a], dy = s.y[b] - s.y[a], dz = s.z[b] - s.z[a];
    const double l = std::sqrt(dx * dx + dy * dy + dz * dz) - m.conn_rest[q];
    e += 0.5 * m.conn_k[q] * l * l;
  }
  if (m.gravity)
    for (int32_t v = 0; v < m.nvert; ++v)
      if (!solid_vertex(m, v))
        e -= m.vert_mass[v] *
             (m.gravity_m_s2[0] * (s.x[v] - m.vert_rest_x[v]) + m.gravity_m_s2[1] * (s.y[v] - m.vert_rest_y[v]) +
              m.gravity_m_s2[2] * (s.z[v] - m.vert_rest_z[v]));
  return e;
}

void compute_internal_forces(const Model& m, const State& s, Work& w) {
  State awake = s;  // measurement helper (tests, reports): may allocate
  std::fill(awake.organ_awake.begin(), awake.organ_awake.end(), 1);
  engine::internal_forces(m, awake, w);
}

void internal_force_and_torque(const Model& m, const State& s, Work& w, std::array<double, 3>& force,
                               std::array<double, 3>& torque) {
  compute_internal_forces(m, s, w);
  force = {0, 0, 0};
  torque = {0, 0, 0};
  for (int32_t v = 0; v < m.nvert; ++v) {
    force[0] += w.fx[v], force[1] += w.fy[v], force[2] += w.fz[v];
    torque[0] += s.y[v] * w.fz[v] - s.z[v] * w.fy[v];
    torque[1] += s.z[v] * w.fx[v] - s.x[v] * w.fz[v];
    torque[2] += s.x[v] * w.fy[v] - s.y[v] * w.fx[v];
  }
}

void organ_positions(const Model& m, const State& s, int32_t organ, std::vector<double>& out) {
  const OrganRange& r = m.organs[organ];
  out.assign(3 * static_cast<size_t>(r.source_vertex_count), 0.0);
  for (int32_t v = r.vert_begin; v < r.vert_end; ++v) {
    const size_t q = 3 * static_cast<size_t>(m.vert_source[v]);
    out[q] = s.x[v], out[q + 1] = s.y[v], out[q + 2] = s.z[v];
  }
}

int32_t global_vertex(const Model& m, int32_t organ, int32_t source_vertex) {
  const OrganRange& r = m.organs[organ];
  for (int32_t v = r.vert_begin; v < r.vert_end; ++v)
    if (m.vert_source[v] == source_vertex) return v;
  return -1;
}

int32_t find_organ(const Model& m, const std::string& name) {
  for (size_t o = 0; o < m.organs.size(); ++o)
    if (m.organs[o].name == name) return static_cast<int32_t>(o);
  return -1;
}

}  // namespace softatlas::sim
