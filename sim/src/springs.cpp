// Edge springs and connection springs (000 eq 6, 000 eq 7, Hooke or elastica 000 eq 5) and their blocks
// in the implicit Euler system (Baraff & Witkin 1998; implicit.cpp solves it).
#include <algorithm>
#include <cmath>

#include "engine.hpp"

namespace softatlas::sim::engine {
namespace {

template <int P>
void organ_springs(const Model& m, const OrganRange& r, const State& s, Work& w) {
  if (r.damping)
    kernels::spring_forces<P, true>(r.spring_begin, r.spring_end, m.spring_a.data(), m.spring_b.data(),
                                    m.spring_rest.data(), m.spring_k.data(), m.spring_d.data(), r.elastica_a,
                                    r.elastica_cap, s.x.data(), s.y.data(), s.z.data(), s.vx.data(), s.vy.data(),
                                    s.vz.data(), w.half_bk.data(), w.fx.data(), w.fy.data(), w.fz.data());
  else
    kernels::spring_forces<P, false>(r.spring_begin, r.spring_end, m.spring_a.data(), m.spring_b.data(),
                                     m.spring_rest.data(), m.spring_k.data(), m.spring_d.data(), r.elastica_a,
                                     r.elastica_cap, s.x.data(), s.y.data(), s.z.data(), s.vx.data(), s.vy.data(),
                                     s.vz.data(), w.half_bk.data(), w.fx.data(), w.fy.data(), w.fz.data());
}

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
__attribute__((noinline)) void assemble_blocks(int32_t begin, int32_t end, const BlockSprings& S, const double* hv,
                                               const State& s, Work& w, double h, int slot) {
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
      if constexpr (P == 1 || P == 2) factor = kernels::elastica_factor(P, a, hv[i] + hv[j], cap);
      if constexpr (P == 3) factor = a;
      const double ke = kk[q] * factor, Le = rest[q] / factor;
      const double dq = d ? d[q] : 0.0;
      const double cc = 1.0 - Le * inv;
      const double alpha = h2 * ke * (cc > 0.0 ? cc : 0.0);
      const double kbeta = h2 * ke - alpha;  // stiffness part of beta
      const double dvx = vx[j] - vx[i], dvy = vy[j] - vy[i], dvz = vz[j] - vz[i];
      const double dvu = dvx * ux + dvy * uy + dvz * uz;
      const double f = ke * (l - Le) + dq * dvu;  // 000 eq 6, 000 eq 7 at x0, v0
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

}  // namespace

// Which spring measure an organ uses: 0 Hooke, 1/2 elastica p, 3 elastica with b = 0.
int spring_measure_kind(const OrganRange& r) {
  if (r.model != ModelKind::nmsm || r.elastica_frozen) return 0;
  if (!r.curvature) return 3;
  return r.elastica_p;
}

void organ_spring_forces(const Model& m, const OrganRange& r, const State& s, Work& w) {
  switch (spring_measure_kind(r)) {
    case 0:
      organ_springs<0>(m, r, s, w);
      break;
    case 1:
      organ_springs<1>(m, r, s, w);
      break;
    case 2:
      organ_springs<2>(m, r, s, w);
      break;
    default:
      organ_springs<3>(m, r, s, w);
      break;
  }
}

void connection_forces(const Model& m, const State& s, Work& w) {
  if (m.nconn == 0) return;
  // Connections are Hooke springs with damping; a sleeping organ's side still feels them.
  kernels::spring_forces<0, true>(0, m.nconn, m.conn_a.data(), m.conn_b.data(), m.conn_rest.data(), m.conn_k.data(),
                                  m.conn_d.data(), 1.0, 0.0, s.x.data(), s.y.data(), s.z.data(), s.vx.data(),
                                  s.vy.data(), s.vz.data(), nullptr, w.fx.data(), w.fy.data(), w.fz.data());
}

void organ_spring_blocks(const Model& m, const OrganRange& r, const State& s, Work& w, double h, int slot) {
  const double* d = r.damping ? m.spring_d.data() : nullptr;
  const double* hv = w.half_bk.data();
  const BlockSprings B{w.cg_sa.data(), w.cg_sb.data(), w.cg_s.data(), m.spring_rest.data(), m.spring_k.data(), d,
                       r.elastica_a,   r.elastica_cap, w.jac.data()};
  switch (spring_measure_kind(r)) {
    case 0:
      assemble_blocks<0>(r.spring_begin, r.spring_end, B, hv, s, w, h, slot);
      break;
    case 1:
      assemble_blocks<1>(r.spring_begin, r.spring_end, B, hv, s, w, h, slot);
      break;
    case 2:
      assemble_blocks<2>(r.spring_begin, r.spring_end, B, hv, s, w, h, slot);
      break;
    default:
      assemble_blocks<3>(r.spring_begin, r.spring_end, B, hv, s, w, h, slot);
      break;
  }
}

void connection_blocks(const Model& m, const State& s, Work& w, double h) {
  const BlockSprings S{m.conn_a.data(), m.conn_b.data(), nullptr, m.conn_rest.data(),
                       m.conn_k.data(), m.conn_d.data(), 1.0,     0.0,
                       w.cjac.data()};
  assemble_blocks<0>(0, m.nconn, S, nullptr, s, w, h, 0);
}

}  // namespace softatlas::sim::engine
