// Triangular tensor-mass model (paper 002: linear elastic tensor-mass on triangle meshes).
//
// Each triangle is a plane-stress linear elastic membrane element of thickness t. Its 9x9
// stiffness splits into 3x3 tensors (paper 002 eq 10): node tensors K_II accumulated on the
// vertices and edge tensors K_IJ accumulated on the edges, so the internal force is
//   F_I = -(K_II u_I + sum_J K_IJ u_J)                                        (eq 15)
// with u the displacement from rest. Damping is Rayleigh, C = alpha M + beta K (eq 3, 16), and
// the step is implicit Euler linearised once (eqs 19-22), solved with conjugate gradients
// (matrix-free, Jacobi preconditioned) as in SOFA's EulerImplicitSolver + CGLinearSolver.
//
// Like paper 002 (and SOFA's TriangularTensorMassForceField) the model is linear: u is measured
// in the world frame, so large rotations produce spurious forces; it suits small deformations.
// Same layout rules as the core (Model / State / Work; step() does not allocate or throw).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

namespace softatlas::sim::tmm {

struct Params {
  double young_modulus_pa = 4000.0;  // E
  double poisson_ratio = 0.45;       // nu, in (-1, 0.5)
  double thickness_m = 1e-3;         // t, as paper 000 eq 9
  double total_mass_kg = 0.0;        // > 0: lumped over vertices by area (paper 002 eq 13);
  double density_kg_m3 = 1060.0;     //   0: density * enclosed volume
  double rayleigh_mass = 0.1;        // alpha (1/s)
  double rayleigh_stiffness = 0.01;  // beta (s)
  int cg_iterations = 100;
  double cg_tolerance = 1e-8;  // relative residual
};

struct Model {
  int32_t nvert = 0, nedge = 0;
  std::vector<double> rest;             // #V*3 row-major
  std::vector<double> vert_mass;        // #V
  std::vector<uint8_t> vert_fixed;      // #V
  std::vector<double> node_tensor;      // #V*9 row-major K_II
  std::vector<int32_t> edge_a, edge_b;  // a < b
  std::vector<double> edge_tensor;      // #E*9 row-major K_ab (K_ba = K_ab^T)
  std::vector<int32_t> faces;           // #F*3 (volume measurement)
  Params params;
  double lame_lambda_plane = 0.0, lame_mu = 0.0;  // plane-stress Lame coefficients
};

// Throws InputError("tensor-mass: ...") on empty meshes, bad indices, degenerate triangles,
// non-finite coordinates or out-of-range parameters. V: #V*3 metres, F: #F*3.
Model compile(const std::vector<double>& V, const std::vector<int32_t>& F, const std::vector<int32_t>& fixed,
              const Params& params);

struct Tool {
  // force mode: a total force split evenly over verts; attach mode: verts move by offset over
  // `iterations` steps (paper 000 section III.C) and stay there.
  enum Mode : int32_t { none = 0, force = 1, attach = 2 } mode = none;
  std::vector<int32_t> verts;
  std::array<double, 3> force_N{0, 0, 0};
  std::array<double, 3> offset_m{0, 0, 0};
  int iterations = 30, progress = 0;
  std::vector<double> anchor;  // attach: start positions (#verts*3)
};

struct State {
  std::vector<double> x, v;  // #V*3
  double time_s = 0.0;
  Tool tool;
};
struct Work {
  std::vector<double> f, r, d, q, s, diag, kv;  // #V*3 each (diag: #V*3)
  std::vector<uint8_t> constrained;             // #V
};

State make_state(const Model& model);
Work make_work(const Model& model);

void pull_force(State& state, const std::vector<int32_t>& verts, const std::array<double, 3>& force_N);
void attach(State& state, const std::vector<int32_t>& verts, const std::array<double, 3>& offset_m, int iterations);
void release(State& state);

struct StepInfo {
  int cg_iterations = 0;
  double cg_residual = 0.0;
  double accel_sum = 0.0;  // sum |dv / dt| over free vertices (paper 000 stopping rule)
  bool finite = true;
};
// One implicit Euler step of dt_s. No allocation, no throw.
StepInfo step(const Model& model, State& state, Work& work, double dt_s);

// f = -K u (#V*3), u = x - rest.
void internal_forces(const Model& model, const std::vector<double>& x, std::vector<double>& f);
// Force the organ exerts on the tool: the internal forces on the picked vertices.
std::array<double, 3> tool_reaction(const Model& model, const State& state, Work& work);
// 1/2 u^T K u + 1/2 v^T M v.
double energy(const Model& model, const State& state, Work& work);
// Enclosed volume of the current surface (closed, outward-oriented meshes).
double volume(const Model& model, const std::vector<double>& x);

}  // namespace softatlas::sim::tmm
