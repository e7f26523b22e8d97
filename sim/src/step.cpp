// The step: forces, integrators (paper 000 Algorithm 1, symplectic Euler, implicit Euler + CG),
// constraint passes (compensation, volume), the tool, sleeping organs and the stability guard.
// Nothing here allocates or throws: every buffer was sized by make_work().
#include <algorithm>
#include <cmath>
#include <cstring>

#include "forces.hpp"
#include "workers.hpp"
#include "softatlas/sim/sim.hpp"

namespace softatlas::sim {
namespace {

using kernels::kTiny;
constexpr int kSnapshotEvery = 16;

// ---- curvature (paper 000 eq 2) into work.half_bk for one organ ------------------------------
void curvature_pass(const Model& m, const OrganRange& r, const State& s, Work& w) {
  const int32_t vb = r.vert_begin, ve = r.vert_end;
  std::fill(w.lap_x.begin() + vb, w.lap_x.begin() + ve, 0.0);
  std::fill(w.lap_y.begin() + vb, w.lap_y.begin() + ve, 0.0);
  std::fill(w.lap_z.begin() + vb, w.lap_z.begin() + ve, 0.0);
  std::fill(w.area2.begin() + vb, w.area2.begin() + ve, 0.0);
  accumulate_cotan_laplacian(r.face_end - r.face_begin, m.face_vert.data() + 3 * r.face_begin,
                             s.x.data(), s.y.data(), s.z.data(), w.lap_x.data(), w.lap_y.data(),
                             w.lap_z.data(), w.area2.data());
  // h_i = coef * H_i, H_i = 1.5 |L_i| / area2_i (geometry.cpp); coef = b L / 2 (p = 1) or
  // sqrt(b) L / 2 (p = 2), so that the spring kernel reads a + h_a + h_b or a + (h_a + h_b)^2.
  const double coef = 1.5 * (r.elastica_p == 1 ? 0.5 * r.elastica_b * r.curvature_unit_m
                                                : 0.5 * std::sqrt(r.elastica_b) * r.curvature_unit_m);
  const double* __restrict lx = w.lap_x.data();
  const double* __restrict ly = w.lap_y.data();
  const double* __restrict lz = w.lap_z.data();
  const double* __restrict a2 = w.area2.data();
  double* __restrict h = w.half_bk.data();
  for (int32_t v = vb; v < ve; ++v) {
    const double l = std::sqrt(lx[v] * lx[v] + ly[v] * ly[v] + lz[v] * lz[v]);
    h[v] = a2[v] > kTiny ? coef * l / a2[v] : 0.0;
  }
}

template <int P>
void organ_springs(const Model& m, const OrganRange& r, const State& s, Work& w) {
  if (r.damping)
    kernels::spring_forces<P, true>(r.spring_begin, r.spring_end, m.spring_a.data(),
                                    m.spring_b.data(), m.spring_rest.data(), m.spring_k.data(),
                                    m.spring_d.data(), r.elastica_a, r.elastica_cap, s.x.data(), s.y.data(),
                                    s.z.data(), s.vx.data(), s.vy.data(), s.vz.data(),
                                    w.half_bk.data(), w.fx.data(), w.fy.data(), w.fz.data());
  else
    kernels::spring_forces<P, false>(r.spring_begin, r.spring_end, m.spring_a.data(),
                                     m.spring_b.data(), m.spring_rest.data(), m.spring_k.data(),
                                     m.spring_d.data(), r.elastica_a, r.elastica_cap, s.x.data(), s.y.data(),
                                     s.z.data(), s.vx.data(), s.vy.data(), s.vz.data(),
                                     w.half_bk.data(), w.fx.data(), w.fy.data(), w.fz.data());
}

// Which spring measure an organ uses: 0 Hooke, 1/2 elastica p, 3 elastica with b = 0.
int spring_measure_kind(const OrganRange& r) {
  if (r.model != ModelKind::nmsm) return 0;
  if (!r.curvature) return 3;
  return r.elastica_p;
}

// Flexion (dihedral) springs, energy 1/2 k (theta - theta0)^2 (paper 003 flexion springs in the
// rotation-invariant dihedral form, docs/physics.md). Gradients of theta (Bridson et al. 2003):
//   g_c = -|e| n1 / |n1|^2, g_d = -|e| n2 / |n2|^2,
//   g_a = -((1 - t_c) g_c + (1 - t_d) g_d), g_b = -(t_c g_c + t_d g_d),
// t_c = (c - a).e / |e|^2 (where c projects on the edge), e = b - a.
void flexion_forces(const Model& m, const OrganRange& r, const State& s, Work& w,
                    double* grad_out = nullptr) {
  const double* X = s.x.data();
  const double* Y = s.y.data();
  const double* Z = s.z.data();
  for (int32_t f = r.flex_begin; f < r.flex_end; ++f) {
    const int32_t a = m.flex_a[f], b = m.flex_b[f], c = m.flex_c[f], d = m.flex_d[f];
    const double pa[3] = {X[a], Y[a], Z[a]}, pb[3] = {X[b], Y[b], Z[b]}, pc[3] = {X[c], Y[c], Z[c]},
                 pd[3] = {X[d], Y[d], Z[d]};
    const double e[3] = {pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]};
    const double u[3] = {pc[0] - pa[0], pc[1] - pa[1], pc[2] - pa[2]};
    const double q[3] = {pd[0] - pb[0], pd[1] - pb[1], pd[2] - pb[2]};
    const double n1[3] = {e[1] * u[2] - e[2] * u[1], e[2] * u[0] - e[0] * u[2], e[0] * u[1] - e[1] * u[0]};
    // n2 = (a - b) x (d - b) = -e x q
    const double n2[3] = {-(e[1] * q[2] - e[2] * q[1]), -(e[2] * q[0] - e[0] * q[2]),
                          -(e[0] * q[1] - e[1] * q[0])};
    const double n1s = n1[0] * n1[0] + n1[1] * n1[1] + n1[2] * n1[2];
    const double n2s = n2[0] * n2[0] + n2[1] * n2[1] + n2[2] * n2[2];
    const double es = e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
    if (grad_out) std::fill(grad_out + 12 * f, grad_out + 12 * f + 12, 0.0);
    if (!(n1s > kTiny) || !(n2s > kTiny) || !(es > kTiny)) continue;  // degenerate wing
    const double el = std::sqrt(es);
    double theta = dihedral_angle(pa, pb, pc, pd) - m.flex_rest_angle[f];
    if (theta > M_PI) theta -= 2 * M_PI;
    if (theta < -M_PI) theta += 2 * M_PI;
    const double tc = (u[0] * e[0] + u[1] * e[1] + u[2] * e[2]) / es;
    const double td = ((pd[0] - pa[0]) * e[0] + (pd[1] - pa[1]) * e[1] + (pd[2] - pa[2]) * e[2]) / es;
    double gc[3], gd[3];
    for (int i = 0; i < 3; ++i) gc[i] = -el * n1[i] / n1s, gd[i] = -el * n2[i] / n2s;
    const double coef = -m.flex_k[f] * theta;  // F = -k (theta - theta0) grad theta
    for (int i = 0; i < 3; ++i) {
      const double ga = -((1 - tc) * gc[i] + (1 - td) * gd[i]);
      const double gb = -(tc * gc[i] + td * gd[i]);
      double* F[3] = {w.fx.data(), w.fy.data(), w.fz.data()};
      F[i][a] += coef * ga, F[i][b] += coef * gb, F[i][c] += coef * gc[i], F[i][d] += coef * gd[i];
      if (grad_out) {
        double* g = grad_out + 12 * f;
        g[i] = ga, g[3 + i] = gb, g[6 + i] = gc[i], g[9 + i] = gd[i];
      }
    }
  }
}

void connection_forces(const Model& m, const State& s, Work& w) {
  if (m.nconn == 0) return;
  // Connections are Hooke springs with damping; a sleeping organ's side still feels them.
  kernels::spring_forces<0, true>(0, m.nconn, m.conn_a.data(), m.conn_b.data(),
                                  m.conn_rest.data(), m.conn_k.data(), m.conn_d.data(), 1.0, 0.0,
                                  s.x.data(), s.y.data(), s.z.data(), s.vx.data(), s.vy.data(),
                                  s.vz.data(), nullptr, w.fx.data(), w.fy.data(), w.fz.data());
}

// One organ's springs (with its curvature pass) and flexion springs, added into work.f.
void organ_internal_forces(const Model& m, const OrganRange& r, const State& s, Work& w) {
  switch (spring_measure_kind(r)) {
    case 0: organ_springs<0>(m, r, s, w); break;
    case 1: curvature_pass(m, r, s, w); organ_springs<1>(m, r, s, w); break;
    case 2: curvature_pass(m, r, s, w); organ_springs<2>(m, r, s, w); break;
    default: organ_springs<3>(m, r, s, w); break;
  }
  if (r.flex_end > r.flex_begin) flexion_forces(m, r, s, w);
}

// Internal forces of the organs that hold a tool vertex, and of the connections; other organs'
// force entries are left as they are (forces_zero becomes false).
void tool_organ_forces(const Model& m, const State& s, Work& w) {
  std::fill(w.organ_flag.begin(), w.organ_flag.end(), uint8_t{0});
  for (int32_t v : s.tool.verts) w.organ_flag[m.vert_organ[v]] = 1;
  for (size_t o = 0; o < m.organs.size(); ++o) {
    const OrganRange& r = m.organs[o];
    if (!w.organ_flag[o]) continue;
    std::fill(w.fx.begin() + r.vert_begin, w.fx.begin() + r.vert_end, 0.0);
    std::fill(w.fy.begin() + r.vert_begin, w.fy.begin() + r.vert_end, 0.0);
    std::fill(w.fz.begin() + r.vert_begin, w.fz.begin() + r.vert_end, 0.0);
  }
  w.forces_zero = false;
  for (size_t o = 0; o < m.organs.size(); ++o)
    if (w.organ_flag[o] && s.organ_awake[o]) organ_internal_forces(m, m.organs[o], s, w);
  connection_forces(m, s, w);
}

// All internal forces of awake organs into work.f (zeroed first unless the explicit update
// already left them zero: it clears them as it consumes them, as bench-ref does).
void internal_forces(const Model& m, const State& s, Work& w) {
  if (!w.forces_zero) {
    std::fill(w.fx.begin(), w.fx.end(), 0.0);
    std::fill(w.fy.begin(), w.fy.end(), 0.0);
    std::fill(w.fz.begin(), w.fz.end(), 0.0);
  }
  w.forces_zero = false;
  for (size_t o = 0; o < m.organs.size(); ++o)
    if (s.organ_awake[o]) organ_internal_forces(m, m.organs[o], s, w);
  connection_forces(m, s, w);
}

// The tool's force or hold, and its reaction (force of the organ on the tool), after the
// internal forces are in work.f.
void apply_tool(const Model& m, State& s, Work& w, bool reaction = true, bool add_force = true) {
  ToolState& t = s.tool;
  if (reaction) t.reaction_N = {0, 0, 0};
  if (t.mode == ToolMode::none || t.verts.empty()) return;
  if (reaction)
    for (int32_t v : t.verts) {
      t.reaction_N[0] += w.fx[v], t.reaction_N[1] += w.fy[v], t.reaction_N[2] += w.fz[v];
    }
  if (t.mode == ToolMode::force && add_force) {
    double F[3] = {t.force_N[0], t.force_N[1], t.force_N[2]};
    const double mag = std::sqrt(F[0] * F[0] + F[1] * F[1] + F[2] * F[2]);
    t.clamped = false;
    if (m.guard && mag > m.max_tool_force_N) {
      const double sc = m.max_tool_force_N / mag;
      F[0] *= sc, F[1] *= sc, F[2] *= sc;
      t.clamped = true;
    }
    const double share = 1.0 / static_cast<double>(t.verts.size());
    for (int32_t v : t.verts) w.fx[v] += F[0] * share, w.fy[v] += F[1] * share, w.fz[v] += F[2] * share;
  }
}

// Where the attached vertices are held at the end of (sub)step fraction `frac` of this step.
void attach_targets(const Model& m, const State& s, Work& w, double frac) {
  const ToolState& t = s.tool;
  const double p0 = std::min(1.0, static_cast<double>(t.attach_progress) / t.attach_iterations);
  const double p1 = std::min(1.0, static_cast<double>(t.attach_progress + 1) / t.attach_iterations);
  const double p = p0 + (p1 - p0) * frac;
  for (size_t q = 0; q < t.verts.size(); ++q)
    for (int c = 0; c < 3; ++c) w.tool_target[3 * q + c] = t.anchor[3 * q + c] + p * t.offset_m[c];
}

// Held vertices get the velocity that carries them to their target over h; with
// `snap` their positions are set to the target as well (before an implicit solve, or after an
// explicit update to remove rounding).
void hold_attached(State& s, const Work& w, double h, bool snap) {
  const ToolState& t = s.tool;
  for (size_t q = 0; q < t.verts.size(); ++q) {
    const int32_t v = t.verts[q];
    const double nx = w.tool_target[3 * q], ny = w.tool_target[3 * q + 1], nz = w.tool_target[3 * q + 2];
    s.vx[v] = (nx - s.x[v]) / h, s.vy[v] = (ny - s.y[v]) / h, s.vz[v] = (nz - s.z[v]) / h;
    if (snap) s.x[v] = nx, s.y[v] = ny, s.z[v] = nz;
  }
}

void snap_attached(State& s, const Work& w) {
  const ToolState& t = s.tool;
  for (size_t q = 0; q < t.verts.size(); ++q) {
    const int32_t v = t.verts[q];
    s.x[v] = w.tool_target[3 * q], s.y[v] = w.tool_target[3 * q + 1], s.z[v] = w.tool_target[3 * q + 2];
  }
}

struct IntegrateStats {
  double max_speed2 = 0.0;
  double checksum = 0.0;
  double accel_sum = 0.0;
  int cg_iterations = 0;
};

// Explicit update of one organ's free vertices. Semi-implicit Euler: v += h (F/m + g),
// x += h v. Paper 000 Algorithm 1 (lines 9-10): p = x + v h + F h^2 / mu, v = (p - x) / h,
// x = p; algebraically the same scheme, written in position form (docs/physics.md).
template <bool Verlet>
void integrate_organ(const Model& m, const OrganRange& r, State& s, Work& w, double h,
                     IntegrateStats& st) {
  const double gx = m.gravity ? m.gravity_m_s2[0] : 0.0, gy = m.gravity ? m.gravity_m_s2[1] : 0.0,
               gz = m.gravity ? m.gravity_m_s2[2] : 0.0;
  const double* __restrict mask = w.free_mask.data();
  const double* __restrict inv = m.vert_inv_mass.data();
  double* __restrict x = s.x.data();
  double* __restrict y = s.y.data();
  double* __restrict z = s.z.data();
  double* __restrict vx = s.vx.data();
  double* __restrict vy = s.vy.data();
  double* __restrict vz = s.vz.data();
  double* __restrict fx = w.fx.data();
  double* __restrict fy = w.fy.data();
  double* __restrict fz = w.fz.data();
  double vmax2 = 0.0, sum = 0.0, asum = 0.0;
  const bool accel = w.measure_accel;
  if (accel)
    for (int32_t i = r.vert_begin; i < r.vert_end; ++i) {
      const double wi = inv[i] * mask[i], g = mask[i];
      const double ax = wi * fx[i] + g * gx, ay = wi * fy[i] + g * gy, az = wi * fz[i] + g * gz;
      asum += wi > 0 ? std::sqrt(ax * ax + ay * ay + az * az) : 0.0;
    }
#pragma omp simd reduction(max : vmax2) reduction(+ : sum)
  for (int32_t i = r.vert_begin; i < r.vert_end; ++i) {
    const double wi = inv[i] * mask[i], g = mask[i];
    const double ax = wi * fx[i] + g * gx, ay = wi * fy[i] + g * gy, az = wi * fz[i] + g * gz;
    if constexpr (Verlet) {
      const double px = x[i] + vx[i] * h + ax * h * h, py = y[i] + vy[i] * h + ay * h * h,
                   pz = z[i] + vz[i] * h + az * h * h;
      vx[i] = (px - x[i]) / h, vy[i] = (py - y[i]) / h, vz[i] = (pz - z[i]) / h;
      x[i] = px, y[i] = py, z[i] = pz;
    } else {
      vx[i] += h * ax, vy[i] += h * ay, vz[i] += h * az;
      x[i] += h * vx[i], y[i] += h * vy[i], z[i] += h * vz[i];
    }
    fx[i] = 0.0, fy[i] = 0.0, fz[i] = 0.0;
    const double sp = vx[i] * vx[i] + vy[i] * vy[i] + vz[i] * vz[i];
    vmax2 = sp > vmax2 ? sp : vmax2;
    sum += x[i] + y[i] + z[i] + sp;
  }
  st.max_speed2 = std::max(st.max_speed2, vmax2);
  st.checksum += sum;
  st.accel_sum += asum;
}

// Over-stretch / over-compress compensation (Duan et al. 2016; paper 000 CMSM and the tau_s of
// Table III): springs longer than (1 + tau_s) l0 or shorter than (1 - tau_c) l0 are moved back to
// that bound, split by inverse mass (Provot 1995), then velocities follow the correction.
void compensation_pass(const Model& m, const OrganRange& r, State& s, Work& w, double h) {
  const int32_t vb = r.vert_begin, ve = r.vert_end;
  std::copy(s.x.begin() + vb, s.x.begin() + ve, w.px.begin() + vb);
  std::copy(s.y.begin() + vb, s.y.begin() + ve, w.py.begin() + vb);
  std::copy(s.z.begin() + vb, s.z.begin() + ve, w.pz.begin() + vb);
  const double hi = r.tau_s >= 0 ? 1.0 + r.tau_s : 1e300;
  const double lo = r.tau_c >= 0 ? 1.0 - r.tau_c : 0.0;

  for (int it = 0; it < r.compensation_iterations; ++it) {
    for (int32_t q = r.spring_begin; q < r.spring_end; ++q) {
      const int32_t a = m.spring_a[q], b = m.spring_b[q];
      const double wa = m.vert_inv_mass[a] * w.free_mask[a], wb = m.vert_inv_mass[b] * w.free_mask[b];
      if (wa + wb <= 0) continue;
      const double dx = s.x[b] - s.x[a], dy = s.y[b] - s.y[a], dz = s.z[b] - s.z[a];
      const double l = std::sqrt(dx * dx + dy * dy + dz * dz);
      const double l0 = m.spring_length0[q];
      double target;
      if (l > hi * l0) target = hi * l0;
      else if (l < lo * l0) target = lo * l0;
      else continue;
      if (!(l > kTiny)) continue;
      const double corr = (l - target) / (l * (wa + wb));
      s.x[a] += wa * corr * dx, s.y[a] += wa * corr * dy, s.z[a] += wa * corr * dz;
      s.x[b] -= wb * corr * dx, s.y[b] -= wb * corr * dy, s.z[b] -= wb * corr * dz;
    }
  }
  for (int32_t v = vb; v < ve; ++v) {
    s.vx[v] += (s.x[v] - w.px[v]) / h, s.vy[v] += (s.y[v] - w.py[v]) / h, s.vz[v] += (s.z[v] - w.pz[v]) / h;
  }
}

// Volume constraint (paper 003 eqs 25-30) on the fan of tetrahedra that the closed surface
// forms with any point: C = V - V0, grad_i C = 1/6 sum_{faces (i,j,k)} x_j x x_k,
// dx_i = -s C w_i grad_i C / sum_j w_j |grad_j C|^2 (one projection per step, stiffness s).
void volume_pass(const Model& m, const OrganRange& r, State& s, Work& w, double h) {
  const int32_t vb = r.vert_begin, ve = r.vert_end;
  std::fill(w.lap_x.begin() + vb, w.lap_x.begin() + ve, 0.0);
  std::fill(w.lap_y.begin() + vb, w.lap_y.begin() + ve, 0.0);
  std::fill(w.lap_z.begin() + vb, w.lap_z.begin() + ve, 0.0);
  const double* X = s.x.data();
  const double* Y = s.y.data();
  const double* Z = s.z.data();
  const double vol = enclosed_volume(X, Y, Z, m.face_vert.data(), r.face_begin, r.face_end);
  const double C = vol - r.rest_volume_m3;
  for (int32_t f = r.face_begin; f < r.face_end; ++f) {
    const int32_t i = m.face_vert[3 * f], j = m.face_vert[3 * f + 1], k = m.face_vert[3 * f + 2];
    auto add = [&](int32_t v, int32_t p, int32_t q) {  // x_p x x_q / 6
      w.lap_x[v] += (Y[p] * Z[q] - Z[p] * Y[q]) / 6.0;
      w.lap_y[v] += (Z[p] * X[q] - X[p] * Z[q]) / 6.0;
      w.lap_z[v] += (X[p] * Y[q] - Y[p] * X[q]) / 6.0;
    };
    add(i, j, k), add(j, k, i), add(k, i, j);
  }
  double denom = 0.0;
  for (int32_t v = vb; v < ve; ++v)
    denom += m.vert_inv_mass[v] * w.free_mask[v] *
             (w.lap_x[v] * w.lap_x[v] + w.lap_y[v] * w.lap_y[v] + w.lap_z[v] * w.lap_z[v]);
  if (!(denom > kTiny)) return;
  const double lambda = -r.volume_stiffness * C / denom;
  for (int32_t v = vb; v < ve; ++v) {
    const double wv = m.vert_inv_mass[v] * w.free_mask[v] * lambda;
    const double dx = wv * w.lap_x[v], dy = wv * w.lap_y[v], dz = wv * w.lap_z[v];
    s.x[v] += dx, s.y[v] += dy, s.z[v] += dz;
    s.vx[v] += dx / h, s.vy[v] += dy / h, s.vz[v] += dz / h;
  }
}

// Position corrections act as forces m dx / h^2; on the tool's vertices they are part of the
// reaction (a compensated spring holds the load through its correction, not its Hooke force).
void constraint_passes(const Model& m, State& s, Work& w, double h) {
  ToolState& t = s.tool;
  const bool tool = t.mode == ToolMode::force && !t.verts.empty();
  std::array<double, 3> before{0, 0, 0};
  bool any = false;
  for (size_t o = 0; o < m.organs.size(); ++o) {
    if (!s.organ_awake[o]) continue;
    const OrganRange& r = m.organs[o];
    if (r.compensation_iterations <= 0 && r.volume_stiffness <= 0) continue;
    if (tool && !any)
      for (int32_t v : t.verts)
        before[0] += m.vert_mass[v] * s.x[v], before[1] += m.vert_mass[v] * s.y[v], before[2] += m.vert_mass[v] * s.z[v];
    any = true;
    if (r.compensation_iterations > 0) compensation_pass(m, r, s, w, h);
    if (r.volume_stiffness > 0) volume_pass(m, r, s, w, h);
  }
  if (tool && any) {
    std::array<double, 3> after{0, 0, 0};
    for (int32_t v : t.verts)
      after[0] += m.vert_mass[v] * s.x[v], after[1] += m.vert_mass[v] * s.y[v], after[2] += m.vert_mass[v] * s.z[v];
    for (int c = 0; c < 3; ++c) t.reaction_N[c] += (after[c] - before[c]) / (h * h);
  }
}

// free_mask = fixed vertices and vertices held by an attachment excluded. Recomputed only when
// an attachment is (or was) active.
void set_free_mask(const Model& m, const State& s, Work& w) {
  const bool attach = s.tool.mode == ToolMode::attach;
  if (!attach && !w.mask_dirty) return;
  for (int32_t v = 0; v < m.nvert; ++v) w.free_mask[v] = m.vert_inv_mass[v] > 0 && !solid_vertex(m, v) ? 1.0 : 0.0;
  if (attach)
    for (int32_t v : s.tool.verts) w.free_mask[v] = 0.0;
  w.mask_dirty = attach;
}

// Explicit sub-step with the organs spread over the worker threads: each thread computes its
// organs' internal forces (organs own disjoint vertex ranges, so no two threads write the same
// force), the calling thread adds connections and the tool, then each thread integrates its
// organs.
struct ParallelSubstep {
  const Model* m;
  State* s;
  Work* w;
  double h;
  bool verlet;
  int phase;
  IntegrateStats stats[64];
};

void parallel_job(void* context, int t) {
  ParallelSubstep& p = *static_cast<ParallelSubstep*>(context);
  const Model& m = *p.m;
  State& s = *p.s;
  Work& w = *p.w;
  for (int32_t o : w.workers->organs[t]) {
    const OrganRange& r = m.organs[o];
    if (p.phase == 0) {
      if (!w.forces_zero) {
        std::fill(w.fx.begin() + r.vert_begin, w.fx.begin() + r.vert_end, 0.0);
        std::fill(w.fy.begin() + r.vert_begin, w.fy.begin() + r.vert_end, 0.0);
        std::fill(w.fz.begin() + r.vert_begin, w.fz.begin() + r.vert_end, 0.0);
      }
      if (s.organ_awake[o]) organ_internal_forces(m, r, s, w);
    } else if (s.organ_awake[o]) {
      if (p.verlet) integrate_organ<true>(m, r, s, w, p.h, p.stats[t]);
      else integrate_organ<false>(m, r, s, w, p.h, p.stats[t]);
    }
  }
}

IntegrateStats explicit_substep_parallel(const Model& m, State& s, Work& w, double h, bool verlet,
                                         double frac) {
  const bool attached = s.tool.mode == ToolMode::attach && !s.tool.verts.empty();
  ParallelSubstep p{&m, &s, &w, h, verlet, 0, {}};
  w.workers->run(parallel_job, &p);
  w.forces_zero = false;
  connection_forces(m, s, w);
  apply_tool(m, s, w);
  if (attached) {
    attach_targets(m, s, w, frac);
    hold_attached(s, w, h, /*snap=*/false);
  }
  p.phase = 1;
  w.workers->run(parallel_job, &p);
  IntegrateStats st;
  for (int t = 0; t < w.workers->threads(); ++t) {
    st.max_speed2 = std::max(st.max_speed2, p.stats[t].max_speed2);
    st.checksum += p.stats[t].checksum;
    st.accel_sum += p.stats[t].accel_sum;
  }
  bool all_awake = true;
  for (uint8_t a : s.organ_awake) all_awake = all_awake && a;
  w.forces_zero = all_awake;
  if (attached) snap_attached(s, w);
  constraint_passes(m, s, w, h);
  return st;
}

IntegrateStats explicit_substep(const Model& m, State& s, Work& w, double h, bool verlet,
                                double frac) {
  if (w.workers) return explicit_substep_parallel(m, s, w, h, verlet, frac);
  const bool attached = s.tool.mode == ToolMode::attach && !s.tool.verts.empty();
  internal_forces(m, s, w);
  apply_tool(m, s, w);
  if (attached) {  // held vertices: zero acceleration, velocity that lands them on the target
    attach_targets(m, s, w, frac);
    hold_attached(s, w, h, /*snap=*/false);
  }
  IntegrateStats st;
  bool all_awake = true;
  for (size_t o = 0; o < m.organs.size(); ++o) {
    if (!s.organ_awake[o]) { all_awake = false; continue; }
    if (verlet) integrate_organ<true>(m, m.organs[o], s, w, h, st);
    else integrate_organ<false>(m, m.organs[o], s, w, h, st);
  }
  w.forces_zero = all_awake;
  if (attached) snap_attached(s, w);
  constraint_passes(m, s, w, h);
  return st;
}

// ---- implicit Euler (Baraff & Witkin 1998), linearised once per step -------------------------
// (M - h D - h^2 K) dv = h (f0 + h K v0); v1 = v0 + dv; x1 = x0 + h v1.
// Per spring the block of -h D - h^2 K is B = alpha I + beta u u^T with
//   alpha = h^2 k_e max(0, 1 - L_e / l),  beta = h d + h^2 k_e - alpha,
// where k_e, L_e are the stiffness and rest length of the spring written as Hooke on l
// (elastica: curvature frozen over the step, k_e = k (a + h_a + h_b), L_e = l_e0 / (a + ...)).
// The max(0, .) drops the indefinite compressive part so that CG sees an SPD matrix.
// Flexion springs and the volume / compensation passes are treated explicitly.
// Per spring: alpha and w = sqrt(beta) u, so the block is alpha I + w w^T (beta >= 0 always),
// stored as 4 floats (w_x, w_y, w_z, alpha).
//
// The CG runs in float on 4-float vertex vectors (x, y, z, 0): one 16-byte load per vertex
// instead of three scattered doubles. Reductions are summed in double.
using f4 = float __attribute__((vector_size(16)));
using i4 = int32_t __attribute__((vector_size(16)));
using d4 = double __attribute__((vector_size(32)));

using f8 = float __attribute__((vector_size(32)));
using i8 = int32_t __attribute__((vector_size(32)));
template <class V>
inline V load_vec(const float* p) {  // unaligned load of a 4- or 8-float vector
  V v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline f4 load4(const float* p) { return load_vec<f4>(p); }
inline f8 load8(const float* p) { return load_vec<f8>(p); }
inline void store4(float* p, f4 v) { std::memcpy(p, &v, sizeof v); }
inline f8 splat8(float a) { return f8{a, a, a, a, a, a, a, a}; }
inline f8 join(f4 a, f4 b) { return __builtin_shufflevector(a, b, 0, 1, 2, 3, 4, 5, 6, 7); }
inline f4 splat4(float a) { return f4{a, a, a, a}; }
inline double hsum3(d4 v) { return v[0] + v[1] + v[2]; }
// x . y over the first three lanes
inline f4 dot3(f4 a, f4 b) {  // broadcast to every lane; lane 3 of a must be 0
  f4 t = a * b;
  t += __builtin_shufflevector(t, t, 1, 0, 3, 2);
  t += __builtin_shufflevector(t, t, 2, 3, 0, 1);
  return t;
}
constexpr i4 kXYZ = {-1, -1, -1, 0};
constexpr i8 kXYZ8 = {-1, -1, -1, 0, -1, -1, -1, 0};
constexpr double kCgFloatFloor = 1e-7;  // relative residual a float CG can reach
constexpr int32_t kCgChunk = 256;       // springs per chunk of the vectorised block assembly

// Springs whose blocks are assembled: ends, spring index (sp == nullptr: t itself), Hooke/elastica
// parameters, and where the blocks go (4 floats per spring, at t).
struct BlockSprings {
  const int32_t *sa, *sb, *sp;
  const double *rest, *k, *d;  // d == nullptr: no damping
  double a, cap;               // elastica factor (P = 1, 2, 3)
  float* blk;
};

// Blocks and right-hand-side terms of springs [begin, end), in chunks: a vectorised pass
// computes each spring's block and term, then a scalar pass scatters the terms to both ends
// (the edge springs come in the CG's interleaved order, Work::cg_sa/cg_sb/cg_s, so consecutive
// ones share no vertex).
// `slot`: which chunk scratch of Work::cg_tmp to use (the worker thread's index).
template <int P>
__attribute__((noinline)) void assemble_blocks(int32_t begin, int32_t end, const BlockSprings& S,
                                               const double* hv, const State& s, Work& w, double h,
                                               int slot) {
  const int32_t* __restrict sa = S.sa;
  const int32_t* __restrict sb = S.sb;
  const int32_t* __restrict sp = S.sp;
  const double* __restrict rest = S.rest;
  const double* __restrict kk = S.k;
  const double* __restrict d = S.d;
  const double* __restrict x = s.x.data();
  const double* __restrict y = s.y.data();
  const double* __restrict z = s.z.data();
  const double* __restrict vx = s.vx.data();
  const double* __restrict vy = s.vy.data();
  const double* __restrict vz = s.vz.data();
  float* __restrict blk = S.blk;
  double* __restrict tmp = w.cg_tmp.data() + 6 * static_cast<size_t>(kCgChunk) * slot;  // g (3), diagonal (3)
  double* __restrict rx = w.rx.data();
  double* __restrict ry = w.ry.data();
  double* __restrict rz = w.rz.data();
  double* __restrict dgx = w.diag_x.data();
  double* __restrict dgy = w.diag_y.data();
  double* __restrict dgz = w.diag_z.data();
  const double a = S.a, cap = S.cap, h2 = h * h;
  for (int32_t c = begin; c < end; c += kCgChunk) {
    const int32_t ce = std::min(end, c + kCgChunk);
#pragma omp simd
    for (int32_t t = c; t < ce; ++t) {
      const int32_t i = sa[t], j = sb[t], q = sp ? sp[t] : t, k = t - c;
      const double dx = x[j] - x[i], dy = y[j] - y[i], dz = z[j] - z[i];
      const double l = std::sqrt(dx * dx + dy * dy + dz * dz);
      const double inv = 1.0 / (l > kTiny ? l : kTiny);
      const double ux = dx * inv, uy = dy * inv, uz = dz * inv;
      double factor = 1.0;
      if constexpr (P == 1) factor = a + std::min(hv[i] + hv[j], cap);
      if constexpr (P == 2) factor = a + std::min((hv[i] + hv[j]) * (hv[i] + hv[j]), cap);
      if constexpr (P == 3) factor = a;
      const double ke = kk[q] * factor, Le = rest[q] / factor;
      const double dq = d ? d[q] : 0.0;
      const double cc = 1.0 - Le * inv;
      const double alpha = h2 * ke * (cc > 0.0 ? cc : 0.0);
      const double kbeta = h2 * ke - alpha;  // stiffness part of beta
      const double dvx = vx[j] - vx[i], dvy = vy[j] - vy[i], dvz = vz[j] - vz[i];
      const double dvu = dvx * ux + dvy * uy + dvz * uz;
      const double f = ke * (l - Le) + dq * dvu;  // eqs 6-7 at x0, v0
      // h f u + h^2 K v0 at i (K pulls i toward j's motion)
      tmp[k] = h * f * ux + alpha * dvx + kbeta * dvu * ux;
      tmp[kCgChunk + k] = h * f * uy + alpha * dvy + kbeta * dvu * uy;
      tmp[2 * kCgChunk + k] = h * f * uz + alpha * dvz + kbeta * dvu * uz;
      const double bb = kbeta + h * dq;
      const double sbeta = std::sqrt(bb > 0.0 ? bb : 0.0);
      const float fa = static_cast<float>(alpha), wx = static_cast<float>(sbeta * ux),
                  wy = static_cast<float>(sbeta * uy), wz = static_cast<float>(sbeta * uz);
      blk[4 * t] = wx, blk[4 * t + 1] = wy, blk[4 * t + 2] = wz, blk[4 * t + 3] = fa;
      // Jacobi diagonal of the same (rounded) block
      tmp[3 * kCgChunk + k] = fa + double(wx) * wx;
      tmp[4 * kCgChunk + k] = fa + double(wy) * wy;
      tmp[5 * kCgChunk + k] = fa + double(wz) * wz;
    }
    for (int32_t t = c; t < ce; ++t) {
      const int32_t i = sa[t], j = sb[t], k = t - c;
      const double gx = tmp[k], gy = tmp[kCgChunk + k], gz = tmp[2 * kCgChunk + k];
      const double ex = tmp[3 * kCgChunk + k], ey = tmp[4 * kCgChunk + k], ez = tmp[5 * kCgChunk + k];
      rx[i] += gx, ry[i] += gy, rz[i] += gz;
      rx[j] -= gx, ry[j] -= gy, rz[j] -= gz;
      dgx[i] += ex, dgy[i] += ey, dgz[i] += ez;
      dgx[j] += ex, dgy[j] += ey, dgz[j] += ez;
    }
  }
}

void connection_blocks(const Model& m, const State& s, Work& w, double h) {
  const BlockSprings S{m.conn_a.data(), m.conn_b.data(), nullptr, m.conn_rest.data(), m.conn_k.data(),
                       m.conn_d.data(), 1.0, 0.0, w.cjac.data()};
  assemble_blocks<0>(0, m.nconn, S, nullptr, s, w, h, 0);
}

// Springs [begin, end) one at a time, both ends scattered: q += blocks p, returns p . blocks p
// (connection springs, and the last springs of an organ).
double cg_springs(int32_t begin, int32_t end, const int32_t* ca, const int32_t* cb, const float* blk,
                  const float* p, float* q) {
  d4 pq = {0, 0, 0, 0};
  for (int32_t s = begin; s < end; ++s) {
    const int32_t i = ca[s], j = cb[s];
    const f4 dv = load4(p + 4 * i) - load4(p + 4 * j);
    const f4 b = load4(blk + 4 * s);
    const f4 wv = reinterpret_cast<f4>(reinterpret_cast<i4>(b) & kXYZ);
    const f4 g = __builtin_shufflevector(b, b, 3, 3, 3, 3) * dv + dot3(dv, b) * wv;
    store4(q + 4 * i, load4(q + 4 * i) + g);
    store4(q + 4 * j, load4(q + 4 * j) - g);
    pq += __builtin_convertvector(dv * g, d4);
  }
  return hsum3(pq);
}

// One CG matrix-vector product over an organ: with Update, p = z + beta p first (z = inv r);
// then q = M p on the organ's vertices, then q += blocks p over its springs. Returns p . q (mass
// and spring energies). The springs run in the interleaved order of Work::cg_sa/cg_sb: four
// streams from the four quarters of the organ's (row-sorted) springs, so consecutive springs
// share no vertex and the read-modify-write chains on q overlap; the loop has no data-dependent
// branch.
template <bool Update>
__attribute__((noinline)) double cg_apply_organ(int32_t vb, int32_t ve, int32_t sbeg, int32_t send,
                                                const int32_t* __restrict sa, const int32_t* __restrict sb,
                                                const float* __restrict blk, const float* __restrict mass,
                                                const float* __restrict inv, const float* __restrict r,
                                                float* __restrict p, float* __restrict q, float beta,
                                                bool springs) {
  const f4 vbeta = splat4(beta);
  d4 pq = {0, 0, 0, 0};
  for (int32_t v = vb; v < ve; ++v) {
    f4 pv = load4(p + 4 * v);
    if constexpr (Update) {
      pv = load4(inv + 4 * v) * load4(r + 4 * v) + vbeta * pv;
      store4(p + 4 * v, pv);
    }
    const f4 qv = mass[v] * pv;
    store4(q + 4 * v, qv);
    pq += __builtin_convertvector(qv * pv, d4);
  }
  if (!springs) return hsum3(pq);
  // Two springs per 8-float register: lanes 0-3 the first, 4-7 the second (in-lane shuffles
  // only). The scatter stays sequential, so two springs sharing a vertex still add correctly.
  f8 e[2] = {splat8(0), splat8(0)};
  auto two = [&](int32_t t, f8& acc) {
    const int32_t i0 = sa[t], j0 = sb[t], i1 = sa[t + 1], j1 = sb[t + 1];
    const f8 dv = join(load4(p + 4 * i0), load4(p + 4 * i1)) - join(load4(p + 4 * j0), load4(p + 4 * j1));
    const f8 b = load8(blk + 4 * t);
    f8 d = dv * b;  // lane 3 of dv is 0
    d += __builtin_shufflevector(d, d, 1, 0, 3, 2, 5, 4, 7, 6);
    d += __builtin_shufflevector(d, d, 2, 3, 0, 1, 6, 7, 4, 5);
    const f8 al = __builtin_shufflevector(b, b, 3, 3, 3, 3, 7, 7, 7, 7);
    const f8 wv = reinterpret_cast<f8>(reinterpret_cast<i8>(b) & kXYZ8);
    const f8 g = al * dv + d * wv;
    const f4 g0 = __builtin_shufflevector(g, g, 0, 1, 2, 3), g1 = __builtin_shufflevector(g, g, 4, 5, 6, 7);
    store4(q + 4 * i0, load4(q + 4 * i0) + g0);
    store4(q + 4 * j0, load4(q + 4 * j0) - g0);
    store4(q + 4 * i1, load4(q + 4 * i1) + g1);
    store4(q + 4 * j1, load4(q + 4 * j1) - g1);
    acc += dv * g;
  };
  int32_t t = sbeg;
  for (; t + 4 <= send; t += 4) two(t, e[0]), two(t + 2, e[1]);
  const f8 e2 = e[0] + e[1];
  pq += __builtin_convertvector(__builtin_shufflevector(e2, e2, 0, 1, 2, 3) + __builtin_shufflevector(e2, e2, 4, 5, 6, 7), d4);
  return hsum3(pq) + cg_springs(t, send, sa, sb, blk, p, q);  // with the last 0-3 springs
}

// Flexion springs' Gauss-Newton blocks: g . p over the spring's four vertices, and q += c g.
double flex_dot(const Model& m, const Work& w, int32_t f, const double* px, const double* py, const double* pz) {
  const double* g = w.flex_grad.data() + 12 * f;
  const int32_t v[4] = {m.flex_a[f], m.flex_b[f], m.flex_c[f], m.flex_d[f]};
  double d = 0;
  for (int k = 0; k < 4; ++k) d += g[3 * k] * px[v[k]] + g[3 * k + 1] * py[v[k]] + g[3 * k + 2] * pz[v[k]];
  return d;
}

void flex_add(const Model& m, const Work& w, int32_t f, double c, double* qx, double* qy, double* qz) {
  const double* g = w.flex_grad.data() + 12 * f;
  const int32_t v[4] = {m.flex_a[f], m.flex_b[f], m.flex_c[f], m.flex_d[f]};
  for (int k = 0; k < 4; ++k) qx[v[k]] += c * g[3 * k], qy[v[k]] += c * g[3 * k + 1], qz[v[k]] += c * g[3 * k + 2];
}

// The same on the CG's 4-float vectors; returns the energy c (g . p)^2.
double cg_flexion(const Model& m, const Work& w, int32_t f, double c, const float* p, float* q) {
  const double* g = w.flex_grad.data() + 12 * f;
  const int32_t v[4] = {m.flex_a[f], m.flex_b[f], m.flex_c[f], m.flex_d[f]};
  double gp = 0;
  for (int k = 0; k < 4; ++k)
    gp += g[3 * k] * p[4 * v[k]] + g[3 * k + 1] * p[4 * v[k] + 1] + g[3 * k + 2] * p[4 * v[k] + 2];
  for (int k = 0; k < 4; ++k)
    for (int a = 0; a < 3; ++a) q[4 * v[k] + a] += static_cast<float>(c * gp * g[3 * k + a]);
  return c * gp * gp;
}

// x += a p, r -= a q over 4-float vertex entries [b4, e4); adds r . z (z = inv r) to rz and
// the residual over free vertices (inv != 0 exactly there) to rr. r is not masked: frozen
// vertices' entries are never read through z or rr.
__attribute__((noinline)) void cg_update(int32_t b4, int32_t e4, float a, const float* __restrict inv,
                                         const float* __restrict p, const float* __restrict q,
                                         float* __restrict x, float* __restrict r, double& rz, double& rr) {
  // float partial sums over chunks of 256 entries (vectorised), chunks summed in double
  double sz = 0.0, sr = 0.0;
  for (int32_t c = b4; c < e4; c += 256) {
    const int32_t ce = std::min(e4, c + 256);
    float cz = 0.0f, cr = 0.0f;
#pragma omp simd reduction(+ : cz, cr)
    for (int32_t k = c; k < ce; ++k) {
      x[k] += a * p[k];
      const float rk = r[k] - a * q[k];
      r[k] = rk;
      const float rk2 = rk * rk;
      cz += rk2 * inv[k];
      cr += inv[k] != 0.0f ? rk2 : 0.0f;
    }
    sz += cz, sr += cr;
  }
  rz += sz, rr += sr;
}

struct ImplicitSolve {
  const Model* m;
  State* s;
  Work* w;
  double h;
};

// Jacobi-preconditioned CG for dv on one connected component of organs (Work: rx = rhs,
// diag = diagonal, free_mask). Vertex loops run over the component's organ ranges.
void pcg_component(ImplicitSolve& S, int32_t comp) {
  const Model& m = *S.m;
  State& s = *S.s;
  Work& w = *S.w;
  const double h = S.h;
  const int32_t ob = m.component_begin[comp], oe = m.component_begin[comp + 1];
  bool awake = false;
  for (int32_t k = ob; k < oe; ++k) awake = awake || s.organ_awake[m.component_organs[k]];
  float* __restrict r = w.cg_r.data();
  float* __restrict p = w.cg_p.data();
  float* __restrict q = w.cg_q.data();
  float* __restrict x = w.cg_x.data();
  float* __restrict inv = w.cg_inv.data();
  float* __restrict b = w.cg_b.data();
  // Inverse Jacobi diagonal with the mask folded in: z = r * inv is zero on frozen vertices, so
  // p and dv stay zero there; their residual entries are never read (cg_update sums the residual
  // where inv != 0).
  int32_t& done = w.cg_done[comp];
  done = 0;
  // The right-hand side is scaled to unit norm: the float iteration then works on numbers near 1
  // whatever the units (h m g is about 1e-8 N s here), far from float's underflow.
  double rr0 = 0.0;
  for (int32_t k = ob; k < oe; ++k) {
    const OrganRange& o = m.organs[m.component_organs[k]];
    for (int32_t v = o.vert_begin; v < o.vert_end; ++v)
      rr0 += w.free_mask[v] * (w.rx[v] * w.rx[v] + w.ry[v] * w.ry[v] + w.rz[v] * w.rz[v]);
  }
  const double norm_b = std::sqrt(rr0);
  const double scale = norm_b > 0 && std::isfinite(norm_b) ? 1.0 / norm_b : 0.0;
  double rz_old = 0.0;
  rr0 = 0.0;
  for (int32_t k = ob; k < oe; ++k) {
    const OrganRange& o = m.organs[m.component_organs[k]];
    for (int32_t v = o.vert_begin; v < o.vert_end; ++v) {
      const double mk = w.free_mask[v];
      const double gx = scale * mk * w.rx[v], gy = scale * mk * w.ry[v], gz = scale * mk * w.rz[v];
      const double ix = mk / w.diag_x[v], iy = mk / w.diag_y[v], iz = mk / w.diag_z[v];
      store4(inv + 4 * v, f4{float(ix), float(iy), float(iz), float(mk)});
      const f4 rv = {float(gx), float(gy), float(gz), 0.0f};
      store4(r + 4 * v, rv);
      store4(b + 4 * v, rv);
      store4(x + 4 * v, splat4(0)), store4(p + 4 * v, splat4(0)), store4(q + 4 * v, splat4(0));
      rz_old += double(rv[0]) * rv[0] * float(ix) + double(rv[1]) * rv[1] * float(iy) +
                double(rv[2]) * rv[2] * float(iz);
      rr0 += double(rv[0]) * rv[0] + double(rv[1]) * rv[1] + double(rv[2]) * rv[2];
    }
  }
  if (!awake) return;
  // A float CG cannot reduce the residual much below float precision (kCgFloatFloor): with any
  // tolerance below that (the default 1e-8 too) it stops there. With cg_tolerance = 0 ("always
  // run cg_iterations", as the benchmark asks) it restarts from the true residual b - A x there
  // instead of iterating on: the recursive residual would sink into denormals, where its
  // products lose all precision and the iteration diverges. A restart costs one matrix-vector
  // product, like an iteration, and counts as one.
  const bool restarts = m.cg_tolerance <= 0.0;
  const double tol = std::max(m.cg_tolerance, kCgFloatFloor);
  const double tol2 = tol * tol * rr0;
  const int32_t cb = m.component_conn_begin[comp], ce = m.component_conn_begin[comp + 1];
  // q = A p (Update: p = z + beta p first) over the component; returns p . A p
  auto apply = [&](bool update, float* pp, double beta) {
    double pq = 0.0;
    for (int32_t k = ob; k < oe; ++k) {
      const int32_t o = m.component_organs[k];
      const OrganRange& g = m.organs[o];
      const bool springs = s.organ_awake[o] != 0;
      const float* blk = w.jac.data();
      const int32_t* sa = w.cg_sa.data();
      const int32_t* sbb = w.cg_sb.data();
      pq += update ? cg_apply_organ<true>(g.vert_begin, g.vert_end, g.spring_begin, g.spring_end, sa, sbb,
                                          blk, w.cg_mass.data(), inv, r, pp, q, static_cast<float>(beta), springs)
                   : cg_apply_organ<false>(g.vert_begin, g.vert_end, g.spring_begin, g.spring_end, sa, sbb,
                                           blk, w.cg_mass.data(), inv, r, pp, q, 0.0f, springs);
    }
    if (ce > cb) pq += cg_springs(cb, ce, m.conn_a.data(), m.conn_b.data(), w.cjac.data(), pp, q);
    for (int32_t k = ob; k < oe; ++k) {
      const int32_t o = m.component_organs[k];
      if (!s.organ_awake[o]) continue;
      for (int32_t f = m.organs[o].flex_begin; f < m.organs[o].flex_end; ++f)
        pq += cg_flexion(m, w, f, h * h * m.flex_k[f], pp, q);
    }
    return pq;
  };
  double beta = 0.0;
  bool restart = false;
  for (int it = 0; it < m.cg_iterations && rr0 > 0; ++it) {
    ++done;
    if (restart) {  // r = b - A x, p = 0 (the next sweep sets p = z)
      apply(false, x, 0.0);
      d4 rz = {0, 0, 0, 0};
      for (int32_t k = ob; k < oe; ++k) {
        const OrganRange& o = m.organs[m.component_organs[k]];
        for (int32_t v = o.vert_begin; v < o.vert_end; ++v) {
          const f4 iv = load4(inv + 4 * v);
          const f4 rv = (load4(b + 4 * v) - load4(q + 4 * v)) * __builtin_shufflevector(iv, iv, 3, 3, 3, 3);
          store4(r + 4 * v, rv);
          store4(p + 4 * v, splat4(0));
          const d4 rd = __builtin_convertvector(rv, d4);
          rz += rd * rd * __builtin_convertvector(iv, d4);
        }
      }
      rz_old = hsum3(rz);
      beta = 0.0;
      restart = false;
      if (!(rz_old > 0) || !std::isfinite(rz_old)) break;  // solved exactly (or lost): keep x
      continue;
    }
    // p = z + beta p and q = A p, organ by organ, then the connections and flexion springs.
    const double pq = apply(true, p, beta);
    const double alpha = rz_old / pq;
    if (!(pq > 0) || !std::isfinite(alpha)) {
      if (!restarts) break;
      restart = true;
      continue;
    }
    double rz_new = 0.0, rr = 0.0;
    for (int32_t k = ob; k < oe; ++k) {
      const OrganRange& o = m.organs[m.component_organs[k]];
      cg_update(4 * o.vert_begin, 4 * o.vert_end, static_cast<float>(alpha), inv, p, q, x, r, rz_new, rr);
    }
    if (rr <= tol2 || !(rz_new > 0) || !std::isfinite(rz_new)) {
      if (!restarts) break;
      restart = true;
      continue;
    }
    beta = rz_new / rz_old;
    rz_old = rz_new;
  }
  const f4 back = splat4(static_cast<float>(norm_b));
  for (int32_t k = ob; k < oe; ++k) {
    const OrganRange& o = m.organs[m.component_organs[k]];
    for (int32_t v = o.vert_begin; v < o.vert_end; ++v) store4(x + 4 * v, back * load4(x + 4 * v));
  }
}

void implicit_component_job(void* context, int t) {
  ImplicitSolve& S = *static_cast<ImplicitSolve*>(context);
  for (int32_t c : S.w->workers->components[t]) pcg_component(S, c);
}

struct ImplicitSetup {
  const Model* m;
  State* s;
  Work* w;
  double h;
  int phase;
};

void implicit_setup_organ(ImplicitSetup& S, int32_t o, int t) {
  const Model& m = *S.m;
  State& s = *S.s;
  Work& w = *S.w;
  const double h = S.h;
  const OrganRange& r = m.organs[o];
  const int32_t vb = r.vert_begin, ve = r.vert_end;
  if (S.phase == 0) {
    std::fill(w.fx.begin() + vb, w.fx.begin() + ve, 0.0);
    std::fill(w.fy.begin() + vb, w.fy.begin() + ve, 0.0);
    std::fill(w.fz.begin() + vb, w.fz.begin() + ve, 0.0);
    if (!s.organ_awake[o]) return;
    if (r.curvature) curvature_pass(m, r, s, w);
    if (r.flex_end > r.flex_begin) flexion_forces(m, r, s, w, w.flex_grad.data());
    return;
  }
  const double gx = m.gravity ? m.gravity_m_s2[0] : 0.0, gy = m.gravity ? m.gravity_m_s2[1] : 0.0,
               gz = m.gravity ? m.gravity_m_s2[2] : 0.0;
  for (int32_t v = vb; v < ve; ++v) {
    const double mv = m.vert_mass[v];
    w.rx[v] = h * (w.fx[v] + mv * gx), w.ry[v] = h * (w.fy[v] + mv * gy), w.rz[v] = h * (w.fz[v] + mv * gz);
    w.diag_x[v] = w.diag_y[v] = w.diag_z[v] = mv;
  }
  if (!s.organ_awake[o]) return;
  const double* d = r.damping ? m.spring_d.data() : nullptr;
  const double* hv = w.half_bk.data();
  const BlockSprings B{w.cg_sa.data(), w.cg_sb.data(), w.cg_s.data(), m.spring_rest.data(), m.spring_k.data(),
                       d, r.elastica_a, r.elastica_cap, w.jac.data()};
  switch (spring_measure_kind(r)) {
    case 0: assemble_blocks<0>(r.spring_begin, r.spring_end, B, hv, s, w, h, t); break;
    case 1: assemble_blocks<1>(r.spring_begin, r.spring_end, B, hv, s, w, h, t); break;
    case 2: assemble_blocks<2>(r.spring_begin, r.spring_end, B, hv, s, w, h, t); break;
    default: assemble_blocks<3>(r.spring_begin, r.spring_end, B, hv, s, w, h, t); break;
  }
  // Flexion springs in the matrix by their Gauss-Newton stiffness k g g^T (PSD): diagonal.
  for (int32_t f = r.flex_begin; f < r.flex_end; ++f) {
    const double* g = w.flex_grad.data() + 12 * f;
    const int32_t v[4] = {m.flex_a[f], m.flex_b[f], m.flex_c[f], m.flex_d[f]};
    const double c = h * h * m.flex_k[f];
    for (int k = 0; k < 4; ++k)
      w.diag_x[v[k]] += c * g[3 * k] * g[3 * k], w.diag_y[v[k]] += c * g[3 * k + 1] * g[3 * k + 1],
          w.diag_z[v[k]] += c * g[3 * k + 2] * g[3 * k + 2];
  }
}

void implicit_setup_job(void* context, int t) {
  ImplicitSetup& S = *static_cast<ImplicitSetup*>(context);
  for (int32_t o : S.w->workers->organs[t]) implicit_setup_organ(S, o, t);
}

IntegrateStats implicit_step(const Model& m, State& s, Work& w, double h) {
  const int32_t n = m.nvert;
  const bool attached = s.tool.mode == ToolMode::attach && !s.tool.verts.empty();
  if (attached) {
    // Move the held vertices first: the solve then sees the pull as a boundary condition.
    attach_targets(m, s, w, 1.0);
    hold_attached(s, w, h, /*snap=*/true);
  }
  // rhs = h f0 + h^2 K v0, assembled with the blocks; f0 also holds flexion, tool and gravity.
  // Per organ (in parallel when there are workers): phase 0 clears forces and computes curvature
  // and flexion; then the tool; phase 1 sets rhs and diagonal and assembles the spring blocks.
  w.forces_zero = false;
  ImplicitSetup setup{&m, &s, &w, h, 0};
  for (setup.phase = 0; setup.phase < 2; ++setup.phase) {
    if (w.workers) {
      w.workers->run(implicit_setup_job, &setup);
    } else {
      for (int32_t o = 0; o < static_cast<int32_t>(m.organs.size()); ++o) implicit_setup_organ(setup, o, 0);
    }
    if (setup.phase == 0) {
      apply_tool(m, s, w, /*reaction=*/false);
      // Flexion springs' h^2 K v0 term: f0 += -h k g (g . v0) (rhs gets h times that).
      for (int32_t f = 0; f < m.nflex; ++f)
        if (s.organ_awake[m.vert_organ[m.flex_a[f]]])
          flex_add(m, w, f, -h * m.flex_k[f] * flex_dot(m, w, f, s.vx.data(), s.vy.data(), s.vz.data()),
                   w.fx.data(), w.fy.data(), w.fz.data());
    }
  }
  if (m.nconn) connection_blocks(m, s, w, h);
  // Frozen vertices: sleeping organs and held/fixed vertices keep dv = 0.
  for (size_t o = 0; o < m.organs.size(); ++o)
    if (!s.organ_awake[o])
      std::fill(w.free_mask.begin() + m.organs[o].vert_begin, w.free_mask.begin() + m.organs[o].vert_end, 0.0);

  // PCG on dv, one independent system per connected component of organs (organs joined by
  // connection springs); components are spread over the worker threads.
  ImplicitSolve solve{&m, &s, &w, h};
  if (w.workers && w.workers->components.size() > 1) {
    w.workers->run(implicit_component_job, &solve);
  } else {
    for (int32_t c = 0; c + 1 < static_cast<int32_t>(m.component_begin.size()); ++c) pcg_component(solve, c);
  }
  const double* __restrict mask = w.free_mask.data();
  const float* __restrict dv = w.cg_x.data();
  IntegrateStats st;
  for (int32_t d : w.cg_done) st.cg_iterations = std::max<int>(st.cg_iterations, d);
  for (int32_t v = 0; v < n; ++v) {
    if (mask[v] == 0.0) continue;
    const double ax = dv[4 * v], ay = dv[4 * v + 1], az = dv[4 * v + 2];
    s.vx[v] += ax, s.vy[v] += ay, s.vz[v] += az;
    s.x[v] += h * s.vx[v], s.y[v] += h * s.vy[v], s.z[v] += h * s.vz[v];
    const double sp = s.vx[v] * s.vx[v] + s.vy[v] * s.vy[v] + s.vz[v] * s.vz[v];
    st.max_speed2 = std::max(st.max_speed2, sp);
    st.checksum += s.x[v] + s.y[v] + s.z[v] + sp;
    if (w.measure_accel) st.accel_sum += std::sqrt(ax * ax + ay * ay + az * az) / h;
  }
  w.mask_dirty = true;
  set_free_mask(m, s, w);  // restore the mask changed for sleeping organs
  constraint_passes(m, s, w, h);
  if (s.tool.mode != ToolMode::none && !s.tool.verts.empty()) {
    // Reaction at the end of the step (implicit: forces at x_{n+1}): only the forces of the
    // organs the tool holds (and the connections) reach the held vertices.
    tool_organ_forces(m, s, w);
    apply_tool(m, s, w, /*reaction=*/true, /*add_force=*/false);
  }
  return st;
}

void snapshot(const Model& m, const State& s, Work& w) {
  std::copy(s.x.begin(), s.x.end(), w.good_x.begin());
  std::copy(s.y.begin(), s.y.end(), w.good_y.begin());
  std::copy(s.z.begin(), s.z.end(), w.good_z.begin());
  w.good_time_s = s.time_s;
  w.good_step = s.step_count;
}

void restore(const Model& m, State& s, Work& w) {
  if (w.good_step < 0) {  // nothing saved yet: the rest shape is always good
    std::copy(m.vert_rest_x.begin(), m.vert_rest_x.end(), s.x.begin());
    std::copy(m.vert_rest_y.begin(), m.vert_rest_y.end(), s.y.begin());
    std::copy(m.vert_rest_z.begin(), m.vert_rest_z.end(), s.z.begin());
  } else {
    std::copy(w.good_x.begin(), w.good_x.end(), s.x.begin());
    std::copy(w.good_y.begin(), w.good_y.end(), s.y.begin());
    std::copy(w.good_z.begin(), w.good_z.end(), s.z.begin());
  }
  // Velocities are zeroed: the energy that blew up must not come back.
  std::fill(s.vx.begin(), s.vx.end(), 0.0);
  std::fill(s.vy.begin(), s.vy.end(), 0.0);
  std::fill(s.vz.begin(), s.vz.end(), 0.0);
}

}  // namespace

const char* to_string(StepStatus status) {
  switch (status) {
    case StepStatus::ok: return "ok";
    case StepStatus::substepped: return "substepped";
    case StepStatus::implicit_fallback: return "implicit-fallback";
    case StepStatus::restored: return "restored";
  }
  return "?";
}

State make_state(const Model& m) {
  State s;
  s.x = m.vert_rest_x, s.y = m.vert_rest_y, s.z = m.vert_rest_z;
  s.vx.assign(m.nvert, 0.0), s.vy.assign(m.nvert, 0.0), s.vz.assign(m.nvert, 0.0);
  s.organ_awake.assign(m.organs.size(), 1);
  s.organ_still_steps.assign(m.organs.size(), 0);
  init_solid_state(m, s);
  return s;
}

Work make_work(const Model& m) {
  Work w;
  const size_t n = m.nvert;
  for (auto* v : {&w.fx, &w.fy, &w.fz, &w.lap_x, &w.lap_y, &w.lap_z, &w.area2, &w.half_bk, &w.px,
                  &w.py, &w.pz, &w.free_mask, &w.good_x, &w.good_y, &w.good_z})
    v->assign(n, 0.0);
  const int threads = std::min<int>(m.threads, static_cast<int>(m.organs.size()));
  // Implicit solver buffers only when a step can be implicit: asked for, or the guard's fallback.
  if (m.integrator == Integrator::implicit || m.guard) {
    w.flex_grad.assign(12 * static_cast<size_t>(m.nflex), 0.0);
    for (auto* v : {&w.rx, &w.ry, &w.rz, &w.diag_x, &w.diag_y, &w.diag_z}) v->assign(n, 0.0);
    for (auto* v : {&w.cg_b, &w.cg_r, &w.cg_p, &w.cg_q, &w.cg_x, &w.cg_inv}) v->assign(4 * n, 0.0f);
    w.cg_mass.resize(n);
    for (size_t v = 0; v < n; ++v) w.cg_mass[v] = static_cast<float>(m.vert_mass[v]);
    w.jac.assign(4 * static_cast<size_t>(m.nspring), 0.0f);
    w.cjac.assign(4 * static_cast<size_t>(m.nconn), 0.0f);
    // CG spring order: per organ, four interleaved streams over the quarters of its springs
    w.cg_sa.resize(m.nspring), w.cg_sb.resize(m.nspring), w.cg_s.resize(m.nspring);
    for (const OrganRange& r : m.organs) {
      const int32_t count = r.spring_end - r.spring_begin, quarter = (count + 3) / 4;
      int32_t t = r.spring_begin;
      for (int32_t k = 0; k < quarter; ++k)
        for (int32_t stream = 0; stream < 4; ++stream) {
          const int32_t local = stream * quarter + k;
          if (local >= count) continue;
          const int32_t sp = r.spring_begin + local;
          w.cg_sa[t] = m.spring_a[sp], w.cg_sb[t] = m.spring_b[sp], w.cg_s[t] = sp;
          ++t;
        }
    }
    // one chunk scratch per worker thread
    w.cg_tmp.assign(6 * static_cast<size_t>(kCgChunk) * std::max(1, threads), 0.0);
    w.cg_done.assign(m.component_begin.empty() ? 0 : m.component_begin.size() - 1, 0);
  }
  w.organ_flag.assign(m.organs.size(), 0);
  if (threads > 1) {
    // Organs to threads, largest first onto the least loaded (LPT), by spring + face count.
    w.workers = std::make_shared<WorkerPool>(threads);
    w.workers->organs.assign(threads, {});
    std::vector<int32_t> order(m.organs.size());
    for (size_t o = 0; o < order.size(); ++o) order[o] = static_cast<int32_t>(o);
    auto cost = [&](int32_t o) {
      const OrganRange& r = m.organs[o];
      return (r.spring_end - r.spring_begin) + (r.curvature ? (r.face_end - r.face_begin) : 0);
    };
    std::sort(order.begin(), order.end(), [&](int32_t a, int32_t b) { return cost(a) > cost(b); });
    std::vector<int64_t> load(threads, 0);
    for (int32_t o : order) {
      const int t = static_cast<int>(std::min_element(load.begin(), load.end()) - load.begin());
      w.workers->organs[t].push_back(o);
      load[t] += cost(o);
    }
    // Implicit solves: whole components (organs joined by connections), same balancing.
    const int32_t ncomp = static_cast<int32_t>(m.component_begin.size()) - 1;
    std::vector<int32_t> comps(ncomp);
    std::vector<int64_t> ccost(ncomp, 0);
    for (int32_t c = 0; c < ncomp; ++c) {
      comps[c] = c;
      for (int32_t k = m.component_begin[c]; k < m.component_begin[c + 1]; ++k) ccost[c] += cost(m.component_organs[k]);
    }
    std::sort(comps.begin(), comps.end(), [&](int32_t a, int32_t b) { return ccost[a] > ccost[b]; });
    w.workers->components.assign(threads, {});
    std::fill(load.begin(), load.end(), 0);
    for (int32_t c : comps) {
      const int t = static_cast<int>(std::min_element(load.begin(), load.end()) - load.begin());
      w.workers->components[t].push_back(c);
      load[t] += ccost[c];
    }
  }
  w.tool_target.reserve(3 * n);  // attach() may hold any number of vertices up to all
  for (int32_t v = 0; v < m.nvert; ++v) w.free_mask[v] = m.vert_inv_mass[v] > 0 && !solid_vertex(m, v) ? 1.0 : 0.0;
  w.solid = make_solid_work(m);
  return w;
}

StepReport step(const Model& m, State& s, Work& w) {
  StepReport rep;
  set_free_mask(m, s, w);
  if (s.tool.mode == ToolMode::attach) w.tool_target.resize(3 * s.tool.verts.size());

  Integrator eff = m.guard ? m.effective_integrator : m.integrator;
  if (m.guard && s.guard_implicit) eff = Integrator::implicit;
  const int substeps = (eff == Integrator::implicit || !m.guard) ? 1 : m.substeps;
  IntegrateStats st;
  if (eff == Integrator::implicit) {
    st = implicit_step(m, s, w, m.dt_s);
    if (m.integrator != Integrator::implicit) {
      rep.status = StepStatus::implicit_fallback;
      rep.message = "guard: time step too large for the explicit integrator, solved implicitly";
    }
  } else {
    const double h = m.dt_s / substeps;
    for (int k = 0; k < substeps; ++k) {
      IntegrateStats sk = explicit_substep(m, s, w, h, eff == Integrator::verlet,
                                           static_cast<double>(k + 1) / substeps);
      st.max_speed2 = std::max(st.max_speed2, sk.max_speed2);
      st.checksum += sk.checksum;
      st.accel_sum = sk.accel_sum;
    }
    if (substeps > 1) {
      rep.status = StepStatus::substepped;
      rep.message = "guard: time step above the stable estimate, split into sub-steps";
    }
  }
  if (!m.solids.empty()) {  // solid organs (solid_step.cpp), after the surface models
    const SolidStats ss = solid_step(m, s, w);
    st.max_speed2 = std::max(st.max_speed2, ss.max_speed2);
    st.checksum += ss.checksum;
  }
  if (s.tool.mode == ToolMode::attach && s.tool.attach_progress < s.tool.attach_iterations)
    ++s.tool.attach_progress;
  rep.tool_clamped = s.tool.clamped;
  rep.accel_sum = st.accel_sum;
  rep.cg_iterations = st.cg_iterations;
  rep.max_speed_m_s = std::sqrt(st.max_speed2);

  // Guard: non-finite values, or a vertex crossing a quarter of the scene in one step.
  const bool bad = !std::isfinite(st.checksum) || rep.max_speed_m_s * m.dt_s > 0.25 * m.size_m;
  if (bad && m.guard) {
    restore(m, s, w);
    s.guard_implicit = true;
    ++s.guard_restores;
    rep.status = StepStatus::restored;
    rep.message = "guard: non-finite or runaway state; restored the last good state and "
                  "switched to implicit Euler";
    rep.max_speed_m_s = 0.0;
  }
  if (rep.status != StepStatus::ok || rep.tool_clamped) ++s.guard_actions;
  s.time_s += m.dt_s;
  ++s.step_count;
  if (m.guard && !bad && s.step_count % kSnapshotEvery == 0) snapshot(m, s, w);

  // Sleep: an organ (and its connected organs) still for sleep_steps steps stops being
  // integrated until a tool or an awake neighbour moves it.
  if (m.allow_sleep) {
    const int32_t norg = static_cast<int32_t>(m.organs.size());
    for (int32_t o = 0; o < norg; ++o) {
      if (!s.organ_awake[o]) continue;
      const OrganRange& r = m.organs[o];
      double vmax2 = 0.0;
      for (int32_t v = r.vert_begin; v < r.vert_end; ++v)
        vmax2 = std::max(vmax2, s.vx[v] * s.vx[v] + s.vy[v] * s.vy[v] + s.vz[v] * s.vz[v]);
      const bool still = vmax2 < m.sleep_speed_m_s * m.sleep_speed_m_s;
      s.organ_still_steps[o] = still ? s.organ_still_steps[o] + 1 : 0;
    }
    for (int32_t o = 0; o < norg; ++o) {
      if (!s.organ_awake[o] || s.organ_still_steps[o] < m.sleep_steps) continue;
      bool touched = false;
      if (s.tool.mode != ToolMode::none)
        for (int32_t v : s.tool.verts) touched = touched || m.vert_organ[v] == o;
      bool neighbours_still = true;
      for (int32_t k = m.organ_neighbors_begin[o]; k < m.organ_neighbors_begin[o + 1]; ++k) {
        const int32_t nb = m.organ_neighbors[k];
        neighbours_still = neighbours_still && (!s.organ_awake[nb] || s.organ_still_steps[nb] >= m.sleep_steps);
      }
      if (touched || !neighbours_still) continue;
      s.organ_awake[o] = 0;
      const OrganRange& r = m.organs[o];
      std::fill(s.vx.begin() + r.vert_begin, s.vx.begin() + r.vert_end, 0.0);
      std::fill(s.vy.begin() + r.vert_begin, s.vy.begin() + r.vert_end, 0.0);
      std::fill(s.vz.begin() + r.vert_begin, s.vz.begin() + r.vert_end, 0.0);
    }
    for (int32_t o = 0; o < norg; ++o) {  // an awake, moving neighbour wakes a sleeper
      if (s.organ_awake[o]) continue;
      for (int32_t k = m.organ_neighbors_begin[o]; k < m.organ_neighbors_begin[o + 1]; ++k) {
        const int32_t nb = m.organ_neighbors[k];
        if (s.organ_awake[nb] && s.organ_still_steps[nb] == 0) {
          s.organ_awake[o] = 1, s.organ_still_steps[o] = 0;
          break;
        }
      }
    }
  }
  return rep;
}

int64_t run_to_rest(const Model& m, State& s, Work& w, int64_t max_steps, double accel_tol,
                    StepReport* last) {
  const bool was = w.measure_accel;
  w.measure_accel = true;
  int64_t k = 0;
  StepReport r;
  while (k < max_steps) {
    r = step(m, s, w);
    ++k;
    if (r.status != StepStatus::restored && r.accel_sum < accel_tol) break;
  }
  w.measure_accel = was;
  if (last) *last = r;
  return k;
}

void wake(const Model& m, State& s, int32_t organ) {
  if (organ < 0 || organ >= static_cast<int32_t>(m.organs.size())) return;
  std::vector<int32_t> stack{organ};  // interaction start, not the step: allocation is fine
  while (!stack.empty()) {
    const int32_t o = stack.back();
    stack.pop_back();
    if (s.organ_awake[o] && s.organ_still_steps[o] == 0) continue;
    s.organ_awake[o] = 1, s.organ_still_steps[o] = 0;
    for (int32_t k = m.organ_neighbors_begin[o]; k < m.organ_neighbors_begin[o + 1]; ++k)
      stack.push_back(m.organ_neighbors[k]);
  }
}

namespace {
void set_tool(const Model& m, State& s, const std::vector<int32_t>& verts, ToolMode mode) {
  s.tool.mode = mode;
  s.tool.verts.clear();
  for (int32_t v : verts)
    if (v >= 0 && v < m.nvert && m.vert_inv_mass[v] > 0) s.tool.verts.push_back(v);
  std::sort(s.tool.verts.begin(), s.tool.verts.end());
  s.tool.verts.erase(std::unique(s.tool.verts.begin(), s.tool.verts.end()), s.tool.verts.end());
  for (int32_t v : s.tool.verts) wake(m, s, m.vert_organ[v]);
  s.tool.reaction_N = {0, 0, 0};
  s.tool.clamped = false;
}
}  // namespace

void pull_force(const Model& m, State& s, const std::vector<int32_t>& verts,
                const std::array<double, 3>& force_N) {
  set_tool(m, s, verts, ToolMode::force);
  s.tool.force_N = force_N;
}

void attach(const Model& m, State& s, const std::vector<int32_t>& verts,
            const std::array<double, 3>& offset_m, int iterations) {
  set_tool(m, s, verts, ToolMode::attach);
  s.tool.offset_m = offset_m;
  s.tool.attach_iterations = std::max(1, iterations);
  s.tool.attach_progress = 0;
  s.tool.anchor.resize(3 * s.tool.verts.size());
  for (size_t q = 0; q < s.tool.verts.size(); ++q) {
    const int32_t v = s.tool.verts[q];
    s.tool.anchor[3 * q] = s.x[v], s.tool.anchor[3 * q + 1] = s.y[v], s.tool.anchor[3 * q + 2] = s.z[v];
  }
}

void move_attachment(State& s, const std::array<double, 3>& offset_m) {
  // The new offset is reached at once (a device moves continuously at 1 kHz).
  s.tool.offset_m = offset_m;
  s.tool.attach_progress = s.tool.attach_iterations;
}

void release(State& s) {
  s.tool.mode = ToolMode::none;
  s.tool.verts.clear();
  s.tool.reaction_N = {0, 0, 0};
  s.tool.clamped = false;
}

std::array<double, 3> tool_reaction(const State& s) { return s.tool.reaction_N; }

double organ_volume(const Model& m, const State& s, int32_t organ) {
  const OrganRange& r = m.organs[organ];
  return enclosed_volume(s.x.data(), s.y.data(), s.z.data(), m.face_vert.data(), r.face_begin,
                         r.face_end);
}

double total_volume(const Model& m, const State& s) {
  double v = 0;
  for (size_t o = 0; o < m.organs.size(); ++o) v += organ_volume(m, s, static_cast<int32_t>(o));
  return v;
}

double max_displacement(const Model& m, const State& s) {
  double d2 = 0;
  for (int32_t v = 0; v < m.nvert; ++v) {
    const double dx = s.x[v] - m.vert_rest_x[v], dy = s.y[v] - m.vert_rest_y[v],
                 dz = s.z[v] - m.vert_rest_z[v];
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
      if (!solid_vertex(m, v)) e -= m.vert_mass[v] * (m.gravity_m_s2[0] * (s.x[v] - m.vert_rest_x[v]) +
                             m.gravity_m_s2[1] * (s.y[v] - m.vert_rest_y[v]) +
                             m.gravity_m_s2[2] * (s.z[v] - m.vert_rest_z[v]));
  return e;
}

void compute_internal_forces(const Model& m, const State& s, Work& w) {
  State awake = s;  // measurement helper (tests, reports): may allocate
  std::fill(awake.organ_awake.begin(), awake.organ_awake.end(), 1);
  internal_forces(m, awake, w);
}

void internal_force_and_torque(const Model& m, const State& s, Work& w,
                               std::array<double, 3>& force, std::array<double, 3>& torque) {
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
