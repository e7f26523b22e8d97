// Plain checks of a triangle surface, independent of VTK and CGAL (used by check and the tests).
#pragma once

#include <string>

#include "softatlas/io/mesh_io.hpp"

namespace softatlas::pipeline {

struct SurfaceReport {
  size_t faces = 0;
  size_t vertices = 0;
  size_t boundary_edges = 0;     // edges with one face
  size_t nonmanifold_edges = 0;  // edges with three or more faces
  size_t misoriented_edges = 0;  // two faces traversing the edge in the same direction
  size_t components = 0;
  int genus = 0;                   // sum over components of (2 - chi) / 2 when closed
  double signed_volume_mm3 = 0.0;  // > 0 for outward normals
  double area_mm2 = 0.0;
  double min_angle_deg = 0.0;
  double share_angle_ge_20 = 0.0;  // fraction of triangles whose smallest angle is >= 20 deg
  bool closed() const { return boundary_edges == 0 && nonmanifold_edges == 0; }
  bool edge_manifold() const { return nonmanifold_edges == 0; }
  bool oriented() const { return misoriented_edges == 0; }
  bool outward() const { return signed_volume_mm3 > 0.0; }
};

SurfaceReport inspect_surface(const io::TriMesh& mesh);

// Connected components of faces (sharing an edge); returns per-face component id and count.
std::vector<int> face_components(const io::TriMesh& mesh, int* count);

// Keeps only the faces whose flag is set and drops unused vertices.
io::TriMesh select_faces(const io::TriMesh& mesh, const std::vector<char>& keep);

}  // namespace softatlas::pipeline
