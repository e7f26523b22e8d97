// Stage 4, repair and remesh (CGAL): closed, manifold, self-intersection free, isotropic,
// simplified to the face budget.
#pragma once

#include <string>
#include <vector>

#include "softatlas/io/mesh_io.hpp"

namespace softatlas::pipeline {

struct RemeshOptions {
  int face_budget = 1000;
  double budget_tolerance = 0.02;  // the contract: within 2 % of the budget
  int remesh_iterations = 5;       // CGAL isotropic_remeshing iterations per attempt
  int relaxation_iterations = 3;   // tangential relaxation after the collapse to the budget
  double wrap_alpha_mm = 0.0;      // alpha-wrap fallback; 0 = 2 % of the bounding-box diagonal
  bool allow_hole_filling = true;
  // Closed input that only touches itself is remeshed first (label surfaces); the final mesh is
  // always checked for self-intersections.
  bool tolerate_self_contact = true;
};

struct RemeshResult {
  io::TriMesh mesh;
  std::vector<std::string> repairs;  // what was done: stitch, holes_filled:N, alpha_wrap, ...
  bool self_intersections = false;   // of the final mesh
  double hausdorff_mm = 0.0;         // symmetric, vertex-sampled, to the input surface
  double mean_distance_mm = 0.0;     // mean of the two one-sided vertex distances
  double target_edge_mm = 0.0;
};

// Throws InputError naming `where` if the budget is below what a closed surface of the input's
// components can have, or if the input cannot be made into a closed surface.
RemeshResult repair_and_remesh(const io::TriMesh& input, const RemeshOptions& options,
                               const std::string& where);

// One-sided distances from the vertices of `from` to the surface `to` (AABB tree): max and mean.
void surface_distance(const io::TriMesh& from, const io::TriMesh& to, double* max_mm,
                      double* mean_mm);

}  // namespace softatlas::pipeline
