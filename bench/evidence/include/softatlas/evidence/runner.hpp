// One interface over every model the evidence compares: the core's models (tmsm, cmsm, nmsm,
// flexion, and the volumetric solid; sim.hpp), the triangular tensor-mass model (tmm.hpp) and the
// tetrahedral FEM (fem.hpp). A virtual call per step, none per spring.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "softatlas/evidence/meshing.hpp"
#include "softatlas/sim/fem.hpp"

namespace softatlas::evidence {

// Model and setting of one run. Names are those of results.json.
struct ModelSpec {
  std::string model = "nmsm";                // tmsm | cmsm | nmsm | nmsm_p2 | flexion | solid | tmm | fem
  std::string integrator = "semi_implicit";  // verlet | semi_implicit | implicit (tmm, fem: implicit)
  double dt_s = 1e-3;
  bool guard = true;
  // mass-spring material (paper 000 eqs 8-10, paper 003), SI
  double young_modulus_pa = 4000.0;
  double thickness_m = 1e-3;
  double total_mass_kg = 0.0;  // 0: density * enclosed volume
  double density_kg_m3 = 1060.0;
  double stiffness = 0.0;  // > 0: uniform spring k (N/m) instead of eq 9
  double damping = -1.0;   // >= 0: uniform d instead of eq 10
  double damping_scale = 1.0;
  double vertex_mass_kg = 0.0;
  double elastica_a = 1.0, elastica_b = 0.1;
  int elastica_p = 1;
  double curvature_unit_m = 1e-3;
  double tau_s = -1.0, tau_c = -1.0;
  int compensation_iterations = 4;
  double flexion_stiffness = 0.0, volume_stiffness = 0.0;
  int cg_iterations = 25;
  double max_tool_force_N = 10.0;
  int max_substeps = 64;
  // tensor-mass and FEM
  double poisson_ratio = 0.45;
  double rayleigh_mass = 0.1, rayleigh_stiffness = 0.01;
};

// The paper's settings for a model name (paper 000 section III; paper 003 for flexion):
// cmsm tau_s = tau_c = 0.01; nmsm a = 1, b from Table III by face count, p = 1 (nmsm_p2: p = 2);
// flexion: flexion springs + volume constraint.
ModelSpec paper_spec(const std::string& model, const std::string& integrator, int faces);
// b of paper 000 Tables II/III for a liver of `faces` faces.
double paper_b(int faces);

struct StepOut {
  bool finite = true;
  bool guard_acted = false;  // sub-stepped, fell back to implicit, restored, or clamped a force
  double accel_sum = 0.0;    // paper 000 stopping rule
};

class Simulation {
 public:
  virtual ~Simulation() = default;
  // Vertex indices are those of the surface the simulation was made from.
  virtual void pull(const std::vector<int32_t>& verts, const std::array<double, 3>& force_N) = 0;
  virtual void attach(const std::vector<int32_t>& verts, const std::array<double, 3>& offset_m, int iterations) = 0;
  virtual void release() = 0;
  // Moves every free vertex (node) by `amplitude_m` in a random direction (seeded): the start of
  // the "unloaded perturbed rest" cells that catch self-excitation.
  virtual void perturb(double amplitude_m, uint32_t seed) = 0;
  virtual StepOut step() = 0;
  virtual void positions(std::vector<double>& out) const = 0;  // #V*3 in surface order
  virtual double volume() const = 0;
  virtual std::array<double, 3> reaction() = 0;  // force the organ exerts on the tool
  virtual double energy() const = 0;
  virtual double stable_dt() const { return 0.0; }  // 0 = not estimated
  virtual std::string plan() const { return ""; }
};

// Mass-spring or tensor-mass model of a surface (metres); fixed vertices held in place.
// Throws InputError for invalid meshes or parameters (the compilers' checks).
std::unique_ptr<Simulation> make_surface_simulation(const TriMesh& surface, const std::vector<int32_t>& fixed,
                                                    const ModelSpec& spec);

// FEM dynamics (implicit Euler) on a tetrahedral mesh; its "surface" is the boundary, whose
// vertex i is tet node boundary_nodes[i]. `fixed` are tet node indices.
std::unique_ptr<Simulation> make_fem_simulation(const sim::fem::TetMesh& mesh, const std::vector<int32_t>& fixed,
                                                const ModelSpec& spec, TriMesh& boundary,
                                                std::vector<int32_t>& boundary_nodes);

}  // namespace softatlas::evidence
