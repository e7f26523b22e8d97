// Meshes for the evidence: surfaces read from disk, remeshed to exact face counts, and
// tetrahedralised for the FEM reference. CGAL lives in one translation unit (meshing_cgal.cpp)
// because it compiles slowly.
#pragma once

#include <array>

#include <cstdint>
#include <string>
#include <vector>

#include "softatlas/sim/fem.hpp"

namespace softatlas::evidence {

// A triangle surface: V #V*3 row-major, F #F*3.
struct TriMesh {
  std::vector<double> V;
  std::vector<int32_t> F;
  int32_t nvert() const { return static_cast<int32_t>(V.size() / 3); }
  int32_t nface() const { return static_cast<int32_t>(F.size() / 3); }
};

// Reads OBJ / OFF / PLY / STL (CGAL), merges duplicate vertices, drops unused ones.
// Throws InputError(path, ...) if the file is missing or holds no triangles.
TriMesh read_surface(const std::string& path);

// Isotropic remeshing (CGAL) to slightly more than `faces` faces, then edge collapse
// (Lindstrom-Turk) down to exactly `faces` faces. The input must be closed and manifold; the
// result is closed, genus as the input, outward oriented. Throws InputError if it is not.
TriMesh remesh_to_faces(const TriMesh& surface, int faces);

// Local refinement of a tetrahedralisation: cells of `size` within `radius` of `centre`, growing
// by `grade` per unit of distance beyond it up to the mesh's cell size (surface units).
struct RefineFocus {
  std::array<double, 3> centre{0, 0, 0};
  double radius = 0.0, size = 0.0, grade = 0.5;
};

// Tetrahedral mesh of the volume bounded by a closed surface (CGAL Mesh_3, polyhedral domain):
// cell size and facet distance in the surface's units, optionally refined around a focus (the
// tool of a displacement load, whose edge is a stress singularity). Deterministic (fixed seed).
sim::fem::TetMesh tetrahedralize(const TriMesh& surface, double cell_size, double facet_distance,
                                 const RefineFocus* focus = nullptr);

}  // namespace softatlas::evidence
