// Internal force kernels of the core (private header). Each kernel takes plain arrays and adds
// into force accumulators; its comment gives the equation and the paper's number.
#pragma once

#include <cmath>
#include <cstdint>

namespace softatlas::sim::kernels {

constexpr double kTiny = 1e-300;

// 000 eq 5, the elastica factor of a spring (a, b), one source for the force kernel, the implicit
// blocks and the compiler's rest lengths: l_e = l (a + min(t, cap)) with
//   t = h_a + h_b (p = 1) or (h_a + h_b)^2 (p = 2),
// h_v = elastica_vertex_coef(p, b, L) kappa_v the per-vertex half terms (b kappa L / 2 for p = 1,
// sqrt(b) kappa L / 2 for p = 2, so that t = b kappa L or b (kappa L)^2 for equal curvatures), and
// cap the organ's cap of the curvature term (Material::elastica_cap above its rest maximum).
inline double elastica_term(int p, double h_sum) { return p == 1 ? h_sum : h_sum * h_sum; }
inline double elastica_factor(int p, double a, double h_sum, double cap) {
  const double t = elastica_term(p, h_sum);
  return a + (t < cap ? t : cap);
}
inline double elastica_vertex_coef(int p, double b, double unit_m) {
  return p == 1 ? 0.5 * b * unit_m : 0.5 * std::sqrt(b) * unit_m;
}

// Spring and damping forces on springs [begin, end), 000 eq 6, 000 eq 7:
//   f_a = [k (l_m - r) + d (v_b - v_a) . u] u,  f_b = -f_a,  u = (x_b - x_a) / l
// where l_m is the spring measure: l (Hooke, TMSM/CMSM) or the elastica length
// l_e = l (a + h_a + h_b) (p = 1) / l (a + (h_a + h_b)^2) (p = 2) with h the per-vertex
// b kappa L / 2 terms (000 eq 5), P = 3: a l (b = 0), and r the matching rest value (l0 or l_e0).
// The curvature term is capped at `cap` (Material::elastica_cap).
//
// In chunks of kSpringChunk springs, two passes: a vectorised one computes each spring's force
// (the square root and the division, which bound a scalar loop, 8 springs at a time with
// AVX-512), a scalar one adds them to both ends. The force on the first end is summed in
// registers while consecutive springs share it (edge springs come sorted by (a, b), about three
// per vertex) and stored once per run: a += into memory per spring chains each spring on the
// previous one's store. Any spring order stays correct; sorted is faster.
// noinline: GCC forgets the __restrict promises of an inlined function's parameters, and the
// loop then reloads positions after every scattered store (measured 1.4x slower).
constexpr int32_t kSpringChunk = 128;
template <int P, bool Damped>
__attribute__((noinline)) void spring_forces(int32_t begin, int32_t end, const int32_t* __restrict sa,
                                             const int32_t* __restrict sb, const double* __restrict rest,
                                             const double* __restrict k, const double* __restrict d, double a,
                                             double cap, const double* __restrict x, const double* __restrict y,
                                             const double* __restrict z, const double* __restrict vx,
                                             const double* __restrict vy, const double* __restrict vz,
                                             const double* __restrict h, double* __restrict fx, double* __restrict fy,
                                             double* __restrict fz) {
  alignas(64) double gxs[kSpringChunk], gys[kSpringChunk], gzs[kSpringChunk];
  int32_t run = begin < end ? sa[begin] : 0;
  double rx = 0.0, ry = 0.0, rz = 0.0;
  for (int32_t c0 = begin; c0 < end; c0 += kSpringChunk) {
    const int32_t n = end - c0 < kSpringChunk ? end - c0 : kSpringChunk;
#pragma omp simd
    for (int32_t t = 0; t < n; ++t) {
      const int32_t s = c0 + t, i = sa[s], j = sb[s];
      const double dx = x[j] - x[i], dy = y[j] - y[i], dz = z[j] - z[i];
      const double l = std::sqrt(dx * dx + dy * dy + dz * dz);
      const double inv = 1.0 / (l > kTiny ? l : kTiny);
      double measure = l;
      if constexpr (P == 1 || P == 2) measure = l * elastica_factor(P, a, h[i] + h[j], cap);
      if constexpr (P == 3) measure = l * a;  // elastica with b = 0
      double f = k[s] * (measure - rest[s]);
      if constexpr (Damped) {
        const double dv = (vx[j] - vx[i]) * dx + (vy[j] - vy[i]) * dy + (vz[j] - vz[i]) * dz;
        f += d[s] * dv * inv;
      }
      const double g = f * inv;
      gxs[t] = g * dx, gys[t] = g * dy, gzs[t] = g * dz;
    }
    for (int32_t t = 0; t < n; ++t) {
      const int32_t i = sa[c0 + t], j = sb[c0 + t];
      if (i != run) {
        fx[run] += rx, fy[run] += ry, fz[run] += rz;
        rx = 0.0, ry = 0.0, rz = 0.0, run = i;
      }
      rx += gxs[t], ry += gys[t], rz += gzs[t];
      fx[j] -= gxs[t], fy[j] -= gys[t], fz[j] -= gzs[t];
    }
  }
  if (begin < end) fx[run] += rx, fy[run] += ry, fz[run] += rz;
}

}  // namespace softatlas::sim::kernels
