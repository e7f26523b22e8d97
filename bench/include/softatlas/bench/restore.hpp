// `softatlas bench restore`: does a pulled organ come back, and does it stay put at rest?
//
//   10 s unloaded from rest plus a 1e-6 m random perturbation (fixed seed)  -> rest_drift_mm
//   grasp the organ's anterior-inferior region, pull 30 mm over 0.5 s       -> pull_reached_mm
//   hold 1 s, release, 5 s more                                              -> residual_mm,
//                                                                               restoration_time_s
//   throughout                                                               -> volume_change_pct
//
// Simulated time throughout (the wall time is reported beside it as a real-time factor).
#pragma once

#include <string>
#include <vector>

#include "softatlas/sim/sim.hpp"

namespace softatlas::bench {

struct RestoreOptions {
  double pull_m = 0.030;
  double rest_s = 10.0, pull_s = 0.5, hold_s = 1.0, after_s = 5.0;
  double residual_at_s = 2.0;      // residual_mm is taken this long after the release
  double restored_below_m = 1e-3;  // restoration_time_s: first time the residual is below this
  double perturb_m = 1e-6;         // rest perturbation: each free vertex moves this far
  unsigned seed = 1;
  bool progress = false;  // a progress line on stderr every simulated second
};

struct RestoreResult {
  std::string organ, model, integrator;
  double dt_s = 0.0;
  int grasped_vertices = 0;
  double rest_drift_mm = 0.0;        // largest displacement during the unloaded phase
  double pull_reached_mm = 0.0;      // displacement of the grasped region's centroid at the hold's end
  double residual_mm = 0.0;          // residual_at_s after the release, rigid motion removed
  double restoration_time_s = -1.0;  // < 0: the residual never fell below restored_below_m
  double volume_change_pct = 0.0;    // the signed change of largest magnitude during the run
  bool finite = true;
  double simulated_s = 0.0, wall_s = 0.0;
};

// Runs the protocol on organ `organ` of a compiled scene description (InputError if the organ is
// absent or has no free vertex to grasp).
RestoreResult run_restore(const sim::SceneDesc& scene, const std::string& organ, const RestoreOptions& options);

// Largest distance (m) of any vertex of `organ` from its rest position once the best-fit rigid
// motion (Kabsch) of the organ is removed.
double rigid_residual(const sim::Model& m, const sim::State& s, int32_t organ);

}  // namespace softatlas::bench
