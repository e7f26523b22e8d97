// Flexion (dihedral) springs (003, in the rotation-invariant dihedral form of docs/physics.md):
// forces, and their Gauss-Newton blocks in the implicit system.
#include <algorithm>
#include <cmath>

#include "softatlas/sim/geometry.hpp"
#include "engine.hpp"

namespace softatlas::sim::engine {
namespace {

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

}  // namespace

// Flexion (dihedral) springs, energy 1/2 k (theta - theta0)^2 (paper 003 flexion springs in the
// rotation-invariant dihedral form, docs/physics.md). Gradients of theta (Bridson et al. 2003):
//   g_c = -|e| n1 / |n1|^2, g_d = -|e| n2 / |n2|^2,
//   g_a = -((1 - t_c) g_c + (1 - t_d) g_d), g_b = -(t_c g_c + t_d g_d),
// t_c = (c - a).e / |e|^2 (where c projects on the edge), e = b - a.
void flexion_forces(const Model& m, const OrganRange& r, const State& s, Work& w, double* grad_out) {
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
    const double n2[3] = {-(e[1] * q[2] - e[2] * q[1]), -(e[2] * q[0] - e[0] * q[2]), -(e[0] * q[1] - e[1] * q[0])};
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

// Flexion springs in the matrix by their Gauss-Newton stiffness k g g^T (PSD): diagonal.
void flexion_blocks(const Model& m, const OrganRange& r, Work& w, double h) {
  for (int32_t f = r.flex_begin; f < r.flex_end; ++f) {
    const double* g = w.flex_grad.data() + 12 * f;
    const int32_t v[4] = {m.flex_a[f], m.flex_b[f], m.flex_c[f], m.flex_d[f]};
    const double c = h * h * m.flex_k[f];
    for (int k = 0; k < 4; ++k)
      w.diag_x[v[k]] += c * g[3 * k] * g[3 * k], w.diag_y[v[k]] += c * g[3 * k + 1] * g[3 * k + 1],
          w.diag_z[v[k]] += c * g[3 * k + 2] * g[3 * k + 2];
  }
}

// Flexion springs' h^2 K v0 term: f0 += -h k g (g . v0) (rhs gets h times that).
void flexion_velocity_terms(const Model& m, const State& s, Work& w, double h) {
  for (int32_t f = 0; f < m.nflex; ++f)
    if (s.organ_awake[m.vert_organ[m.flex_a[f]]])
      flex_add(m, w, f, -h * m.flex_k[f] * flex_dot(m, w, f, s.vx.data(), s.vy.data(), s.vz.data()), w.fx.data(),
               w.fy.data(), w.fz.data());
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

}  // namespace softatlas::sim::engine
