// The step's parts (private header), one file per concern, MuJoCo engine_*.c style. step.cpp
// calls them in the order of its table of contents:
//
//   forces.cpp       all internal forces of the awake organs (springs, curvature, flexion)
//   springs.cpp      edge and connection springs (000 eq 6, 000 eq 7) and their implicit blocks
//   curvature.cpp    discrete mean curvature per vertex (000 eq 2) for the elastica (000 eq 5)
//   flexion.cpp      dihedral flexion springs (003), forces and Gauss-Newton blocks
//   compensation.cpp over-stretch / over-compress compensation (CMSM)
//   volume.cpp       volume constraint (003 eq 25 to 003 eq 30)
//   constraints.cpp  the position passes after an integration (compensation, volume)
//   explicit.cpp     paper 000 Algorithm 1 (Verlet position form) and symplectic Euler
//   implicit.cpp     backward Euler linearised once per step, Jacobi-preconditioned CG
//   tool.cpp         force pulling, position attachment, the reaction on the tool
//   sleep.cpp        resting organs sleep until touched
//   guard.cpp        integrator choice, snapshot / restore of the last good state
//   measure.cpp      volumes, energy, displacement, force and torque balance
//
// Nothing called from step() allocates or throws: every buffer was sized by make_work().
#pragma once

#include <cstdint>

#include "forces.hpp"
#include "softatlas/sim/sim.hpp"

namespace softatlas::sim::engine {

using kernels::kTiny;
constexpr int kSnapshotEvery = 16;  // guard: steps between snapshots of the last good state
constexpr int32_t kCgChunk = 256;   // springs per chunk of the vectorised block assembly

struct IntegrateStats {
  double max_speed2 = 0.0;
  double checksum = 0.0;
  double accel_sum = 0.0;
  int cg_iterations = 0;
};

// ---- forces.cpp ---------------------------------------------------------------------------------
void organ_internal_forces(const Model& m, const OrganRange& r, const State& s, Work& w);
void internal_forces(const Model& m, const State& s, Work& w);

// ---- springs.cpp --------------------------------------------------------------------------------
int spring_measure_kind(const OrganRange& r);  // 0 Hooke, 1/2 elastica p, 3 elastica with b = 0
void organ_spring_forces(const Model& m, const OrganRange& r, const State& s, Work& w);
void connection_forces(const Model& m, const State& s, Work& w);
// Implicit Euler: the per-spring blocks alpha I + w w^T into work.jac / work.cjac, the
// right-hand-side terms into work.rx and the Jacobi diagonal into work.diag (slot: the worker
// thread's chunk scratch).
void organ_spring_blocks(const Model& m, const OrganRange& r, const State& s, Work& w, double h, int slot);
void connection_blocks(const Model& m, const State& s, Work& w, double h);

// ---- curvature.cpp ------------------------------------------------------------------------------
void curvature_pass(const Model& m, const OrganRange& r, const State& s, Work& w);

// ---- flexion.cpp --------------------------------------------------------------------------------
// grad_out (implicit): d theta / dx of each flexion spring, 12 doubles per spring.
void flexion_forces(const Model& m, const OrganRange& r, const State& s, Work& w, double* grad_out = nullptr);
void flexion_blocks(const Model& m, const OrganRange& r, Work& w, double h);     // Jacobi diagonal
void flexion_velocity_terms(const Model& m, const State& s, Work& w, double h);  // h^2 K v0 of rhs
double cg_flexion(const Model& m, const Work& w, int32_t f, double c, const float* p, float* q);

// ---- compensation.cpp, volume.cpp, constraints.cpp ----------------------------------------------
void compensation_pass(const Model& m, const OrganRange& r, State& s, Work& w, double h);
void volume_pass(const Model& m, const OrganRange& r, State& s, Work& w, double h);
void constraint_passes(const Model& m, State& s, Work& w, double h);

// ---- explicit.cpp -------------------------------------------------------------------------------
// The step's explicit sub-steps (verlet or semi-implicit), `substeps` of dt / substeps each.
IntegrateStats explicit_step(const Model& m, State& s, Work& w, bool verlet, int substeps);

// ---- implicit.cpp -------------------------------------------------------------------------------
IntegrateStats implicit_step(const Model& m, State& s, Work& w, double h);

// ---- tool.cpp -----------------------------------------------------------------------------------
void begin_tool_step(const Model& m, const State& s, Work& w);  // free mask, attach targets' size
void end_tool_step(State& s);                                   // attachment progress
void tool_organ_forces(const Model& m, const State& s, Work& w);
void apply_tool(const Model& m, State& s, Work& w, bool reaction = true, bool add_force = true);
void attach_targets(const Model& m, const State& s, Work& w, double frac);
void hold_attached(State& s, const Work& w, double h, bool snap);
void snap_attached(State& s, const Work& w);
void set_free_mask(const Model& m, const State& s, Work& w);

// ---- sleep.cpp ----------------------------------------------------------------------------------
void update_sleep(const Model& m, State& s);

// ---- guard.cpp ----------------------------------------------------------------------------------
// The integrator of this step (the guard's plan, or implicit after a restore) and its sub-steps.
Integrator step_integrator(const Model& m, const State& s, int& substeps);
// Non-finite values or a runaway vertex: restores the last good state. Returns true if it did.
bool guard_check(const Model& m, State& s, Work& w, const IntegrateStats& st, StepReport& rep);
void guard_snapshot(const Model& m, const State& s, Work& w, bool restored);

}  // namespace softatlas::sim::engine
