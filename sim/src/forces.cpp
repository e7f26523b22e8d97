// All internal forces of the awake organs into work.f: springs (with the curvature pass of the
// elastica), flexion springs, connections.
#include <algorithm>

#include "engine.hpp"

namespace softatlas::sim::engine {

// One organ's springs (with its curvature pass) and flexion springs, added into work.f.
void organ_internal_forces(const Model& m, const OrganRange& r, const State& s, Work& w) {
  if (r.curvature) curvature_pass(m, r, s, w);  // 000 eq 2 for the elastica of 000 eq 5
  organ_spring_forces(m, r, s, w);
  if (r.flex_end > r.flex_begin) flexion_forces(m, r, s, w);
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

}  // namespace softatlas::sim::engine
