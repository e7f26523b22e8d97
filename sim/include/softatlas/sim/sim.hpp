// The physics core's public API: compile a scene, make state and work, step.
//
//   SceneDesc scene = ...;                       // organs (metres), materials, connections
//   Model model = compile(scene);                // checks everything once (InputError)
//   State state = make_state(model);
//   Work work = make_work(model);
//   pull_force(model, state, verts, {0, 0, 1e-3});
//   StepReport r = step(model, state, work);     // no allocation, no throw
#pragma once

#include <string>

#include "softatlas/sim/error.hpp"
#include "softatlas/sim/geometry.hpp"
#include "softatlas/sim/model.hpp"

namespace softatlas::sim {

// Builds the Model of a scene, keeping only what it needs: organs that are shown or connected
// (transitively) to a shown organ; no curvature pass where b = 0 or the model is not nmsm; no
// damping work where d = 0; no gravity when off; connections to absent organs dropped. Computes
// masses (000 eq 8), stiffness (000 eq 9), damping (000 eq 10), rest elastica lengths, the stable time step,
// and the plan. Throws InputError (field named) for: empty or invalid meshes, out-of-range
// indices, non-finite coordinates, negative stiffness/mass/thickness, bad p, bad dt.
Model compile(const SceneDesc& scene);

// The time step a scene's models need when SceneDesc::dt_s is 0 (timestep.cpp): the solid
// model's implicit step (kSolidStep_s) when every organ that moves is solid, else the surface
// models' 1 ms (their explicit integrators and the guard's sub-steps are tuned for it).
constexpr double kSolidStep_s = 8e-3;
constexpr double kSurfaceStep_s = 1e-3;
double recommended_dt_s(const SceneDesc& scene);

// The compiled plan as text: what each step computes, what was left out and why.
std::string explain(const Model& model);

State make_state(const Model& model);  // rest positions, zero velocity, every organ awake
// Moves every free vertex, and every node of a solid organ's lattice, by `amplitude_m` in a
// random direction (seeded, so reproducible): the "rest plus a perturbation" start that shows
// whether a model drifts or self-excites with no load (bench restore, bench stability).
void perturb(const Model& model, State& state, double amplitude_m, uint32_t seed);
Work make_work(const Model& model);

enum class StepStatus : int32_t {
  ok = 0,
  substepped = 1,         // the guard split the step into model.substeps explicit sub-steps
  implicit_fallback = 2,  // the guard solved this step with implicit Euler
  restored = 3,           // non-finite or runaway values: the last good state was restored
};
const char* to_string(StepStatus status);

struct StepReport {
  StepStatus status = StepStatus::ok;
  double accel_sum = 0.0;  // sum_i |a_i| over free vertices (paper 000 stopping rule)
  double max_speed_m_s = 0.0;
  bool tool_clamped = false;
  int cg_iterations = 0;     // implicit steps: CG iterations done (most over the components)
  int contacts = 0;          // vertices projected out of another organ (contact.cpp)
  const char* message = "";  // static text, set when status != ok
};

// Advances the state by model.dt_s. Never allocates, never throws; on non-finite values it
// restores the last good state (kept every few steps), zeroes velocities and reports `restored`.
StepReport step(const Model& model, State& state, Work& work);

// The paper's stopping rule: step until sum |a| < accel_tol or max_steps. Returns steps taken.
int64_t run_to_rest(const Model& model, State& state, Work& work, int64_t max_steps, double accel_tol,
                    StepReport* last = nullptr);

// ---- interaction ------------------------------------------------------------------------------
// Force pulling: a total force (N) split evenly over the picked vertices.
void pull_force(const Model& model, State& state, const std::vector<int32_t>& verts,
                const std::array<double, 3>& force_N);
// Position attachment (paper 000 section III.C): the picked vertices move from where they are
// to where they are + offset over `iterations` steps, then stay there.
void attach(const Model& model, State& state, const std::vector<int32_t>& verts, const std::array<double, 3>& offset_m,
            int iterations);
// Moves an existing attachment's target (haptic device motion): new offset from the anchor.
void move_attachment(State& state, const std::array<double, 3>& offset_m);
void release(State& state);
// The force the organ exerts on the tool (N): minus the sum of internal forces... see
// docs/physics.md; for force pulling at equilibrium it is minus the applied force.
std::array<double, 3> tool_reaction(const State& state);

// One implicit step's stiffness (N/m) of holding `verts` (global) on solid organs: how much the
// tool's reaction changes when every held vertex's target moves by the same offset, from the
// solid step's prefactored matrix (inertia M/h^2, elasticity, Rayleigh damping): the sum over the
// solid organs held of 1^T (C A^-1 C^T)^-1 1, isotropic (solid_hold.cpp). 0 when none of `verts`
// is on a solid organ. For the haptic coupling's local model; allocates unless `verts` is the
// hold the last step used.
double solid_hold_stiffness(const Model& model, const Work& work, const std::vector<int32_t>& verts);

// Wakes an organ and every organ connected to it.
void wake(const Model& model, State& state, int32_t organ);

// ---- measurements -----------------------------------------------------------------------------
double organ_volume(const Model& model, const State& state, int32_t organ);
double total_volume(const Model& model, const State& state);
// Largest displacement from the rest shape (m).
double max_displacement(const Model& model, const State& state);
// Kinetic + spring potential energy (J), for drift measurements.
double total_energy(const Model& model, const State& state);
// Sum of internal forces and of their torques about the origin (should both vanish).
void internal_force_and_torque(const Model& model, const State& state, Work& work, std::array<double, 3>& force,
                               std::array<double, 3>& torque);
// Internal forces only (springs, damping, flexion, connections; no gravity, no tool) into
// work.fx/fy/fz; used by tests and by the reaction force.
void compute_internal_forces(const Model& model, const State& state, Work& work);

// Positions of one organ as row-major #V*3 in the source mesh's vertex order, so the source
// faces index them directly (rendering, export). Vertices used by no face are (0, 0, 0).
void organ_positions(const Model& model, const State& state, int32_t organ, std::vector<double>& out);
// Global (compiled) index of vertex `source_vertex` of the organ's source mesh; -1 if unused.
// The compiler reorders vertices for memory locality: always map through this.
int32_t global_vertex(const Model& model, int32_t organ, int32_t source_vertex);
int32_t find_organ(const Model& model, const std::string& name);  // -1 if absent

}  // namespace softatlas::sim
