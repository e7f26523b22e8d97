// The one-step stiffness of a hold on a solid organ, for the haptic coupling's local model
// (atlas_app virtual_coupling.hpp). The solid step solves A x = b + C^T lambda with C x = t, one
// row per lattice tetrahedron holding grasped vertices, on their mean, and t the mean of their
// targets (solid_step.cpp grasp_rows, the exact constraints): lambda = S^-1 (t - C A^-1 b)
// with S = C A^-1 C^T, and the tool's reaction is -sum_j lambda_j. Moving every target by the same
// offset d changes the reaction by -(1^T S^-1 1) d: one scalar for x, y and z, since A acts alike
// on the three (the prefactored matrix holds inertia M/h^2, the elastic weights and the Rayleigh
// term, so this is the stiffness of one implicit step, "K + B / dt" of a spring model).
#include <cmath>
#include <vector>

#include <Eigen/Dense>

#include "engine.hpp"
#include "softatlas/sim/sim.hpp"
#include "softatlas/sim/solid.hpp"
#include "solid_factor.hpp"

namespace softatlas::sim {
namespace {

// 1^T S^-1 1 from the lower Cholesky factor of S (k x k, column-major).
double ones_quadratic(const double* chol, int32_t k) {
  const Eigen::Map<const Eigen::MatrixXd> L(chol, k, k);
  const Eigen::VectorXd y = L.triangularView<Eigen::Lower>().solve(Eigen::VectorXd::Ones(k));
  return y.squaredNorm();
}

}  // namespace

double solid_hold_stiffness(const Model& m, const Work& w, const std::vector<int32_t>& verts) {
  double total = 0.0;
  for (size_t bi = 0; bi < m.solids.size(); ++bi) {
    const SolidBody& b = m.solids[bi];
    const OrganRange& r = m.organs[b.organ];
    std::vector<int32_t> local;
    for (int32_t v : verts)
      if (v >= 0 && v < m.nvert && m.vert_organ[v] == b.organ && b.embed_tet[v - r.vert_begin] >= 0)
        local.push_back(v - r.vert_begin);
    if (local.empty()) continue;
    if (bi < w.solid.size() && w.solid[bi].grasp_verts == local) {  // held: the step's own rows and factor
      const int32_t k = w.solid[bi].grasp.rows;
      if (w.solid[bi].grasp_chol.size() == static_cast<size_t>(k) * k) {
        total += ones_quadratic(w.solid[bi].grasp_chol.data(), k);
        continue;
      }
    }
    // Not held yet (a probe's patch before the touch): the step's Schur complement, built here.
    const GraspRows rows = grasp_rows(b, local);
    Eigen::MatrixXd Z, L;
    if (!grasp_schur(b, local, rows, Z, L)) continue;
    total += ones_quadratic(L.data(), rows.rows);
  }
  return std::isfinite(total) ? total : 0.0;
}

}  // namespace softatlas::sim
