// What the two FEM translation units share (fem.cpp: linear tetrahedra; fem_quadratic.cpp:
// quadratic ones): Eigen's dense and sparse headers, 3-vector names, a node's position, the size of
// a point set. Each file's anonymous namespace says `using namespace detail;`.
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
#include <cstdint>
#include <vector>

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

}  // namespace softatlas::sim::fem::detail
