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
// noinline: GCC forgets the __restrict promises of an inlined function's parameters, and the
// loop then reloads positions after every scattered store (measured 1.4x slower).
template <int P, bool Damped>
__attribute__((noinline)) void spring_forces(int32_t begin, int32_t end, const int32_t* __restrict sa,
                                             const int32_t* __restrict sb, const double* __restrict rest,
                                             const double* __restrict k, const double* __restrict d, double a,
                                             double cap, const double* __restrict x, const double* __restrict y,
                                             const double* __restrict z, const double* __restrict vx,
                                             const double* __restrict vy, const double* __restrict vz,
                                             const double* __restrict h, double* __restrict fx, double* __restrict fy,
                                             double* __restrict fz) {
  for (int32_t s = begin; s < end; ++s) {
    const int32_t i = sa[s], j = sb[s];
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
    const double gx = g * dx, gy = g * dy, gz = g * dz;
    fx[i] += gx, fy[i] += gy, fz[i] += gz;
    fx[j] -= gx, fy[j] -= gy, fz[j] -= gz;
  }
}

}  // namespace softatlas::sim::kernels
