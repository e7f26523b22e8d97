// The tool: force pulling and position attachment (000 section III.C), the free mask, and the
// reaction force on the tool.
#include <algorithm>
#include <cmath>

#include "engine.hpp"

namespace softatlas::sim::engine {

void begin_tool_step(const Model& m, const State& s, Work& w) {
  set_free_mask(m, s, w);
  if (s.tool.mode == ToolMode::attach) w.tool_target.resize(3 * s.tool.verts.size());
}

void end_tool_step(State& s) {
  if (s.tool.mode == ToolMode::attach && s.tool.attach_progress < s.tool.attach_iterations) ++s.tool.attach_progress;
}

// Internal forces of the organs that hold a tool vertex, and of the connections; other organs'
// force entries are left as they are (forces_zero becomes false).
void tool_organ_forces(const Model& m, const State& s, Work& w) {
  std::fill(w.organ_flag.begin(), w.organ_flag.end(), uint8_t{0});
  for (int32_t v : s.tool.verts) w.organ_flag[m.vert_organ[v]] = 1;
  for (size_t o = 0; o < m.organs.size(); ++o) {
    const OrganRange& r = m.organs[o];
    if (!w.organ_flag[o]) continue;
    std::fill(w.fx.begin() + r.vert_begin, w.fx.begin() + r.vert_end, 0.0);
    std::fill(w.fy.begin() + r.vert_begin, w.fy.begin() + r.vert_end, 0.0);
    std::fill(w.fz.begin() + r.vert_begin, w.fz.begin() + r.vert_end, 0.0);
  }
  w.forces_zero = false;
  for (size_t o = 0; o < m.organs.size(); ++o)
    if (w.organ_flag[o] && s.organ_awake[o]) organ_internal_forces(m, m.organs[o], s, w);
  connection_forces(m, s, w);
}

// The tool's force or hold, and its reaction (force of the organ on the tool), after the
// internal forces are in work.f.
void apply_tool(const Model& m, State& s, Work& w, bool reaction, bool add_force) {
  ToolState& t = s.tool;
  if (reaction) t.reaction_N = {0, 0, 0};
  if (t.mode == ToolMode::none || t.verts.empty()) return;
  if (reaction)
    for (int32_t v : t.verts) {
      t.reaction_N[0] += w.fx[v], t.reaction_N[1] += w.fy[v], t.reaction_N[2] += w.fz[v];
    }
  if (t.mode == ToolMode::force && add_force) {
    double F[3] = {t.force_N[0], t.force_N[1], t.force_N[2]};
    const double mag = std::sqrt(F[0] * F[0] + F[1] * F[1] + F[2] * F[2]);
    t.clamped = false;
    if (m.guard && mag > m.max_tool_force_N) {
      const double sc = m.max_tool_force_N / mag;
      F[0] *= sc, F[1] *= sc, F[2] *= sc;
      t.clamped = true;
    }
    const double share = 1.0 / static_cast<double>(t.verts.size());
    for (int32_t v : t.verts) w.fx[v] += F[0] * share, w.fy[v] += F[1] * share, w.fz[v] += F[2] * share;
  }
}

// Where the attached vertices are held at the end of (sub)step fraction `frac` of this step.
void attach_targets(const Model& m, const State& s, Work& w, double frac) {
  const ToolState& t = s.tool;
  const double p0 = std::min(1.0, static_cast<double>(t.attach_progress) / t.attach_iterations);
  const double p1 = std::min(1.0, static_cast<double>(t.attach_progress + 1) / t.attach_iterations);
  const double p = p0 + (p1 - p0) * frac;
  for (size_t q = 0; q < t.verts.size(); ++q)
    for (int c = 0; c < 3; ++c) w.tool_target[3 * q + c] = t.anchor[3 * q + c] + p * t.offset_m[c] + t.contact_shift[c];
}

// Held vertices get the velocity that carries them to their target over h; with
// `snap` their positions are set to the target as well (before an implicit solve, or after an
// explicit update to remove rounding).
void hold_attached(State& s, const Work& w, double h, bool snap) {
  const ToolState& t = s.tool;
  for (size_t q = 0; q < t.verts.size(); ++q) {
    const int32_t v = t.verts[q];
    const double nx = w.tool_target[3 * q], ny = w.tool_target[3 * q + 1], nz = w.tool_target[3 * q + 2];
    s.vx[v] = (nx - s.x[v]) / h, s.vy[v] = (ny - s.y[v]) / h, s.vz[v] = (nz - s.z[v]) / h;
    if (snap) s.x[v] = nx, s.y[v] = ny, s.z[v] = nz;
  }
}

void snap_attached(State& s, const Work& w) {
  const ToolState& t = s.tool;
  for (size_t q = 0; q < t.verts.size(); ++q) {
    const int32_t v = t.verts[q];
    s.x[v] = w.tool_target[3 * q], s.y[v] = w.tool_target[3 * q + 1], s.z[v] = w.tool_target[3 * q + 2];
  }
}

// free_mask = fixed vertices and vertices held by an attachment excluded. Recomputed only when
// an attachment is (or was) active.
void set_free_mask(const Model& m, const State& s, Work& w) {
  const bool attach = s.tool.mode == ToolMode::attach;
  if (!attach && !w.mask_dirty) return;
  for (int32_t v = 0; v < m.nvert; ++v) w.free_mask[v] = m.vert_inv_mass[v] > 0 && !solid_vertex(m, v) ? 1.0 : 0.0;
  if (attach)
    for (int32_t v : s.tool.verts) w.free_mask[v] = 0.0;
  w.mask_dirty = attach;
}

}  // namespace softatlas::sim::engine

namespace softatlas::sim {
namespace {
void set_tool(const Model& m, State& s, const std::vector<int32_t>& verts, ToolMode mode) {
  s.tool.mode = mode;
  s.tool.verts.clear();
  for (int32_t v : verts)
    if (v >= 0 && v < m.nvert && m.vert_inv_mass[v] > 0) s.tool.verts.push_back(v);
  std::sort(s.tool.verts.begin(), s.tool.verts.end());
  s.tool.verts.erase(std::unique(s.tool.verts.begin(), s.tool.verts.end()), s.tool.verts.end());
  for (int32_t v : s.tool.verts) wake(m, s, m.vert_organ[v]);
  s.tool.reaction_N = {0, 0, 0};
  s.tool.clamped = false;
}
}  // namespace

void pull_force(const Model& m, State& s, const std::vector<int32_t>& verts, const std::array<double, 3>& force_N) {
  set_tool(m, s, verts, ToolMode::force);
  s.tool.force_N = force_N;
}

void attach(const Model& m, State& s, const std::vector<int32_t>& verts, const std::array<double, 3>& offset_m,
            int iterations) {
  set_tool(m, s, verts, ToolMode::attach);
  s.tool.offset_m = offset_m;
  s.tool.attach_iterations = std::max(1, iterations);
  s.tool.attach_progress = 0;
  s.tool.anchor.resize(3 * s.tool.verts.size());
  s.tool.contact_shift = {0, 0, 0};
  for (size_t q = 0; q < s.tool.verts.size(); ++q) {
    const int32_t v = s.tool.verts[q];
    s.tool.anchor[3 * q] = s.x[v], s.tool.anchor[3 * q + 1] = s.y[v], s.tool.anchor[3 * q + 2] = s.z[v];
  }
}

void move_attachment(State& s, const std::array<double, 3>& offset_m) {
  // The new offset is reached at once (a device moves continuously at 1 kHz).
  s.tool.offset_m = offset_m;
  s.tool.attach_progress = s.tool.attach_iterations;
}

void release(State& s) {
  s.tool.mode = ToolMode::none;
  s.tool.verts.clear();
  s.tool.reaction_N = {0, 0, 0};
  s.tool.clamped = false;
}

std::array<double, 3> tool_reaction(const State& s) { return s.tool.reaction_N; }

}  // namespace softatlas::sim
