// The solid model's prefactored system matrix (solid.hpp), shared by the step (solid_step.cpp)
// and the haptic linearisation of a hold (solid_hold.cpp). Private to sim/.
#pragma once

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>

namespace softatlas::sim {

struct SolidFactor {
  // A = M / h^2 + sum_e w_e G_e^T G_e (+ Rayleigh, + the anchors of fixed vertices): one scalar
  // #nnode x #nnode matrix for x, y and z (Bouaziz et al. 2014 eq 12)
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt;
  Eigen::VectorXd base_rhs;  // constant part of the right-hand side: anchors (#nnode*3, col-major)
};

}  // namespace softatlas::sim
