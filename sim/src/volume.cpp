// Volume constraint (003 eq 25 to 003 eq 30), one projection per step.
#include <algorithm>

#include "softatlas/sim/geometry.hpp"
#include "engine.hpp"

namespace softatlas::sim::engine {

// Volume constraint (003 eq 25 to 003 eq 30) on the fan of tetrahedra that the closed surface
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
  add_volume_gradient(X, Y, Z, m.face_vert.data(), r.face_begin, r.face_end, 0, w.lap_x.data(), w.lap_y.data(),
                      w.lap_z.data());
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

}  // namespace softatlas::sim::engine
