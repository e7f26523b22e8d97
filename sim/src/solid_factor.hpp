// The solid model's prefactored system matrix (solid.hpp), shared by the step (solid_step.cpp)
// and the haptic linearisation of a hold (solid_hold.cpp). Private to sim/.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>

namespace softatlas::sim {

struct SolidFactor {
  // A = M / h^2 + sum_e w_e G_e^T G_e (+ Rayleigh, + the anchors of fixed vertices): one scalar
  // #nnode x #nnode matrix for x, y and z (Bouaziz et al. 2014 eq 12)
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt;
  Eigen::VectorXd base_rhs;  // constant part of the right-hand side: anchors (#nnode*3, col-major)
};

struct SolidBody;

// The exact constraints of holding organ-local vertices `local` (each embedded in a tetrahedron):
// Z = A^-1 C^T (#nnode x k) and the lower Cholesky factor L of S = C Z, S regularised by 1e-10 of
// its largest diagonal entry (more held vertices than free nodes make S singular; with
// consistent targets the multipliers' sum stays exact). False if S could not be factorised.
// Used by the step (solid_step.cpp) and the haptic linearisation (solid_hold.cpp).
bool grasp_schur(const SolidBody& body, const std::vector<int32_t>& local, Eigen::MatrixXd& Z, Eigen::MatrixXd& L);

}  // namespace softatlas::sim
