// Meshes for the core's tests: closed-form shapes (icosphere, cube, plane) and a minimal OBJ
// reader so that the core's tests need nothing but Eigen (the product reads OBJ via assimp).
#pragma once

#include <string>
#include <vector>

#include "softatlas/sim/model.hpp"

namespace softatlas::test {

struct Mesh {
  std::vector<double> V;   // #V*3
  std::vector<int32_t> F;  // #F*3
};

Mesh icosphere(int subdivisions, double radius);   // level 2: 162 v / 320 f (paper 000 sphere)
Mesh cube(double side);                            // 8 v / 12 f, outward
Mesh plane_grid(int n, double size);               // n x n quads split in triangles, z = 0
Mesh read_obj(const std::string& path);            // v / f lines only
std::string shared_data(const std::string& rel);   // SOFTATLAS_SHARED_DATA/rel
std::string project_data(const std::string& rel);  // SOFTATLAS_SOURCE_DIR/data/rel

sim::OrganDesc organ(const std::string& name, const Mesh& mesh, double scale = 1.0);

}  // namespace softatlas::test
