// Stage 4, repair and remesh (CGAL): closed, manifold, self-intersection free, simplified to
// the face budget: isotropic, refined where that rounds off a thin tip or rim (two-level
// sizing, then a Garland-Heckbert seeded remesh); volume restored to the reference.
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
  // Shape bound: when the isotropic mesh is further than this from the input (symmetric
  // Hausdorff), refined candidates are tried; one replaces it only if closer at the same
  // triangle quality (RemeshResult::simplification says which). 0 = isotropic only.
  double max_hausdorff_mm = 0.0;
  // Volume to give the final surface back (the label's voxel volume): smoothing, the staircase
  // chamfer of flying edges and remeshing all shrink a surface, thin ones most. The surface is
  // offset along its normals, per vertex, capped by the distance to its other side, until within
  // 0.5 %, by at most max_offset_mm in all at any vertex. 0 = keep the volume as it comes out.
  double target_volume_mm3 = 0.0;
  double max_offset_mm = 0.0;
};

struct RemeshResult {
  io::TriMesh mesh;
  std::vector<std::string> repairs;  // what was done: stitch, holes_filled:N, alpha_wrap, ...
  bool self_intersections = false;   // of the final mesh
  double hausdorff_mm = 0.0;         // symmetric, vertex-sampled, to the input surface
  double mean_distance_mm = 0.0;     // mean of the two one-sided vertex distances
  double target_edge_mm = 0.0;
  std::string simplification = "isotropic";  // or "isotropic_two_level", "garland_heckbert+isotropic"
  double isotropic_hausdorff_mm = 0.0;       // what the isotropic route reached
  double volume_offset_mm = 0.0;             // area-weighted mean normal offset that restored the volume
  double volume_offset_max_mm = 0.0;         // its largest value at one vertex (signed)
};

// Throws InputError naming `where` if the budget is below what a closed surface of the input's
// components can have, or if the input cannot be made into a closed surface.
RemeshResult repair_and_remesh(const io::TriMesh& input, const RemeshOptions& options, const std::string& where);

// One-sided distances from the vertices of `from` to the surface `to` (AABB tree): max and mean.
void surface_distance(const io::TriMesh& from, const io::TriMesh& to, double* max_mm, double* mean_mm);

}  // namespace softatlas::pipeline
