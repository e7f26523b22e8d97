// The stability guard: which integrator a step uses (the compiled plan, or implicit Euler after
// a restore), the runaway check, and the snapshot / restore of the last good state.
#include <algorithm>
#include <cmath>

#include "engine.hpp"

namespace softatlas::sim::engine {
namespace {

void snapshot(const Model& m, const State& s, Work& w) {
  std::copy(s.x.begin(), s.x.end(), w.good_x.begin());
  std::copy(s.y.begin(), s.y.end(), w.good_y.begin());
  std::copy(s.z.begin(), s.z.end(), w.good_z.begin());
  w.good_time_s = s.time_s;
  w.good_step = s.step_count;
}

void restore(const Model& m, State& s, Work& w) {
  if (w.good_step < 0) {  // nothing saved yet: the rest shape is always good
    std::copy(m.vert_rest_x.begin(), m.vert_rest_x.end(), s.x.begin());
    std::copy(m.vert_rest_y.begin(), m.vert_rest_y.end(), s.y.begin());
    std::copy(m.vert_rest_z.begin(), m.vert_rest_z.end(), s.z.begin());
  } else {
    std::copy(w.good_x.begin(), w.good_x.end(), s.x.begin());
    std::copy(w.good_y.begin(), w.good_y.end(), s.y.begin());
    std::copy(w.good_z.begin(), w.good_z.end(), s.z.begin());
  }
  // Velocities are zeroed: the energy that blew up must not come back.
  std::fill(s.vx.begin(), s.vx.end(), 0.0);
  std::fill(s.vy.begin(), s.vy.end(), 0.0);
  std::fill(s.vz.begin(), s.vz.end(), 0.0);
}

}  // namespace

Integrator step_integrator(const Model& m, const State& s, int& substeps) {
  Integrator eff = m.guard ? m.effective_integrator : m.integrator;
  if (m.guard && s.guard_implicit) eff = Integrator::implicit;
  substeps = (eff == Integrator::implicit || !m.guard) ? 1 : m.substeps;
  return eff;
}

// Non-finite values, or a vertex crossing a quarter of the scene in one step.
bool guard_check(const Model& m, State& s, Work& w, const IntegrateStats& st, StepReport& rep) {
  const bool bad = !std::isfinite(st.checksum) || rep.max_speed_m_s * m.dt_s > 0.25 * m.size_m;
  if (bad && m.guard) {
    restore(m, s, w);
    s.guard_implicit = true;
    ++s.guard_restores;
    rep.status = StepStatus::restored;
    rep.message =
        "guard: non-finite or runaway state; restored the last good state and "
        "switched to implicit Euler";
    rep.max_speed_m_s = 0.0;
  }
  if (rep.status != StepStatus::ok || rep.tool_clamped) ++s.guard_actions;
  return bad;
}

void guard_snapshot(const Model& m, const State& s, Work& w, bool bad) {
  if (m.guard && !bad && s.step_count % kSnapshotEvery == 0) snapshot(m, s, w);
}

}  // namespace softatlas::sim::engine

namespace softatlas::sim {

const char* to_string(StepStatus status) {
  switch (status) {
    case StepStatus::ok:
      return "ok";
    case StepStatus::substepped:
      return "substepped";
    case StepStatus::implicit_fallback:
      return "implicit-fallback";
    case StepStatus::restored:
      return "restored";
  }
  return "?";
}

}  // namespace softatlas::sim
