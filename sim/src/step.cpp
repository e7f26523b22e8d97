// The step, as a table of contents: each line is a family of equations in its own file
// (engine.hpp lists them). Also make_state / make_work (every buffer the step uses is sized
// here), perturb (the start of the rest tests) and the paper's stopping rule.
#include <algorithm>
#include <cmath>
#include <random>

#include "engine.hpp"
#include "workers.hpp"

namespace softatlas::sim {

using engine::kCgChunk;

State make_state(const Model& m) {
  State s;
  s.x = m.vert_rest_x, s.y = m.vert_rest_y, s.z = m.vert_rest_z;
  s.vx.assign(m.nvert, 0.0), s.vy.assign(m.nvert, 0.0), s.vz.assign(m.nvert, 0.0);
  s.organ_awake.assign(m.organs.size(), 1);
  for (size_t o = 0; o < m.organs.size(); ++o)  // rigid organs sleep for good (sleep.cpp)
    if (m.organs[o].model == ModelKind::rigid) s.organ_awake[o] = 0;
  s.organ_still_steps.assign(m.organs.size(), 0);
  init_solid_state(m, s);  // solid_step.cpp: lattice nodes at rest
  s.contact_let_go.assign(m.contact.on ? m.nvert : 0, 0);
  return s;
}

void perturb(const Model& m, State& s, double amplitude_m, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  auto direction = [&](double d[3]) {
    for (int c = 0; c < 3; ++c) d[c] = gauss(rng);
    const double n = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    const double sc = n > 0 ? amplitude_m / n : 0.0;
    for (int c = 0; c < 3; ++c) d[c] *= sc;
  };
  for (int32_t v = 0; v < m.nvert; ++v) {
    if (m.vert_inv_mass[v] == 0) continue;
    double d[3];
    direction(d);
    s.x[v] += d[0], s.y[v] += d[1], s.z[v] += d[2];
  }
  for (size_t i = 0; i + 2 < s.solid_x.size(); i += 3) {  // the lattice carries a solid's surface
    double d[3];
    direction(d);
    for (int c = 0; c < 3; ++c) s.solid_x[i + c] += d[c];
  }
}

Work make_work(const Model& m) {
  Work w;
  const size_t n = m.nvert;
  for (auto* v : {&w.fx, &w.fy, &w.fz, &w.lap_x, &w.lap_y, &w.lap_z, &w.area2, &w.half_bk, &w.px, &w.py, &w.pz,
                  &w.free_mask, &w.good_x, &w.good_y, &w.good_z})
    v->assign(n, 0.0);
  const int threads = std::min<int>(m.threads, static_cast<int>(m.organs.size()));
  // Implicit solver buffers only when a step can be implicit: asked for, or the guard's fallback.
  if (m.integrator == Integrator::implicit || m.guard) {
    w.flex_grad.assign(12 * static_cast<size_t>(m.nflex), 0.0);
    for (auto* v : {&w.rx, &w.ry, &w.rz, &w.diag_x, &w.diag_y, &w.diag_z}) v->assign(n, 0.0);
    for (auto* v : {&w.cg_b, &w.cg_r, &w.cg_p, &w.cg_q, &w.cg_x, &w.cg_inv}) v->assign(4 * n, 0.0f);
    w.cg_mass.resize(n);
    for (size_t v = 0; v < n; ++v) w.cg_mass[v] = static_cast<float>(m.vert_mass[v]);
    w.jac.assign(4 * static_cast<size_t>(m.nspring), 0.0f);
    w.cjac.assign(4 * static_cast<size_t>(m.nconn), 0.0f);
    // CG spring order: per organ, four interleaved streams over the quarters of its springs
    w.cg_sa.resize(m.nspring), w.cg_sb.resize(m.nspring), w.cg_s.resize(m.nspring);
    for (const OrganRange& r : m.organs) {
      const int32_t count = r.spring_end - r.spring_begin, quarter = (count + 3) / 4;
      int32_t t = r.spring_begin;
      for (int32_t k = 0; k < quarter; ++k)
        for (int32_t stream = 0; stream < 4; ++stream) {
          const int32_t local = stream * quarter + k;
          if (local >= count) continue;
          const int32_t sp = r.spring_begin + local;
          w.cg_sa[t] = m.spring_a[sp], w.cg_sb[t] = m.spring_b[sp], w.cg_s[t] = sp;
          ++t;
        }
    }
    // one chunk scratch per worker thread
    w.cg_tmp.assign(6 * static_cast<size_t>(kCgChunk) * std::max(1, threads), 0.0);
    w.cg_done.assign(m.component_begin.empty() ? 0 : m.component_begin.size() - 1, 0);
  }
  w.organ_flag.assign(m.organs.size(), 0);
  if (threads > 1) {
    // Organs to threads, largest first onto the least loaded (LPT), by spring + face count.
    w.workers = std::make_shared<WorkerPool>(threads);
    w.workers->organs.assign(threads, {});
    std::vector<int32_t> order(m.organs.size());
    for (size_t o = 0; o < order.size(); ++o) order[o] = static_cast<int32_t>(o);
    auto cost = [&](int32_t o) {
      const OrganRange& r = m.organs[o];
      return (r.spring_end - r.spring_begin) + (r.curvature ? (r.face_end - r.face_begin) : 0);
    };
    std::sort(order.begin(), order.end(), [&](int32_t a, int32_t b) { return cost(a) > cost(b); });
    std::vector<int64_t> load(threads, 0);
    for (int32_t o : order) {
      const int t = static_cast<int>(std::min_element(load.begin(), load.end()) - load.begin());
      w.workers->organs[t].push_back(o);
      load[t] += cost(o);
    }
    // Implicit solves: whole components (organs joined by connections), same balancing.
    const int32_t ncomp = static_cast<int32_t>(m.component_begin.size()) - 1;
    std::vector<int32_t> comps(ncomp);
    std::vector<int64_t> ccost(ncomp, 0);
    for (int32_t c = 0; c < ncomp; ++c) {
      comps[c] = c;
      for (int32_t k = m.component_begin[c]; k < m.component_begin[c + 1]; ++k) ccost[c] += cost(m.component_organs[k]);
    }
    std::sort(comps.begin(), comps.end(), [&](int32_t a, int32_t b) { return ccost[a] > ccost[b]; });
    w.workers->components.assign(threads, {});
    std::fill(load.begin(), load.end(), 0);
    for (int32_t c : comps) {
      const int t = static_cast<int>(std::min_element(load.begin(), load.end()) - load.begin());
      w.workers->components[t].push_back(c);
      load[t] += ccost[c];
    }
  }
  w.tool_target.reserve(3 * n);  // attach() may hold any number of vertices up to all
  for (int32_t v = 0; v < m.nvert; ++v) w.free_mask[v] = m.vert_inv_mass[v] > 0 && !solid_vertex(m, v) ? 1.0 : 0.0;
  w.solid = make_solid_work(m);
  w.contact = make_contact_work(m);
  return w;
}

StepReport step(const Model& m, State& s, Work& w) {
  const FlushDenormals flush;  // workers.hpp: no float denormal stalls
  StepReport rep;
  engine::begin_tool_step(m, s, w);  // tool.cpp: free mask, attach targets

  int substeps = 1;  // guard.cpp: the integrator of this step
  const Integrator eff = engine::step_integrator(m, s, substeps);
  engine::IntegrateStats st;
  if (eff == Integrator::implicit) {  // implicit.cpp: backward Euler + CG
    st = engine::implicit_step(m, s, w, m.dt_s);
    if (m.integrator != Integrator::implicit) {
      rep.status = StepStatus::implicit_fallback;
      rep.message = "guard: time step too large for the explicit integrator, solved implicitly";
    }
  } else {  // explicit.cpp: 000 Algorithm 1 or symplectic Euler
    st = engine::explicit_step(m, s, w, eff == Integrator::verlet, substeps);
    if (substeps > 1) {
      rep.status = StepStatus::substepped;
      rep.message = "guard: time step above the stable estimate, split into sub-steps";
    }
  }
  if (!m.solids.empty()) {  // solid_step.cpp: the solid organs
    const SolidStats ss = solid_step(m, s, w);
    st.max_speed2 = std::max(st.max_speed2, ss.max_speed2);
    st.checksum += ss.checksum;
  }
  rep.contacts = contact_pass(m, s, w);  // contact.cpp: organs do not pass through
  // Inside each integrator: forces.cpp (springs.cpp 000 eq 6, 000 eq 7; curvature.cpp 000 eq 2
  // for 000 eq 5; flexion.cpp), tool.cpp (force or hold), then constraints.cpp
  // (compensation.cpp; volume.cpp 003 eq 25 to 003 eq 30).
  engine::end_tool_step(s);
  rep.tool_clamped = s.tool.clamped;
  rep.accel_sum = st.accel_sum;
  rep.cg_iterations = st.cg_iterations;
  rep.max_speed_m_s = std::sqrt(st.max_speed2);

  const bool restored = engine::guard_check(m, s, w, st, rep);  // guard.cpp: restore if runaway
  s.time_s += m.dt_s;
  ++s.step_count;
  engine::guard_snapshot(m, s, w, restored);  // guard.cpp: the last good state
  engine::update_sleep(m, s);                 // sleep.cpp: resting organs sleep
  return rep;
}

int64_t run_to_rest(const Model& m, State& s, Work& w, int64_t max_steps, double accel_tol, StepReport* last) {
  const bool was = w.measure_accel;
  w.measure_accel = true;
  int64_t k = 0;
  StepReport r;
  while (k < max_steps) {
    r = step(m, s, w);
    ++k;
    if (r.status != StepStatus::restored && r.accel_sum < accel_tol) break;
  }
  w.measure_accel = was;
  if (last) *last = r;
  return k;
}

}  // namespace softatlas::sim
