// The position passes after an integration: compensation and volume, and their share of the
// reaction on the tool.
#include <array>

#include "engine.hpp"

namespace softatlas::sim::engine {

// Position corrections act as forces m dx / h^2; on the tool's vertices they are part of the
// reaction (a compensated spring holds the load through its correction, not its Hooke force).
void constraint_passes(const Model& m, State& s, Work& w, double h) {
  ToolState& t = s.tool;
  const bool tool = t.mode == ToolMode::force && !t.verts.empty();
  std::array<double, 3> before{0, 0, 0};
  bool any = false;
  for (size_t o = 0; o < m.organs.size(); ++o) {
    if (!s.organ_awake[o]) continue;
    const OrganRange& r = m.organs[o];
    if (r.compensation_iterations <= 0 && r.volume_stiffness <= 0) continue;
    if (tool && !any)
      for (int32_t v : t.verts)
        before[0] += m.vert_mass[v] * s.x[v], before[1] += m.vert_mass[v] * s.y[v],
            before[2] += m.vert_mass[v] * s.z[v];
    any = true;
    if (r.compensation_iterations > 0) compensation_pass(m, r, s, w, h);
    if (r.volume_stiffness > 0) volume_pass(m, r, s, w, h);
  }
  if (tool && any) {
    std::array<double, 3> after{0, 0, 0};
    for (int32_t v : t.verts)
      after[0] += m.vert_mass[v] * s.x[v], after[1] += m.vert_mass[v] * s.y[v], after[2] += m.vert_mass[v] * s.z[v];
    for (int c = 0; c < 3; ++c) t.reaction_N[c] += (after[c] - before[c]) / (h * h);
  }
}

}  // namespace softatlas::sim::engine
