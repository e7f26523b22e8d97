// The organs, supports and loads of the evidence, and the measurements taken on a run.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "softatlas/evidence/meshing.hpp"
#include "softatlas/evidence/runner.hpp"

namespace softatlas::evidence {

// Support and tool region of the liver: the lowest 15% of the height is held; tools act within
// 12 mm of the top vertex (paper 000 pulls "the top surface" and does not say how the liver is held).
constexpr double kSupportFraction = 0.15;
constexpr double kToolRadius = 0.012;

// Icosphere: icosahedron subdivided `level` times on a sphere of `radius` (level 2: the paper's
// 162 vertices / 320 faces sphere).
TriMesh icosphere(int level, double radius);

// The liver of the evidence: a closed surface centred at the origin, scaled so its largest
// extent is `size_m` (paper 000: 170 x 140 x 160 mm), +y up (the SOFA scenes' convention).
TriMesh normalise_organ(const TriMesh& in, double size_m);
double enclosed_volume(const TriMesh& m);

// Support: vertices below the lowest `fraction` of the height (y), held in place.
std::vector<int32_t> support_vertices(const std::vector<double>& V, double fraction);
// Vertices within `radius` of p (at least the nearest one).
std::vector<int32_t> region(const std::vector<double>& V, const std::array<double, 3>& p, double radius);
// The three vertices of the face whose centroid is nearest to p.
std::vector<int32_t> nearest_face(const TriMesh& m, const std::array<double, 3>& p);
std::array<double, 3> top_point(const TriMesh& m);  // the vertex with the largest y

struct LoadCase {
  std::string name;     // results.json "load"
  bool attach = false;  // false: force pulling (N); true: position attachment (m)
  std::array<double, 3> value{0, 0, 0};
  int attach_iterations = 30;  // paper 000 Table II
};
// The loads of the accuracy sweep: paper 000 Table I forces, Table II displacements, a 50 mm pull.
std::vector<LoadCase> accuracy_loads(bool quick);

// Position error against reference displacements (#V*3, from rest): RMS and max in mm.
void position_error_mm(const std::vector<double>& rest, const std::vector<double>& x,
                       const std::vector<double>& ref_disp, double& rms_mm, double& max_mm);

// Paper 003 Table 1: mean and standard deviation of |x0 - x_inf| (mm) over the vertices.
void restoration_mm(const std::vector<double>& rest, const std::vector<double>& x, double& mean_mm, double& sd_mm);

// Degraded copies of a good mesh with the same topology (stability sweep): "good", "sliver",
// "short_edge" (near-zero edges), "flipped" (folded-over triangle fans).
TriMesh degrade(const TriMesh& good, const std::string& kind);

double norm3(const std::array<double, 3>& v);

}  // namespace softatlas::evidence
