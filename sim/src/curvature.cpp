// Discrete mean curvature per vertex (000 eq 2) and the per-vertex half terms of the elastica
// factor (000 eq 5) that the spring kernels read.
#include <algorithm>
#include <cmath>

#include "engine.hpp"

namespace softatlas::sim::engine {

// Curvature (000 eq 2) into work.half_bk for one organ.
void curvature_pass(const Model& m, const OrganRange& r, const State& s, Work& w) {
  const int32_t vb = r.vert_begin, ve = r.vert_end;
  std::fill(w.lap_x.begin() + vb, w.lap_x.begin() + ve, 0.0);
  std::fill(w.lap_y.begin() + vb, w.lap_y.begin() + ve, 0.0);
  std::fill(w.lap_z.begin() + vb, w.lap_z.begin() + ve, 0.0);
  std::fill(w.area2.begin() + vb, w.area2.begin() + ve, 0.0);
  accumulate_cotan_laplacian(r.face_end - r.face_begin, m.face_vert.data() + 3 * r.face_begin, s.x.data(), s.y.data(),
                             s.z.data(), w.lap_x.data(), w.lap_y.data(), w.lap_z.data(), w.area2.data());
  // h_i = coef * H_i, H_i = 1.5 |L_i| / area2_i (geometry.cpp); coef = b L / 2 (p = 1) or
  // sqrt(b) L / 2 (p = 2), so that the spring kernel reads a + h_a + h_b or a + (h_a + h_b)^2.
  const double coef = 1.5 * kernels::elastica_vertex_coef(r.elastica_p, r.elastica_b, r.curvature_unit_m);
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

}  // namespace softatlas::sim::engine
