// Sleeping organs: an organ (and its connected organs) still for sleep_steps steps stops being
// integrated until a tool or an awake neighbour moves it. Rigid organs never wake: nothing moves
// them, and a wake does not pass through them to the organs on their other side.
#include <algorithm>
#include <vector>

#include "engine.hpp"

namespace softatlas::sim::engine {

void update_sleep(const Model& m, State& s) {
  if (!m.allow_sleep) return;
  const int32_t norg = static_cast<int32_t>(m.organs.size());
  for (int32_t o = 0; o < norg; ++o) {
    if (!s.organ_awake[o]) continue;
    const OrganRange& r = m.organs[o];
    double vmax2 = 0.0;
    for (int32_t v = r.vert_begin; v < r.vert_end; ++v)
      vmax2 = std::max(vmax2, s.vx[v] * s.vx[v] + s.vy[v] * s.vy[v] + s.vz[v] * s.vz[v]);
    const bool still = vmax2 < m.sleep_speed_m_s * m.sleep_speed_m_s;
    s.organ_still_steps[o] = still ? s.organ_still_steps[o] + 1 : 0;
  }
  for (int32_t o = 0; o < norg; ++o) {
    if (!s.organ_awake[o] || s.organ_still_steps[o] < m.sleep_steps) continue;
    bool touched = false;
    if (s.tool.mode != ToolMode::none)
      for (int32_t v : s.tool.verts) touched = touched || m.vert_organ[v] == o;
    bool neighbours_still = true;
    for (int32_t k = m.organ_neighbors_begin[o]; k < m.organ_neighbors_begin[o + 1]; ++k) {
      const int32_t nb = m.organ_neighbors[k];
      neighbours_still = neighbours_still && (!s.organ_awake[nb] || s.organ_still_steps[nb] >= m.sleep_steps);
    }
    if (touched || !neighbours_still) continue;
    s.organ_awake[o] = 0;
    const OrganRange& r = m.organs[o];
    std::fill(s.vx.begin() + r.vert_begin, s.vx.begin() + r.vert_end, 0.0);
    std::fill(s.vy.begin() + r.vert_begin, s.vy.begin() + r.vert_end, 0.0);
    std::fill(s.vz.begin() + r.vert_begin, s.vz.begin() + r.vert_end, 0.0);
  }
  for (int32_t o = 0; o < norg; ++o) {  // an awake, moving neighbour wakes a sleeper
    if (s.organ_awake[o] || m.organs[o].model == ModelKind::rigid) continue;
    for (int32_t k = m.organ_neighbors_begin[o]; k < m.organ_neighbors_begin[o + 1]; ++k) {
      const int32_t nb = m.organ_neighbors[k];
      if (s.organ_awake[nb] && s.organ_still_steps[nb] == 0) {
        s.organ_awake[o] = 1, s.organ_still_steps[o] = 0;
        break;
      }
    }
  }
}

}  // namespace softatlas::sim::engine

namespace softatlas::sim {

void wake(const Model& m, State& s, int32_t organ) {
  if (organ < 0 || organ >= static_cast<int32_t>(m.organs.size())) return;
  std::vector<int32_t> stack{organ};  // interaction start, not the step: allocation is fine
  while (!stack.empty()) {
    const int32_t o = stack.back();
    stack.pop_back();
    if (m.organs[o].model == ModelKind::rigid) continue;
    if (s.organ_awake[o] && s.organ_still_steps[o] == 0) continue;
    s.organ_awake[o] = 1, s.organ_still_steps[o] = 0;
    for (int32_t k = m.organ_neighbors_begin[o]; k < m.organ_neighbors_begin[o + 1]; ++k)
      stack.push_back(m.organ_neighbors[k]);
  }
}

}  // namespace softatlas::sim
