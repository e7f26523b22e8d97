// The accuracy reference (issue 13): quadratic (10-node) tetrahedra with a compressible
// neo-Hookean material, solved for static equilibrium by Newton's method with the consistent
// tangent and a backtracking line search.
//
// Why not the linear tetrahedra of fem.hpp: constant-strain tetrahedra lock in bending (the
// cantilever is 15-78 % too stiff at 1-5 cells through the thickness) and lock more as Poisson's
// ratio approaches 1/2; the corotational tangent without the derivative of R stalls on the 50 mm
// pull. Quadratic elements bend with a few cells and stay usable at nu = 0.49; the neo-Hookean
// energy has an exact tangent, so Newton converges quadratically, and the line search on the
// energy keeps every iterate uninverted.
//
//   fem::TetMesh mesh = ...;                                    // linear tetrahedra (corners)
//   fem::QuadraticModel q = fem::compile_quadratic(mesh, material);
//   fem::Load load = fem::make_load(q);                         // sized for corners + edge nodes
//   fem::fix_nodes(load, fem::quadratic_region(q, corners), {0, 0, 0});
//   std::vector<double> x = q.rest;
//   fem::StaticReport rep = fem::solve_static(q, load, x);
//
// Node numbering: the linear mesh's nodes keep their indices (corner nodes 0..nvertex-1); edge
// node nvertex + e sits at the rest midpoint of edge e. Units: SI. Static only (no dynamics).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "softatlas/sim/fem.hpp"

namespace softatlas::sim::fem {

struct QuadraticModel {
  Model linear;         // the corner mesh (tets reordered to positive volume)
  int32_t nvertex = 0;  // corner nodes
  int32_t nnode = 0;    // corners + edge nodes
  int32_t ntet = 0;
  std::vector<double> rest;          // #nnode*3
  std::vector<int32_t> tets;         // #T*10: corners 0..3 (as linear.tets), edges 01 02 03 12 13 23
  std::vector<int32_t> edge_ends;    // #E*2: the corner nodes of edge node nvertex + e
  std::vector<int32_t> edge_offset;  // #nvertex+1: CSR over the smaller corner of each edge
  std::vector<int32_t> edge_other;   //   the larger corner
  std::vector<int32_t> edge_id;      //   its edge node
  double lame_lambda = 0.0, lame_mu = 0.0;
};

// Same checks and reordering as compile() (InputError on degenerate tetrahedra, bad material);
// the material's elasticity field is ignored (always neo-Hookean).
QuadraticModel compile_quadratic(const TetMesh& mesh, const Material& material);

// Edge node between corners a and b, -1 if they share no edge.
int32_t edge_node(const QuadraticModel& q, int32_t a, int32_t b);
// The corners and every edge node whose two corners are both in `corners`: the nodes to fix
// or load for a region given by its corners.
std::vector<int32_t> quadratic_region(const QuadraticModel& q, const std::vector<int32_t>& corners);

Load make_load(const QuadraticModel& q);
// Consistent nodal forces of a uniform traction (Pa) on triangles of corner nodes (#F*3, e.g.
// from boundary_faces): for 6-node triangles the corners take 0 and each edge node 1/3 of the area.
void add_traction(const QuadraticModel& q, Load& load, const std::vector<int32_t>& faces,
                  const std::array<double, 3>& traction_pa);

// Compressible neo-Hookean strain energy density (Bonet & Wood, Nonlinear Continuum Mechanics,
// section 6.4.3), with J = det F and
// I_C = tr(F^T F):  W = mu/2 (I_C - 3) - mu ln J + lambda/2 (ln J)^2;
// the first Piola stress P = mu (F - F^-T) + lambda ln J F^-T. Small strain: linear elasticity
// with the same Lame coefficients. Integrated with the 4-point rule (degree 2).
// Elastic energy at x (#nnode*3); +inf if any quadrature point has J <= 0 (inverted).
double elastic_energy(const QuadraticModel& q, const std::vector<double>& x);
// Volume of the deformed body, the integral of J with the same rule.
double deformed_volume(const QuadraticModel& q, const std::vector<double>& x);
// Internal forces -dW/dx at x into f (#nnode*3, resized).
void internal_forces(const QuadraticModel& q, const std::vector<double>& x, std::vector<double>& f);
// y = K(x) v with K = d^2 W / dx^2 (the consistent tangent), all degrees of freedom.
void tangent_times(const QuadraticModel& q, const std::vector<double>& x, const std::vector<double>& v,
                   std::vector<double>& y);

// Static equilibrium f_int(x) + f_ext = 0 with the prescribed displacements reached in
// `load_steps` equal increments (forces scaled alike). Per increment, Newton: K dx = r - K_fc dc
// (dc: what is left of the prescribed increment), a backtracking line search that halves the
// step until no quadrature point inverts and, once the prescribed values are reached, the
// energy decreases (Armijo); an indefinite tangent is shifted until dx descends. Converged when
// |r| <= tolerance * max(|f_ext|, |reaction|).
StaticReport solve_static(const QuadraticModel& q, const Load& load, std::vector<double>& x,
                          const StaticOptions& options = {});

// Sum of internal forces on `nodes`: the force the body exerts on what holds them.
std::array<double, 3> reaction_force(const QuadraticModel& q, const std::vector<double>& x,
                                     const std::vector<int32_t>& nodes);

// Displacements of points embedded in the corner mesh (embed_points(q.linear, pts)), with the
// quadratic shape functions: N_a = L_a (2 L_a - 1) at corners, N_ab = 4 L_a L_b at edges.
void interpolate(const QuadraticModel& q, const Embedding& emb, const std::vector<double>& x, std::vector<double>& out);

}  // namespace softatlas::sim::fem
