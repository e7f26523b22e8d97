// The solid organ model (material `model: solid`): a coarse volumetric lattice of tetrahedra
// inside each organ's closed surface, the surface vertices embedded in it by barycentric weights,
// corotational linear elasticity solved by projective dynamics with a prefactored system matrix.
//
//   lattice    body of regular cells (6 Kuhn tetrahedra each) covering the inside of the surface;
//              cells cut by the surface keep the fraction of their volume that lies inside as a
//              weight on mass and stiffness (composite elements, Nesme et al. 2009); spacing
//              from the organ's volume and a node budget (solid_lattice.cpp)
//   energy     per tetrahedron mu |F - R|^2, R the rotation of F (corotational elasticity, Mueller &
//              Gross 2004); per lattice cell 3 lambda / 2 t^2 with F_c the cell's mean deformation
//              gradient (its 6 tetrahedra) and t the shift with det(R_c^T F_c + t I) = 1: an exact
//              volume projection on the cell, not on each tetrahedron (mean dilatation, as Q1/P0
//              hexahedra: 6 volume constraints per node locked the lattice, which then inverted
//              under a pull); the two projective-dynamics constraints of Bouaziz et al. 2014
//   damping    Rayleigh stiffness-proportional damping beta K with beta = 2 zeta / omega_1, zeta
//              the material's damping ratio at the organ's lowest shear mode omega_1, written in the
//              rotated frame so that rigid motion is not damped
//   step       implicit Euler as a minimisation (Liu et al. 2013, Bouaziz et al. 2014): a few
//              local (rotation fits) / global (one prefactored sparse solve, Eigen SimplicialLDLT)
//              iterations; fixed vertices are stiff zero-length anchors in the matrix; the vertices the
//              tool holds are exact constraints, one per lattice tetrahedron on their mean, through a
//              Schur complement on the prefactored matrix, whose multipliers are the tool's
//              reaction force (solid_step.cpp)
//
// Units SI. Everything allocated by compile_solids() and make_solid_work(); solid_step() does not
// allocate except the first time the tool grasps a new set of vertices of a solid organ.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "softatlas/sim/fem.hpp"

namespace softatlas::sim {

// The lattice of one closed surface (vertices #V*3, faces #F*3, outward or inward oriented).
struct SolidLattice {
  fem::TetMesh mesh;                 // nodes and positive tetrahedra
  std::vector<double> tet_fraction;  // #tets: inside fraction of the tetrahedron's cell (0, 1]
                                     // (tetrahedra 6c .. 6c + 5 are cell c's)
  std::vector<int32_t> embed_tet;    // #V: tetrahedron holding each surface vertex (-1: unused)
  std::vector<double> embed_w;       // #V*4 barycentric weights
  double spacing_m = 0.0;
};
// Cells of size spacing_m; a cell is kept when part of it lies inside the surface (27 samples,
// ray parity along x) or a surface vertex lies in it. Throws InputError when the surface has no
// extent or the spacing is not positive.
SolidLattice solid_lattice(const std::vector<double>& vertices, const std::vector<int32_t>& faces, double spacing_m);
// The spacing whose lattice has at most about `node_budget` nodes (>= 8).
SolidLattice solid_lattice_budget(const std::vector<double>& vertices, const std::vector<int32_t>& faces,
                                  int node_budget);

struct Model;
struct State;
struct Work;
struct SceneDesc;

struct SolidFactor;  // the prefactored system matrix (Eigen, solid_step.cpp)

// The constraint rows of a hold (solid_factor.hpp grasp_rows): one per lattice tetrahedron holding
// grasped vertices, on their mean position.
struct GraspRows {
  int32_t rows = 0;
  std::vector<int32_t> row;   // per held vertex: its row (-1: at an anchor, not held; grasp_rows)
  std::vector<double> share;  // per held vertex: 1 / (held vertices of its row), 0 without a row
};

// One compiled solid organ.
struct SolidBody {
  int32_t organ = 0;       // compiled organ index
  int32_t node_begin = 0;  // first node in State::solid_x / solid_v (#nodes * 3 doubles)
  int32_t nnode = 0, ntet = 0;
  double spacing_m = 0.0;                 // lattice cell size
  std::vector<double> rest;               // #nnode * 3
  std::vector<double> mass;               // #nnode, kg (sums to the organ's mass)
  std::vector<int32_t> tets;              // #ntet * 4 local node indices (positive volume)
  std::vector<double> grad;               // #ntet * 12: gradient g_i of each node's shape function
  std::vector<double> w_strain;           // #ntet: 2 mu V f (f = inside fraction of the cell)
  int32_t ncell = 0;                      // lattice cells (ntet / 6)
  std::vector<double> w_volume;           // #ncell: 3 lambda V_cell f (the cell's volume constraint)
  std::vector<int32_t> cell_nodes;        // #ncell * 8 its nodes
  std::vector<double> cell_grad;          // #ncell * 24: gradient of F_c = sum_j x_j g_j^T per node
  std::vector<int32_t> embed_tet;         // per organ vertex (v - vert_begin): tetrahedron
  std::vector<double> embed_w;            // per organ vertex * 4: barycentric weights
  int32_t npiece = 0;                     // closed pieces of the surface with a volume constraint (<= 8)
  std::vector<int32_t> vert_piece;        // per organ vertex: its piece (-1: none)
  std::vector<double> piece_rest_volume;  // #npiece, m^3 (signed, as the faces are oriented)
  int32_t nfixed = 0;                     // fixed surface vertices (anchors in the matrix)
  std::vector<uint8_t> node_anchored;     // #nnode: node of a tetrahedron holding a fixed vertex
  double anchor_weight = 0.0;             // N/m of each anchor
  double young_modulus_pa = 0.0, poisson_ratio = 0.0, damping_ratio = 0.0;
  double omega1_rad_s = 0.0;  // lowest shear mode estimate
  double beta_s = 0.0;        // Rayleigh stiffness coefficient
  double dt_s = 0.0;          // the factor is built for this step
  int iterations = 0;         // local/global iterations per step
  std::shared_ptr<const SolidFactor> factor;
};

// Per solid organ scratch (copyable; no Eigen types in this header).
struct SolidWork {
  std::vector<double> q;          // #nnode * 3 current iterate (row-major)
  std::vector<double> s;          // inertial prediction
  std::vector<double> rhs;        // #nnode * 3
  std::vector<double> sol;        // #nnode * 3 (column-major scratch for the solver)
  std::vector<double> quat;       // #ntet * 4 warm start of the rotation fits (w, x, y, z)
  std::vector<double> rot;        // #ntet * 9 its rotation matrix (column-major)
  std::vector<double> f_prev;     // #ntet * 9 deformation gradient at the start of the step
  std::vector<double> r_prev;     // #ntet * 9 its rotation
  std::vector<double> cell_quat;  // #ncell * 4, #ncell * 9: the cells' rotation fits, as quat / rot
  std::vector<double> cell_rot;
  std::vector<double> fext;  // #nnode * 3 external nodal forces of this step
  // the pieces' volume constraints: surface positions and volume gradient (#organ vertices * 3, x
  // block then y then z), the gradients on the nodes (#npiece * #nnode * 3), their responses
  // U = A^-1 G (#nnode x 3 #npiece, column-major), the grasp's share of them (k x 3 #npiece)
  std::vector<double> vol_p, vol_g, vol_gn, vol_u, vol_res;
  // the tool's exact constraints (k = grasp.rows): grasped vertices, their rows, Z = A^-1 C^T
  // (#nnode x k, column-major), Cholesky factor of S = C Z (k x k), multipliers and targets (k * 3)
  std::vector<int32_t> grasp_verts;
  GraspRows grasp;
  std::vector<double> grasp_z, grasp_chol, grasp_lambda, grasp_target, grasp_rhs;
  // this step: awake, grasp rows held by the tool (0: none); results of the organ's solve
  int thread = 0;  // worker thread that solves this organ
  bool active = false;
  int32_t grasp_active = 0;
  double out_reaction[3] = {0, 0, 0}, out_max_speed2 = 0.0, out_checksum = 0.0;
};

// Builds every organ whose material model is solid (after the rest of compile()).
void compile_solids(const SceneDesc& scene, Model& model);
// Rest nodes, zero velocities.
void init_solid_state(const Model& model, State& state);
std::vector<SolidWork> make_solid_work(const Model& model);
// True when vertex v belongs to a solid organ (the surface integrators leave it alone).
bool solid_vertex(const Model& model, int32_t v);

struct SolidStats {
  double max_speed2 = 0.0;  // surface vertices, (m/s)^2
  double checksum = 0.0;    // finite unless something went wrong
  bool reaction = false;    // the tool holds a solid organ: reaction_N was set
};
// Advances every awake solid organ by model.dt_s and writes its surface vertices' positions and
// velocities; external loads: the tool (force or attachment, targets in work.tool_target), the
// connection springs (implicit on this organ's side, the other end at its start-of-step state),
// gravity. Organs run in parallel on work.workers when the model has threads > 1. The grasp's
// S = C A^-1 C^T uses the step's own matrix A (connections and anchors included), so
// 1^T S^-1 1 is the grasp's one-step stiffness; grasp_lambda holds the last iteration's multipliers.
SolidStats solid_step(const Model& model, State& state, Work& work);

// The organ's surface vertices (positions and velocities in the state) from its lattice nodes;
// returns their largest squared speed. After the solve, and after contact moved the nodes.
double solid_surface_update(const Model& model, const SolidBody& body, State& state);

// After contact moved some of the organ's nodes (node_acc[4 g + 3] > 0 for global node g, as
// contact.cpp accumulates them): each closed piece's volume given back by the nodes contact left
// alone, one mass-weighted projection (003 eq 25 with eqs 27-30 on the embedded surface), positions
// only (like contact's own correction); an organ pressed flat against its neighbour bulges
// elsewhere, as tissue does.
void solid_restore_volume(const Model& model, const SolidBody& body, SolidWork& work, State& state,
                          const double* node_acc);

// One line for the compiled plan (explain): lattice size, material, damping, iterations.
std::string solid_plan(const SolidBody& body);

// Elastic energy of the solid organs plus the kinetic energy of their nodes (J).
double solid_energy(const Model& model, const State& state);

}  // namespace softatlas::sim
