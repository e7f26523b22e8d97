// Tetrahedral finite elements: the reference solution that the surface models are measured
// against (issue 7). Linear (small-strain) and corotational elasticity on linear tetrahedra,
// static equilibrium (Newton with load steps) and dynamics (implicit Euler, Rayleigh damping).
//
// This is a reference solver, not a real-time one: it allocates, factorises sparse matrices
// (Eigen SimplicialLDLT) and favours clarity over speed. Units: SI (m, kg, s, N, Pa).
//
//   TetMesh mesh = read_gmsh("liver.msh");           // or box_mesh(...)
//   fem::Model model = fem::compile(mesh, material);  // InputError on degenerate tetrahedra
//   fem::Load load = fem::make_load(model);           // forces + prescribed displacements
//   std::vector<double> x = model.rest;
//   fem::solve_static(model, load, x);
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace softatlas::sim::fem {

// Linear tetrahedra. nodes: #N*3 (row-major), tets: #T*4 node indices.
struct TetMesh {
  std::vector<double> nodes;
  std::vector<int32_t> tets;
  int32_t nnode() const { return static_cast<int32_t>(nodes.size() / 3); }
  int32_t ntet() const { return static_cast<int32_t>(tets.size() / 4); }
};

// Gmsh ASCII meshes, format 1 ($NOD/$ELM) and 2 ($MeshFormat/$Nodes/$Elements). Keeps the
// 4-node tetrahedra (element type 4), ignores other element types, renumbers nodes densely in
// file order and drops nodes that no tetrahedron uses. `scale` multiplies coordinates (file
// units to metres). Throws InputError("file:line", ...) on malformed input.
TetMesh read_gmsh(const std::string& path, double scale = 1.0);

// Box [0,lx] x [0,ly] x [0,lz] cut into nx*ny*nz cells of 6 tetrahedra each (Kuhn subdivision:
// every cell is split along the same main diagonal, so neighbouring cells conform).
TetMesh box_mesh(double lx, double ly, double lz, int nx, int ny, int nz);

// Boundary triangles (faces that belong to exactly one tetrahedron), oriented outward. #F*3.
std::vector<int32_t> boundary_faces(const TetMesh& mesh);

// Sum of tetrahedron volumes of positions x (#N*3) (signed, positive for positive tets).
double mesh_volume(const TetMesh& mesh, const std::vector<double>& x);

enum class Elasticity : int32_t {
  linear = 0,        // small strain: f = -K (x - X); not rotation invariant
  corotational = 1,  // per-tet rotation R from the polar decomposition of F (Mueller & Gross 2004)
};
const char* to_string(Elasticity e);

struct Material {
  double young_modulus_pa = 4000.0;
  double poisson_ratio = 0.45;
  double density_kg_m3 = 1060.0;
  Elasticity elasticity = Elasticity::corotational;
  double rayleigh_mass = 0.0;  // C = alpha M + beta K (dynamics only)
  double rayleigh_stiffness = 0.0;
};

// Everything fixed after compile: rest positions, per-tet shape gradients and stiffness blocks.
struct Model {
  int32_t nnode = 0, ntet = 0;
  std::vector<double> rest;           // #N*3
  std::vector<int32_t> tets;          // #T*4, reordered so that every rest volume is positive
  std::vector<double> tet_volume;     // #T
  std::vector<double> tet_dm_inv;     // #T*9 row-major inverse of Dm = [X1-X0 X2-X0 X3-X0]
  std::vector<double> tet_stiffness;  // #T*144, 12x12 row-major element stiffness (rest frame)
  std::vector<double> node_mass;      // #N lumped: density * V / 4 per tet
  Material material;
  double lame_lambda = 0.0, lame_mu = 0.0;
};

// Lame coefficients from E and nu (3-D): lambda = E nu / ((1 + nu)(1 - 2 nu)), mu = E / (2 (1 + nu)).
void lame(double young_modulus, double poisson_ratio, double& lambda, double& mu);

// Throws InputError("tetrahedral mesh: ...") for an empty mesh, bad indices, non-finite
// coordinates, degenerate (zero-volume) tetrahedra, E <= 0, nu outside (-1, 0.5), density <= 0.
Model compile(const TetMesh& mesh, const Material& material);

// The load: nodal forces and prescribed displacements (Dirichlet, per degree of freedom).
struct Load {
  std::vector<double> force;       // #N*3, N
  std::vector<uint8_t> dof_fixed;  // #N*3, 1 = prescribed
  std::vector<double> dof_disp;    // #N*3, prescribed displacement from rest (m)
};
Load make_load(const Model& model);  // no force, nothing fixed
// Fixes all three DOFs of `nodes` at displacement `disp_m`.
void fix_nodes(Load& load, const std::vector<int32_t>& nodes, const std::array<double, 3>& disp_m);
// Adds a total force split evenly over `nodes`.
void add_force(Load& load, const std::vector<int32_t>& nodes, const std::array<double, 3>& force_N);

// Internal elastic forces at positions x (#N*3) into f (#N*3, resized).
void internal_forces(const Model& model, const std::vector<double>& x, std::vector<double>& f);

struct StaticOptions {
  int load_steps = 1;       // corotational: apply the load in this many equal increments
  int max_iterations = 60;  // Newton iterations per increment
  double tolerance = 1e-9;  // |residual| / (|load| + tiny) and |dx| / size
  // Called after each increment with its load fraction (s / load_steps) and the positions: the
  // quasi-static load path, for comparisons along it rather than at its end only.
  std::function<void(double fraction, const std::vector<double>& x)> on_increment;
};
struct StaticReport {
  int iterations = 0;
  double residual = 0.0;  // relative residual at the end
  bool converged = false;
};
// Static equilibrium f_int(x) + f_ext = 0 with the prescribed displacements. x holds the start
// positions (usually model.rest) and receives the solution. Linear: one sparse solve.
// Corotational: Newton with the rotated stiffness R K R^T as tangent (the derivative of R is
// left out, which makes the convergence linear but robust).
StaticReport solve_static(const Model& model, const Load& load, std::vector<double>& x,
                          const StaticOptions& options = {});

struct State {
  std::vector<double> x, v;  // #N*3
  double time_s = 0.0;
};
State make_state(const Model& model);
// One backward Euler step linearised at x (Baraff & Witkin 1998):
//   (M + h C + h^2 K) dv = h (f_ext + f_int(x) - C v - h K v),  C = alpha M + beta K,
// then v += dv, x += h v. Prescribed DOFs are set to their target with zero velocity.
void step_implicit(const Model& model, const Load& load, State& state, double dt_s);

// Sum of internal forces on `nodes` at positions x: the force the body exerts on whatever holds
// these nodes (for a pulled region at equilibrium it equals minus the applied force).
std::array<double, 3> reaction_force(const Model& model, const std::vector<double>& x,
                                     const std::vector<int32_t>& nodes);

// Elastic energy at x (linear: 1/2 u^T K u; corotational: per tet 1/2 u_R^T K u_R) plus
// kinetic energy of v (v may be empty).
double energy(const Model& model, const std::vector<double>& x, const std::vector<double>& v);

// Points embedded in the tetrahedra: tet index and barycentric weights, for reading the FEM
// displacement at the vertices of a different (surface) mesh. Points outside the mesh take the
// tetrahedron whose smallest barycentric weight is largest (nearest, weights clamped and
// renormalised). pts: #P*3.
struct Embedding {
  std::vector<int32_t> tet;      // #P
  std::vector<double> weight;    // #P*4
  std::vector<double> distance;  // #P, 0 inside, else distance to the clamped point (m)
};
Embedding embed_points(const Model& model, const std::vector<double>& pts);
// Displacements (from rest) of the embedded points for FEM positions x: out #P*3.
void interpolate(const Model& model, const Embedding& emb, const std::vector<double>& x, std::vector<double>& out);

}  // namespace softatlas::sim::fem
