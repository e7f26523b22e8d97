// Implicit Euler (Baraff & Witkin 1998), linearised once per step, solved per connected
// component with a Jacobi-preconditioned CG in float.
#include <algorithm>
#include <cmath>
#include <cstring>

#include "workers.hpp"
#include "engine.hpp"

namespace softatlas::sim::engine {
namespace {

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

// Springs [begin, end) one at a time, both ends scattered: q += blocks p, returns p . blocks p
// (connection springs, and the last springs of an organ).
double cg_springs(int32_t begin, int32_t end, const int32_t* ca, const int32_t* cb, const float* blk, const float* p,
                  float* q) {
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
                                                float* __restrict p, float* __restrict q, float beta, bool springs) {
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
  pq += __builtin_convertvector(
      __builtin_shufflevector(e2, e2, 0, 1, 2, 3) + __builtin_shufflevector(e2, e2, 4, 5, 6, 7), d4);
  return hsum3(pq) + cg_springs(t, send, sa, sb, blk, p, q);  // with the last 0-3 springs
}

// x += a p, r -= a q over 4-float vertex entries [b4, e4); adds r . z (z = inv r) to rz and
// the residual over free vertices (inv != 0 exactly there) to rr. r is not masked: frozen
// vertices' entries are never read through z or rr.
__attribute__((noinline)) void cg_update(int32_t b4, int32_t e4, float a, const float* __restrict inv,
                                         const float* __restrict p, const float* __restrict q, float* __restrict x,
                                         float* __restrict r, double& rz, double& rr) {
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
      rz_old +=
          double(rv[0]) * rv[0] * float(ix) + double(rv[1]) * rv[1] * float(iy) + double(rv[2]) * rv[2] * float(iz);
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
      pq += update ? cg_apply_organ<true>(g.vert_begin, g.vert_end, g.spring_begin, g.spring_end, sa, sbb, blk,
                                          w.cg_mass.data(), inv, r, pp, q, static_cast<float>(beta), springs)
                   : cg_apply_organ<false>(g.vert_begin, g.vert_end, g.spring_begin, g.spring_end, sa, sbb, blk,
                                           w.cg_mass.data(), inv, r, pp, q, 0.0f, springs);
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
  organ_spring_blocks(m, r, s, w, h, t);
  flexion_blocks(m, r, w, h);
}

void implicit_setup_job(void* context, int t) {
  ImplicitSetup& S = *static_cast<ImplicitSetup*>(context);
  for (int32_t o : S.w->workers->organs[t]) implicit_setup_organ(S, o, t);
}

}  // namespace

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
      flexion_velocity_terms(m, s, w, h);
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

}  // namespace softatlas::sim::engine
