// Explicit integrators: paper 000 Algorithm 1 (Verlet position form) and symplectic Euler, with
// the organs spread over the worker threads when there are any.
#include <algorithm>
#include <cmath>

#include "workers.hpp"
#include "engine.hpp"

namespace softatlas::sim::engine {
namespace {

// Explicit update of one organ's free vertices. Semi-implicit Euler: v += h (F/m + g),
// x += h v. Paper 000 Algorithm 1 (lines 9-10): p = x + v h + F h^2 / mu, v = (p - x) / h,
// x = p; algebraically the same scheme, written in position form (docs/physics.md).
template <bool Verlet>
void integrate_organ(const Model& m, const OrganRange& r, State& s, Work& w, double h, IntegrateStats& st) {
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

// The explicit update zeroes the forces it consumes; a sleeping organ's forces stay, so the next
// step must clear all of them unless every organ that can move was integrated. Rigid organs never
// move: only their vertices that end a connection spring hold a force, cleared here.
bool all_soft_awake(const Model& m, const State& s) {
  for (size_t o = 0; o < m.organs.size(); ++o)
    if (!s.organ_awake[o] && m.organs[o].model != ModelKind::rigid) return false;
  return true;
}

void clear_rigid_forces(const Model& m, Work& w) {
  for (int32_t v : m.rigid_conn_verts) w.fx[v] = 0.0, w.fy[v] = 0.0, w.fz[v] = 0.0;
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
      if (p.verlet)
        integrate_organ<true>(m, r, s, w, p.h, p.stats[t]);
      else
        integrate_organ<false>(m, r, s, w, p.h, p.stats[t]);
    }
  }
}

IntegrateStats explicit_substep_parallel(const Model& m, State& s, Work& w, double h, bool verlet, double frac) {
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
  w.forces_zero = all_soft_awake(m, s);
  clear_rigid_forces(m, w);
  if (attached) snap_attached(s, w);
  constraint_passes(m, s, w, h);
  return st;
}

IntegrateStats explicit_substep(const Model& m, State& s, Work& w, double h, bool verlet, double frac) {
  if (w.workers) return explicit_substep_parallel(m, s, w, h, verlet, frac);
  const bool attached = s.tool.mode == ToolMode::attach && !s.tool.verts.empty();
  internal_forces(m, s, w);
  apply_tool(m, s, w);
  if (attached) {  // held vertices: zero acceleration, velocity that lands them on the target
    attach_targets(m, s, w, frac);
    hold_attached(s, w, h, /*snap=*/false);
  }
  IntegrateStats st;
  for (size_t o = 0; o < m.organs.size(); ++o) {
    if (!s.organ_awake[o]) continue;
    if (verlet)
      integrate_organ<true>(m, m.organs[o], s, w, h, st);
    else
      integrate_organ<false>(m, m.organs[o], s, w, h, st);
  }
  w.forces_zero = all_soft_awake(m, s);
  clear_rigid_forces(m, w);
  if (attached) snap_attached(s, w);
  constraint_passes(m, s, w, h);
  return st;
}

}  // namespace

IntegrateStats explicit_step(const Model& m, State& s, Work& w, bool verlet, int substeps) {
  IntegrateStats st;
  const double h = m.dt_s / substeps;
  for (int k = 0; k < substeps; ++k) {
    IntegrateStats sk = explicit_substep(m, s, w, h, verlet, static_cast<double>(k + 1) / substeps);
    st.max_speed2 = std::max(st.max_speed2, sk.max_speed2);
    st.checksum += sk.checksum;
    st.accel_sum = sk.accel_sum;
  }
  return st;
}

}  // namespace softatlas::sim::engine
