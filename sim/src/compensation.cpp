// Over-stretch / over-compress compensation (CMSM, Duan et al. 2016).
#include <algorithm>
#include <cmath>

#include "engine.hpp"

namespace softatlas::sim::engine {

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
      if (l > hi * l0)
        target = hi * l0;
      else if (l < lo * l0)
        target = lo * l0;
      else
        continue;
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

}  // namespace softatlas::sim::engine
