// One loaded run of one model, measured at several iteration counts (private to the evidence).
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

#include "softatlas/evidence/evidence.hpp"
#include "softatlas/sim/fem_quadratic.hpp"
#include "softatlas/evidence/runner.hpp"
#include "softatlas/evidence/scenario.hpp"

namespace softatlas::evidence {

struct Reference {
  std::vector<double> disp;                 // FEM displacement at the surface's vertices (#V*3)
  std::array<double, 3> reaction{0, 0, 0};  // FEM force on the tool (attach loads)
  bool valid = false;
};

struct Snapshot {
  int64_t iterations = 0;
  double ms_per_step = 0.0;
  double rms_mm = 0.0, max_mm = 0.0, volume_change_pct = 0.0;
  // Attachments: the force on the tool against the reference's (%), and what the tool feels per
  // metre, |reaction| / |offset|, against the reference's. Force loads: NaN (at rest the reaction
  // balances the applied force by Newton's third law; it measures nothing).
  double force_error_pct = NAN, grasp_stiffness_N_per_m = NAN, grasp_stiffness_ratio = NAN;
  std::array<double, 3> reaction{0, 0, 0};
  bool finite = true, converged = false;
  int64_t guard_actions = 0;
};

struct Trajectory {
  std::vector<Snapshot> snaps;
  bool restored_measured = false;
  double restoration_mean_mm = 0.0, restoration_sd_mm = 0.0, restoration_time_ms = 0.0;
};

// Applies the load to `sim` (tool on `tool_verts`), steps until sum|a| < accel_tol (after the
// attachment has arrived) or max_steps, taking a snapshot at each of `snap_steps` and at the end.
// With `restoration`, then releases and measures paper 003's shape restoration.
Trajectory run_trajectory(Simulation& sim, const TriMesh& surface, const std::vector<int32_t>& tool_verts,
                          const LoadCase& load, const Reference& ref, double dt_s,
                          const std::vector<int64_t>& snap_steps, int64_t max_steps, double accel_tol,
                          bool restoration);

// One state of the reference along a load's quasi-static path: the load fraction (0, 1] and the
// FEM node positions there (one per Newton increment of the reference solve).
struct PathPoint {
  double fraction = 1.0;
  std::vector<double> x;
};

// Parameter fitting against the FEM reference (paper 003 section 2.2): PSO and Nelder-Mead with
// the same budget, trained on the quasi-static path of one attachment (`train_path`, the
// reference's increments of loads[train]), tested at rest on every load (`ref_x`: the reference's
// final node positions, one per load). Writes fit_convergence.svg.
nlohmann::json fit_parameters(const Options& opt, const TriMesh& source, const sim::fem::QuadraticModel& fmodel,
                              const std::vector<LoadCase>& loads, const std::vector<std::vector<double>>& ref_x,
                              size_t train, const std::vector<PathPoint>& train_path);

}  // namespace softatlas::evidence
