#include "trajectory.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

namespace softatlas::evidence {

Trajectory run_trajectory(Simulation& sim, const TriMesh& surface, const std::vector<int32_t>& tool_verts,
                          const LoadCase& load, const Reference& ref, double dt_s,
                          const std::vector<int64_t>& snap_steps, int64_t max_steps, double accel_tol,
                          bool restoration) {
  using clock = std::chrono::steady_clock;
  Trajectory out;
  const double v0 = std::abs(enclosed_volume(surface));
  if (load.attach)
    sim.attach(tool_verts, load.value, load.attach_iterations);
  else
    sim.pull(tool_verts, load.value);
  std::vector<double> x;
  double step_seconds = 0.0;
  int64_t guard_actions = 0;
  bool finite = true;
  auto snapshot = [&](int64_t it, bool converged) {
    Snapshot s;
    s.iterations = it;
    s.ms_per_step = it > 0 ? 1e3 * step_seconds / static_cast<double>(it) : 0.0;
    sim.positions(x);
    if (ref.valid) position_error_mm(surface.V, x, ref.disp, s.rms_mm, s.max_mm);
    s.volume_change_pct = 100.0 * (sim.volume() - v0) / v0;
    s.reaction = sim.reaction();
    if (load.attach) {
      const std::array<double, 3> d = {s.reaction[0] - ref.reaction[0], s.reaction[1] - ref.reaction[1],
                                       s.reaction[2] - ref.reaction[2]};
      const double offset = std::max(norm3(load.value), 1e-300);
      s.grasp_stiffness_N_per_m = norm3(s.reaction) / offset;
      if (ref.valid) {
        s.force_error_pct = 100.0 * norm3(d) / std::max(norm3(ref.reaction), 1e-300);
        s.grasp_stiffness_ratio = norm3(s.reaction) / std::max(norm3(ref.reaction), 1e-300);
      }
    }
    s.finite = finite;
    s.converged = converged;
    s.guard_actions = guard_actions;
    out.snaps.push_back(s);
  };
  std::vector<int64_t> snaps = snap_steps;
  std::sort(snaps.begin(), snaps.end());
  size_t next = 0;
  int64_t it = 0;
  bool converged = false;
  const int64_t arrive = load.attach ? load.attach_iterations : 0;
  // Paper 000's stopping rule sum_i |a_i| < tol, with a_i from the last three positions (the
  // harness measures it the same way for every model, outside the timed step).
  std::vector<double> p1, p2;
  sim.positions(p1);
  p2 = p1;
  auto accel_sum = [&]() {
    sim.positions(x);
    double s = 0.0;
    for (size_t i = 0; i < x.size() / 3; ++i) {
      double a2 = 0;
      for (int c = 0; c < 3; ++c) {
        const double a = (x[3 * i + c] - 2.0 * p1[3 * i + c] + p2[3 * i + c]) / (dt_s * dt_s);
        a2 += a * a;
      }
      s += std::sqrt(a2);
    }
    std::swap(p2, p1);
    std::swap(p1, x);
    return s;
  };
  while (it < max_steps) {
    const auto t0 = clock::now();
    StepOut r = sim.step();
    step_seconds += std::chrono::duration<double>(clock::now() - t0).count();
    ++it;
    guard_actions += r.guard_acted ? 1 : 0;
    if (!r.finite) {
      finite = false;
      break;
    }
    r.accel_sum = accel_sum();
    while (next < snaps.size() && snaps[next] < it) ++next;
    if (next < snaps.size() && snaps[next] == it) {
      snapshot(it, false);
      ++next;
    }
    if (it > arrive && r.accel_sum < accel_tol) {
      converged = true;
      break;
    }
  }
  if (out.snaps.empty() || out.snaps.back().iterations != it)
    snapshot(it, converged);
  else
    out.snaps.back().converged = converged;
  if (restoration && finite) {
    sim.release();
    int64_t k = 0;
    sim.positions(p1);
    p2 = p1;
    for (; k < max_steps; ++k) {
      const StepOut r = sim.step();
      if (!r.finite) break;
      if (accel_sum() < accel_tol && k > 1) break;
    }
    sim.positions(x);
    restoration_mm(surface.V, x, out.restoration_mean_mm, out.restoration_sd_mm);
    out.restoration_time_ms = 1e3 * dt_s * static_cast<double>(k);
    out.restored_measured = true;
  }
  return out;
}

}  // namespace softatlas::evidence
