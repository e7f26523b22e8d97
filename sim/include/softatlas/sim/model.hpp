// Model / State / Work: the MuJoCo-style split of the physics core.
//
//   Model  fixed after compile(): topology, rest values, masses, parameters, the plan
//   State  what a step changes: positions, velocities, time, interaction progress, sleep
//   Work   scratch buffers, sized once by make_work(); step() never allocates
//
// Units: SI inside the core (m, kg, s, N). The organ-set loader converts mm to m.
// Arrays are flat, named entity_field, with counts beside them; vertices are SoA (x, y, z).
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "softatlas/sim/contact.hpp"
#include "softatlas/sim/solid.hpp"

namespace softatlas::sim {

enum class ModelKind : int32_t {
  tmsm = 0,     // Hooke springs (paper 000 baseline)
  cmsm = 1,     // Hooke + over-stretch / over-compress compensation (Duan et al. 2016)
  nmsm = 2,     // elastica springs (000 eq 5, 000 eq 6, 000 eq 7)
  flexion = 3,  // Hooke + dihedral flexion springs + volume constraint (paper 003)
  solid = 4,    // volumetric lattice, corotational FEM by projective dynamics (sim/solid.hpp)
  rigid = 5,    // fixed context (bone): drawn, picked, anchors connections; never moves or steps
};
const char* to_string(ModelKind kind);
bool parse_model_kind(const std::string& text, ModelKind& out);

enum class Integrator : int32_t {
  verlet = 0,         // paper 000 Algorithm 1 (position form)
  semi_implicit = 1,  // symplectic Euler: v += dt a, x += dt v
  implicit = 2,       // backward Euler, linearised once per step, solved with CG (Baraff-Witkin)
};
const char* to_string(Integrator integrator);
bool parse_integrator(const std::string& text, Integrator& out);

// Per-organ material parameters in the core (already in SI). Defaults match io::MaterialSpec,
// except the model: the core defaults to the paper's nmsm, organ sets (io) to solid.
struct Material {
  ModelKind model = ModelKind::nmsm;
  double young_modulus_pa = 4000.0;  // 000 eq 9
  double thickness_m = 1e-3;         // 000 eq 9
  double total_mass_kg = 0.0;        // > 0: 000 eq 8 with this mu; 0: density * enclosed volume
  double density_kg_m3 = 1060.0;
  double stiffness = 0.0;      // > 0: every spring gets this k (N/m) instead of 000 eq 9
  double damping = -1.0;       // >= 0: every spring gets this d (N s/m) instead of 000 eq 10
  double damping_scale = 1.0;  // multiplies 000 eq 10
  // Damping ratio zeta (1: critical); < 0: the model's default. Spring models: >= 0 gives every
  // spring the ratio of its own two-vertex mode instead of 000 eq 10,
  // d = zeta 2 sqrt(k m_a m_b / (m_a + m_b)); 000 eq 10 as used is zeta = (m_a + m_b) / sqrt(m_a m_b)
  // >= 2, larger on small vertices (docs/physics.md). Solid model: Rayleigh damping with this ratio
  // at the organ's lowest shear mode, default 0.5 (sim/solid.hpp).
  double damping_ratio = -1.0;
  double vertex_mass_kg = 0.0;  // > 0: every vertex gets this mass instead of 000 eq 8
  double elastica_a = 1.0;      // 000 eq 5
  double elastica_b = 0.1;      // 000 eq 5; 0 turns the curvature pass off for this organ
  int elastica_p = 1;           // 000 eq 5: 1 or 2
  // 000 eq 5 adds b |kappa|^p to the dimensionless a, so kappa must be measured in some length unit
  // L: we use b |kappa L|^p. The paper's organ experiments are in mm (L = 1e-3 m); its sphere is
  // dimensionless (L = 1). See docs/physics.md.
  double curvature_unit_m = 1e-3;
  // How far the curvature term b |kappa L|^p of 000 eq 5 may rise above its largest value in the rest
  // shape. A point load makes a cone tip whose discrete curvature grows without bound; uncapped,
  // the elastica length (and with it the spring's stiffness) explodes and no explicit step is
  // stable (docs/physics.md).
  double elastica_cap = 2.0;
  // false (default): the conservative elastica. 000 eq 5's factor a + b |kappa L|^p is taken at
  // the rest curvature, so each spring is Hooke with stiffness k (a + b |kappa0 L|^p): the force
  // is the gradient of E = 1/2 k_e (l - l0)^2 and an unloaded organ cannot gain energy.
  // true: the paper's literal form, curvature of the deformed shape every step; its force acts
  // along the spring only and is not the gradient of any energy, so at rest it can feed energy in
  // (1-5 mm drift from a 1 um perturbation, docs/physics.md). Kept to reproduce paper 000's tables.
  bool elastica_literal = false;
  double tau_s = -1.0;              // over-stretch ratio; < 0 = off
  double tau_c = -1.0;              // over-compress ratio; < 0 = off
  int compensation_iterations = 4;  // inner iterations of the compensation (CMSM)
  double flexion_stiffness = 0.0;   // dihedral springs, N m / rad; 0 = off
  double volume_stiffness = 0.0;    // volume constraint, 0..1 per step; 0 = off
  // solid model (sim/solid.hpp)
  double poisson_ratio = 0.49;  // Lame lambda, mu from E and nu (organs: nearly incompressible)
  int solid_nodes = 0;          // lattice node budget; 0 = the scene's 1,500 shared by volume (80-300)
  int solid_iterations = 0;     // local/global iterations per step; 0 = 4
};

// What the caller describes; compile() turns it into a Model (sim/scene.hpp).
struct OrganDesc {
  std::string name;
  std::vector<double> vertices;  // #V*3, metres
  std::vector<int32_t> faces;    // #F*3
  std::vector<int32_t> fixed;    // local vertex indices held in place
  Material material;
  bool shown = true;  // shown organs, and organs connected to them, are simulated
};

struct ConnectionDesc {
  int32_t organ_a = 0, vertex_a = 0;  // organ index into SceneDesc::organs, local vertex
  int32_t organ_b = 0, vertex_b = 0;
  double rest_length_m = 0.0;
  double stiffness = 0.0;  // N/m
};

struct SceneDesc {
  std::vector<OrganDesc> organs;
  std::vector<ConnectionDesc> connections;
  Integrator integrator = Integrator::semi_implicit;
  double dt_s = 1e-3;  // 0: the step the scene's models need (recommended_dt_s)
  bool gravity = false;
  std::array<double, 3> gravity_m_s2{0.0, 0.0, -9.81};
  int cg_iterations = 25;          // implicit Euler: maximum CG iterations
  double cg_tolerance = 1e-8;      // relative residual; 0 = always run cg_iterations
  bool guard = true;               // stability guard on
  double max_tool_force_N = 10.0;  // the guard clamps tool forces to this
  // Explicit sub-steps the guard may take before it switches to implicit Euler; one implicit
  // step with 25 CG iterations costs about as much as 10-15 explicit steps.
  int max_substeps = 16;
  bool allow_sleep = true;        // resting organs sleep until touched
  double sleep_speed_m_s = 1e-6;  // below this speed for sleep_steps steps, an organ sleeps
  int sleep_steps = 200;
  int threads = 1;      // worker threads; organs are stepped in parallel
  bool contact = true;  // organs do not pass through each other (sim/contact.hpp)
};

// One compiled organ: contiguous ranges in the global arrays.
struct OrganRange {
  std::string name;
  int32_t source_index = 0;         // index in SceneDesc::organs
  int32_t source_vertex_count = 0;  // vertices of the source mesh (some may be unused)
  int32_t vert_begin = 0, vert_end = 0;
  int32_t face_begin = 0, face_end = 0;
  int32_t spring_begin = 0, spring_end = 0;
  int32_t flex_begin = 0, flex_end = 0;
  ModelKind model = ModelKind::nmsm;
  double elastica_a = 1.0, elastica_b = 0.0;
  int elastica_p = 1;
  double curvature_unit_m = 1e-3;
  double elastica_cap = 2.0;  // absolute cap of the curvature term (rest maximum + material cap)
  double tau_s = -1.0, tau_c = -1.0;
  int compensation_iterations = 0;
  double volume_stiffness = 0.0;
  double rest_volume_m3 = 0.0;
  bool curvature = false;        // needs the curvature pass (literal nmsm with b > 0)
  bool elastica_frozen = false;  // conservative nmsm: compiled to Hooke springs of k (a + ...)
  bool damping = false;          // any spring with d > 0
  bool has_fixed = false;
};

struct Model {
  // vertices
  int32_t nvert = 0;
  std::vector<double> vert_rest_x, vert_rest_y, vert_rest_z;  // rest positions
  std::vector<double> vert_mass;                              // kg (fixed vertices keep their mass for reporting)
  std::vector<double> vert_inv_mass;                          // 0 for fixed vertices
  std::vector<int32_t> vert_organ;                            // compiled organ index
  std::vector<int32_t> vert_source;                           // index in the source organ mesh (vertices are reordered
                                                              // for locality: Cuthill-McKee, see compile.cpp)
  // faces (sorted by organ)
  int32_t nface = 0;
  std::vector<int32_t> face_vert;  // #F*3 global vertex indices
  // springs: organ edge springs first (sorted by organ, then by vertex), then connections
  int32_t nspring = 0;  // edge springs
  std::vector<int32_t> spring_a, spring_b;
  std::vector<double> spring_rest;     // l0 (Hooke) or rest elastica length l_e0 (nmsm)
  std::vector<double> spring_length0;  // plain rest length l0 (compensation, guard)
  std::vector<double> spring_k, spring_d;
  int32_t nconn = 0;  // inter-organ connection springs
  std::vector<int32_t> conn_a, conn_b;
  std::vector<double> conn_rest, conn_k, conn_d;
  // flexion (dihedral) springs: edge (a, b) with wings c, d
  int32_t nflex = 0;
  std::vector<int32_t> flex_a, flex_b, flex_c, flex_d;
  std::vector<double> flex_rest_angle, flex_k;
  // organs
  std::vector<OrganRange> organs;
  std::vector<int32_t> organ_neighbors_begin, organ_neighbors;  // CSR: organs joined by connections
  // Connected components of organs (independent linear systems for implicit Euler): organs
  // component_organs[component_begin[c] .. component_begin[c+1]), connection springs
  // [component_conn_begin[c], component_conn_begin[c+1]) (connections are sorted by component).
  std::vector<int32_t> component_begin, component_organs, component_conn_begin;
  // settings
  Integrator integrator = Integrator::semi_implicit;
  double dt_s = 1e-3;
  bool gravity = false;
  std::array<double, 3> gravity_m_s2{0.0, 0.0, -9.81};
  int cg_iterations = 25;
  double cg_tolerance = 1e-8;
  bool guard = true;
  double max_tool_force_N = 10.0;
  int max_substeps = 16;
  bool allow_sleep = true;
  double sleep_speed_m_s = 1e-6;
  int sleep_steps = 200;
  int threads = 1;
  // stability estimate (guard): largest stable explicit dt for this model, and the plan
  double stable_dt_s = 0.0;
  int substeps = 1;  // explicit sub-steps per step() chosen by the guard
  Integrator effective_integrator = Integrator::semi_implicit;
  // what compile() left out and why, and what each step computes (printed by --explain)
  std::vector<std::string> plan;
  std::vector<std::string> dropped;
  double size_m = 0.0;  // bounding-box diagonal, a length scale for tolerances
  // solid organs (sim/solid.hpp): their surface vertices follow the lattice, not an integrator
  std::vector<SolidBody> solids;
  std::vector<int32_t> organ_solid;  // per organ: index into solids, -1 for surface models
  // rigid organs (ModelKind::rigid): every vertex fixed, no springs, asleep for good. Their
  // vertices that end a connection spring get forces they never consume; the explicit step
  // clears just these after integrating (so a rigid organ costs no per-vertex work).
  std::vector<int32_t> rigid_conn_verts;
  ContactModel contact;  // contact between organs (sim/contact.hpp)
};

// The tool: one interaction at a time (force pulling or position attachment).
enum class ToolMode : int32_t { none = 0, force = 1, attach = 2 };

struct ToolState {
  ToolMode mode = ToolMode::none;
  std::vector<int32_t> verts;               // picked global vertex indices
  std::array<double, 3> force_N{0, 0, 0};   // force mode: total force, split evenly
  std::array<double, 3> offset_m{0, 0, 0};  // attach mode: target displacement of the picked verts
  int attach_iterations = 30;               // attach mode: reach the target over this many steps
  int attach_progress = 0;
  std::vector<double> anchor;                    // attach: start positions of the picked verts (#*3)
  std::array<double, 3> contact_shift{0, 0, 0};  // attach: where contact holds the picked vertices
                                                 // off their targets (a proxy stopped at another organ, contact.cpp)
  // outputs of the last step
  std::array<double, 3> reaction_N{0, 0, 0};  // force the organ exerts on the tool
  bool clamped = false;                       // the guard limited the requested force
};

struct State {
  double time_s = 0.0;
  int64_t step_count = 0;
  std::vector<double> x, y, z, vx, vy, vz;
  std::vector<uint8_t> organ_awake;  // per compiled organ
  std::vector<int32_t> organ_still_steps;
  ToolState tool;
  // stability guard bookkeeping
  bool guard_implicit = false;  // after a restore the guard keeps solving implicitly
  int64_t guard_actions = 0;    // sub-stepped, implicit, clamped or restored steps
  int64_t guard_restores = 0;
  std::vector<double> solid_x, solid_v;  // solid organs' lattice nodes (#nodes*3), sim/solid.hpp
  std::vector<uint8_t> contact_let_go;   // per vertex: pushed in deep, left to elasticity (contact.hpp)
};

class WorkerPool;  // sim/src/workers.hpp

// A Work belongs to one stepping thread at a time (its worker pool is shared by copies).
struct Work {
  std::shared_ptr<WorkerPool> workers;                      // model.threads > 1: organs stepped in parallel
  std::vector<double> fx, fy, fz;                           // force accumulators
  std::vector<double> lap_x, lap_y, lap_z, area2, half_bk;  // curvature pass
  std::vector<double> px, py, pz;                           // previous positions (compensation, attach)
  // implicit solver
  std::vector<double> rx, ry, rz;  // right-hand side, assembled in double
  // CG vectors in float, 4 per vertex (x, y, z, 0): right-hand side, residual, direction, A p, solution, and the
  // inverse Jacobi diagonal with the free mask in its fourth lane. The solve is bound by memory
  // traffic; float changes dv by about 1e-7 relative, far below the error of 25 CG iterations
  // (docs/performance.md).
  std::vector<float> cg_b, cg_r, cg_p, cg_q, cg_x, cg_inv, cg_mass;
  // per spring blocks alpha I + w w^T of the implicit system (w = sqrt(beta) u): 4 floats each,
  // (w_x, w_y, w_z, alpha); edge springs, then connection springs (cjac)
  std::vector<float> jac, cjac;
  // the CG's order of the edge springs (per organ, four interleaved streams; see step.cpp):
  // ends and index of the t-th spring in that order
  std::vector<int32_t> cg_sa, cg_sb, cg_s;
  std::vector<double> cg_tmp;                  // block assembly scratch (one chunk of springs)
  std::vector<int32_t> cg_done;                // CG iterations done, per connected component
  std::vector<double> flex_grad;               // implicit: d theta / dx of each flexion spring (#*12)
  std::vector<double> diag_x, diag_y, diag_z;  // Jacobi preconditioner
  std::vector<uint8_t> organ_flag;             // per organ scratch (organs the tool holds)
  std::vector<double> free_mask;               // 1 for vertices the integrator moves, else 0
  std::vector<double> tool_target;             // attach: current target of each picked vertex
  bool measure_accel = false;                  // fill StepReport::accel_sum (costs a sqrt/vertex)
  bool forces_zero = true;                     // fx/fy/fz are all zero (the explicit update clears them)
  bool mask_dirty = false;                     // free_mask must be recomputed
  // guard: last good state
  std::vector<double> good_x, good_y, good_z;  // restore zeroes velocities
  double good_time_s = 0.0;
  int64_t good_step = -1;
  std::vector<SolidWork> solid;  // per solid organ (sim/solid.hpp)
  ContactWork contact;           // contact detection and projection (sim/contact.hpp)
};

}  // namespace softatlas::sim
