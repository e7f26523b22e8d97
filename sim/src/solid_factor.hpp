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

// The rows of a hold on organ-local vertices `local` (each embedded in a tetrahedron): one per
// lattice tetrahedron that holds some of them, constraining their mean position. row[j] is vertex
// j's row, share[j] = 1 / (vertices in that row).
GraspRows grasp_rows(const SolidBody& body, const std::vector<int32_t>& local);
// The exact constraints of those rows: Z = A^-1 C^T (#nnode x rows) and the lower Cholesky factor
// L of S = C Z, S regularised by 1e-10 of its largest diagonal entry (more rows than free nodes
// make S singular; with consistent targets the multipliers' sum stays exact). False if S could not
// be factorised. Used by the step (solid_step.cpp) and the haptic linearisation (solid_hold.cpp).
bool grasp_schur(const SolidBody& body, const std::vector<int32_t>& local, const GraspRows& rows, Eigen::MatrixXd& Z,
                 Eigen::MatrixXd& L);

}  // namespace softatlas::sim
