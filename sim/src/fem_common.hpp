// What the two FEM translation units share (fem.cpp: linear tetrahedra; fem_quadratic.cpp:
// quadratic ones): Eigen's dense and sparse headers, 3-vector names, a node's position, the size of
// a point set, an empty load, a force summed over nodes. Each file's anonymous namespace says `using namespace detail;`.
#pragma once

// GCC 12 reports false "may be used uninitialized" warnings inside Eigen's AVX-512 kernels
// (-march=native); they are in the library headers, not in the FEM files.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"
#endif
#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif
#include <algorithm>
#include <array>
#include <cstdint>
#include <vector>

#include "softatlas/sim/fem.hpp"

namespace softatlas::sim::fem::detail {

using Mat3 = Eigen::Matrix3d;
using Vec3 = Eigen::Vector3d;

inline Eigen::Vector3d node(const std::vector<double>& x, int32_t i) {
  return Eigen::Vector3d(x[3 * i], x[3 * i + 1], x[3 * i + 2]);
}

// Diagonal of the bounding box of x (#N*3); 1 for an empty set: the scale of the tolerances.
inline double box_size(const std::vector<double>& x) {
  if (x.empty()) return 1.0;
  Eigen::Vector3d lo = node(x, 0), hi = lo;
  for (size_t i = 0; i < x.size() / 3; ++i) {
    lo = lo.cwiseMin(node(x, static_cast<int32_t>(i)));
    hi = hi.cwiseMax(node(x, static_cast<int32_t>(i)));
  }
  return std::max((hi - lo).norm(), 1e-300);
}

// A load on `nnode` nodes with no force and no fixed degree of freedom.
inline Load empty_load(int32_t nnode) {
  Load l;
  l.force.assign(3 * static_cast<size_t>(nnode), 0.0);
  l.dof_fixed.assign(3 * static_cast<size_t>(nnode), 0);
  l.dof_disp.assign(3 * static_cast<size_t>(nnode), 0.0);
  return l;
}

// The sum of the nodal vectors f (#N*3) over `nodes` (a reaction force from the internal forces).
inline std::array<double, 3> node_sum(const std::vector<double>& f, const std::vector<int32_t>& nodes) {
  std::array<double, 3> r{0, 0, 0};
  for (int32_t n : nodes)
    for (int c = 0; c < 3; ++c) r[c] += f[3 * static_cast<size_t>(n) + c];
  return r;
}

}  // namespace softatlas::sim::fem::detail
