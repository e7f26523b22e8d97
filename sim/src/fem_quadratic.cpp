// Quadratic tetrahedra, neo-Hookean, Newton with the consistent tangent (see fem_quadratic.hpp).
//
// Per element and quadrature point q (4-point rule, barycentric points (a, b, b, b) and
// permutations, a = 0.585..., b = 0.138..., weight V/4), with g_n the rest-frame gradient of
// shape function n (constant gradients of the barycentric coordinates L_a, since the rest
// tetrahedra are straight):
//   corner a: g = (4 L_a - 1) grad L_a,   edge (a, b): g = 4 (L_a grad L_b + L_b grad L_a)
//   F = sum_n x_n g_n^T,   vec(F) = B u  (B: 9 x 30, row 3 i + k, column 3 n + i holds g_n[k])
//   f_e = -sum_q w_q B^T vec(P(F)),   K_e = sum_q w_q B^T A B,   A = dP/dF (9 x 9, symmetric)
//   dP[dF] = mu dF + (mu - lambda ln J) F^-T dF^T F^-T + lambda tr(F^-1 dF) F^-T.
#include "softatlas/sim/fem_quadratic.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "fem_common.hpp"
#include "softatlas/sim/error.hpp"

namespace softatlas::sim::fem {

namespace {

using namespace detail;  // Mat3, Vec3, node(), box_size()

using Mat9 = Eigen::Matrix<double, 9, 9>;
using Vec9 = Eigen::Matrix<double, 9, 1>;
using Mat930 = Eigen::Matrix<double, 9, 30>;
using Mat30 = Eigen::Matrix<double, 30, 30>;
using Vec30 = Eigen::Matrix<double, 30, 1>;

// The corners of the six edges, in the order of QuadraticModel::tets (columns 4..9).
constexpr int kEdge[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};

// 4-point rule (degree 2) on the tetrahedron, barycentric coordinates.
constexpr double kQa = 0.5854101966249685, kQb = 0.1381966011250105;
Eigen::Vector4d quad_point(int q) {
  Eigen::Vector4d L = Eigen::Vector4d::Constant(kQb);
  L[q] = kQa;
  return L;
}

// Gradients of L0..L3 in the rest frame (rows of Dm^-1 for L1..L3, L0 the negative sum).
std::array<Vec3, 4> bary_gradients(const QuadraticModel& q, int32_t t) {
  const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> inv(&q.linear.tet_dm_inv[9 * t]);
  std::array<Vec3, 4> g;
  for (int a = 1; a < 4; ++a) g[a] = inv.row(a - 1).transpose();
  g[0] = -(g[1] + g[2] + g[3]);
  return g;
}

// Shape-function gradients of the 10 nodes at barycentric point L: rows of G (10 x 3).
Eigen::Matrix<double, 10, 3> shape_gradients(const std::array<Vec3, 4>& gl, const Eigen::Vector4d& L) {
  Eigen::Matrix<double, 10, 3> G;
  for (int a = 0; a < 4; ++a) G.row(a) = ((4.0 * L[a] - 1.0) * gl[a]).transpose();
  for (int e = 0; e < 6; ++e) {
    const int a = kEdge[e][0], b = kEdge[e][1];
    G.row(4 + e) = (4.0 * (L[a] * gl[b] + L[b] * gl[a])).transpose();
  }
  return G;
}

Mat930 strain_matrix(const Eigen::Matrix<double, 10, 3>& G) {
  Mat930 B = Mat930::Zero();
  for (int n = 0; n < 10; ++n)
    for (int i = 0; i < 3; ++i)
      for (int k = 0; k < 3; ++k) B(3 * i + k, 3 * n + i) = G(n, k);
  return B;
}

// The 30 values of a nodal field (#nnode*3) at the element's nodes.
Vec30 gather_element(const QuadraticModel& q, int32_t t, const std::vector<double>& x) {
  Vec30 u;
  for (int n = 0; n < 10; ++n) u.segment<3>(3 * n) = node(x, q.tets[10 * t + n]);
  return u;
}

// Displacements from rest of the element's nodes: the strain is formed from these, not from the
// positions, so small strains keep their digits.
Vec30 element_displacements(const QuadraticModel& q, int32_t t, const std::vector<double>& x) {
  Vec30 u;
  for (int n = 0; n < 10; ++n) {
    const int32_t i = q.tets[10 * t + n];
    u.segment<3>(3 * n) = node(x, i) - node(q.rest, i);
  }
  return u;
}

Mat3 unvec(const Vec9& v) {
  Mat3 F;
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) F(i, k) = v[3 * i + k];
  return F;
}
Vec9 vec(const Mat3& F) {
  Vec9 v;
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) v[3 * i + k] = F(i, k);
  return v;
}

struct Stress {
  double energy_density = 0.0;
  Mat3 P;
  bool inverted = false;
};

// J - 1 of F = I + H without cancellation: det(I + H) = 1 + I1 + I2 + I3 of H.
double det_minus_one(const Mat3& H) {
  const double tr = H.trace();
  return tr + 0.5 * (tr * tr - (H * H).trace()) + H.determinant();
}

// Energy and stress from the displacement gradient H = F - I, written so that no term of the
// order of mu or lambda cancels against another (small loads keep their relative accuracy):
// F - F^-T = H + F^-T H^T, tr(F^T F) - 3 = 2 tr H + |H|^2, ln J = log1p(J - 1).
Stress neo_hookean(const QuadraticModel& q, const Mat3& H) {
  Stress s;
  const double jm1 = det_minus_one(H);
  if (!(jm1 > -1.0) || !std::isfinite(jm1)) {
    s.inverted = true;
    s.energy_density = std::numeric_limits<double>::infinity();
    s.P.setZero();
    return s;
  }
  const double lnJ = std::log1p(jm1), mu = q.lame_mu, lambda = q.lame_lambda;
  const Mat3 FinvT = (Mat3::Identity() + H).inverse().transpose();
  s.energy_density = 0.5 * mu * (2.0 * H.trace() + H.squaredNorm()) - mu * lnJ + 0.5 * lambda * lnJ * lnJ;
  s.P = mu * (H + FinvT * H.transpose()) + lambda * lnJ * FinvT;
  return s;
}

// A = dP/dF at F (J > 0), column 3 j + l = vec(dP[e_j e_l^T]).
Mat9 neo_hookean_tangent(const QuadraticModel& q, const Mat3& F) {
  const double lnJ = std::log(F.determinant()), mu = q.lame_mu, lambda = q.lame_lambda;
  const Mat3 Finv = F.inverse(), FinvT = Finv.transpose();
  Mat9 A;
  for (int j = 0; j < 3; ++j)
    for (int l = 0; l < 3; ++l) {
      Mat3 dF = Mat3::Zero();
      dF(j, l) = 1.0;
      const Mat3 dP =
          mu * dF + (mu - lambda * lnJ) * FinvT * dF.transpose() * FinvT + lambda * (Finv * dF).trace() * FinvT;
      A.col(3 * j + l) = vec(dP);
    }
  return 0.5 * (A + A.transpose());
}

// Visits every element's quadrature points: fn(t, weight, B, H) with H = F - I.
template <class Fn>
void for_each_point(const QuadraticModel& q, const std::vector<double>& x, Fn&& fn) {
  for (int32_t t = 0; t < q.ntet; ++t) {
    const std::array<Vec3, 4> gl = bary_gradients(q, t);
    const Vec30 u = element_displacements(q, t, x);
    const double w = q.linear.tet_volume[t] / 4.0;
    for (int p = 0; p < 4; ++p) {
      const Mat930 B = strain_matrix(shape_gradients(gl, quad_point(p)));
      if (!fn(t, w, B, unvec(B * u))) return;
    }
  }
}

// K_e = sum_q w_q B^T A B at x (30 x 30); quadrature points with J <= 0 contribute nothing.
Mat30 element_tangent(const QuadraticModel& q, int32_t t, const std::vector<double>& x) {
  const std::array<Vec3, 4> gl = bary_gradients(q, t);
  const Vec30 u = element_displacements(q, t, x);
  const double w = q.linear.tet_volume[t] / 4.0;
  Mat30 K = Mat30::Zero();
  for (int p = 0; p < 4; ++p) {
    const Mat930 B = strain_matrix(shape_gradients(gl, quad_point(p)));
    const Mat3 F = Mat3::Identity() + unvec(B * u);
    if (F.determinant() > 0.0) K.noalias() += w * B.transpose() * neo_hookean_tangent(q, F) * B;
  }
  return K;
}

// Conjugate gradients on K x = b preconditioned by a factorisation M of a nearby (SPD) matrix:
// true when |b - K x| <= 1e-8 |b| within 25 iterations (the inexact-Newton forcing term stays
// far below the Newton residual, so the convergence stays quadratic down to the floor).
bool pcg(const Eigen::SparseMatrix<double>& K, const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>& M,
         const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  const double bnorm = b.norm();
  x = M.solve(b);
  Eigen::VectorXd r = b - K * x, z = M.solve(r), p = z, Kp;
  double rz = r.dot(z);
  for (int it = 0; it < 25; ++it) {
    if (r.norm() <= 1e-8 * bnorm) return x.allFinite();
    Kp = K * p;
    const double pKp = p.dot(Kp);
    if (!(pKp > 0.0)) return false;
    const double a = rz / pKp;
    x += a * p;
    r -= a * Kp;
    z = M.solve(r);
    const double rz_next = r.dot(z);
    p = z + (rz_next / rz) * p;
    rz = rz_next;
  }
  return r.norm() <= 1e-8 * bnorm && x.allFinite();
}

}  // namespace

QuadraticModel compile_quadratic(const TetMesh& mesh, const Material& material) {
  QuadraticModel q;
  q.linear = compile(mesh, material);  // all the checks; tets reordered to positive volume
  q.nvertex = q.linear.nnode;
  q.ntet = q.linear.ntet;
  q.lame_lambda = q.linear.lame_lambda;
  q.lame_mu = q.linear.lame_mu;
  std::map<std::pair<int32_t, int32_t>, int32_t> edges;
  q.tets.resize(10 * static_cast<size_t>(q.ntet));
  for (int32_t t = 0; t < q.ntet; ++t) {
    const int32_t* c = &q.linear.tets[4 * t];
    for (int a = 0; a < 4; ++a) q.tets[10 * t + a] = c[a];
    for (int e = 0; e < 6; ++e) {
      const int32_t a = c[kEdge[e][0]], b = c[kEdge[e][1]];
      const auto key = std::minmax(a, b);
      auto it = edges.find(key);
      if (it == edges.end()) {
        it = edges.emplace(key, q.nvertex + static_cast<int32_t>(q.edge_ends.size() / 2)).first;
        q.edge_ends.insert(q.edge_ends.end(), {key.first, key.second});
      }
      q.tets[10 * t + 4 + e] = it->second;
    }
  }
  q.nnode = q.nvertex + static_cast<int32_t>(q.edge_ends.size() / 2);
  q.rest = q.linear.rest;
  q.rest.resize(3 * static_cast<size_t>(q.nnode));
  for (int32_t e = 0; e < q.nnode - q.nvertex; ++e)
    for (int c = 0; c < 3; ++c)
      q.rest[3 * (q.nvertex + e) + c] =
          0.5 * (q.linear.rest[3 * q.edge_ends[2 * e] + c] + q.linear.rest[3 * q.edge_ends[2 * e + 1] + c]);
  // CSR by the smaller corner (std::map iterates in key order).
  q.edge_offset.assign(q.nvertex + 1, 0);
  for (const auto& kv : edges) ++q.edge_offset[kv.first.first + 1];
  for (int32_t i = 0; i < q.nvertex; ++i) q.edge_offset[i + 1] += q.edge_offset[i];
  for (const auto& kv : edges) {
    q.edge_other.push_back(kv.first.second);
    q.edge_id.push_back(kv.second);
  }
  return q;
}

int32_t edge_node(const QuadraticModel& q, int32_t a, int32_t b) {
  if (a > b) std::swap(a, b);
  if (a < 0 || b >= q.nvertex || a == b) return -1;
  const auto first = q.edge_other.begin() + q.edge_offset[a], last = q.edge_other.begin() + q.edge_offset[a + 1];
  const auto it = std::lower_bound(first, last, b);
  return it != last && *it == b ? q.edge_id[it - q.edge_other.begin()] : -1;
}

std::vector<int32_t> quadratic_region(const QuadraticModel& q, const std::vector<int32_t>& corners) {
  std::vector<uint8_t> in(q.nvertex, 0);
  for (int32_t c : corners)
    if (c >= 0 && c < q.nvertex) in[c] = 1;
  std::vector<int32_t> out = corners;
  for (int32_t e = 0; e < q.nnode - q.nvertex; ++e)
    if (in[q.edge_ends[2 * e]] && in[q.edge_ends[2 * e + 1]]) out.push_back(q.nvertex + e);
  return out;
}

Load make_load(const QuadraticModel& q) { return empty_load(q.nnode); }

void add_traction(const QuadraticModel& q, Load& load, const std::vector<int32_t>& faces,
                  const std::array<double, 3>& traction_pa) {
  for (size_t f = 0; f + 2 < faces.size(); f += 3) {
    const Vec3 a = node(q.rest, faces[f]), b = node(q.rest, faces[f + 1]), c = node(q.rest, faces[f + 2]);
    const double area = 0.5 * (b - a).cross(c - a).norm();
    for (int k = 0; k < 3; ++k) {
      const int32_t e = edge_node(q, faces[f + k], faces[f + (k + 1) % 3]);
      if (e < 0) throw InputError("add_traction", "face " + std::to_string(f / 3) + " is not a face of the mesh");
      for (int d = 0; d < 3; ++d) load.force[3 * e + d] += traction_pa[d] * area / 3.0;
    }
  }
}

double elastic_energy(const QuadraticModel& q, const std::vector<double>& x) {
  double e = 0.0;
  for_each_point(q, x, [&](int32_t, double w, const Mat930&, const Mat3& H) {
    const Stress s = neo_hookean(q, H);
    e += w * s.energy_density;
    return !s.inverted;
  });
  return std::isfinite(e) ? e : std::numeric_limits<double>::infinity();
}

double deformed_volume(const QuadraticModel& q, const std::vector<double>& x) {
  double v = 0.0;
  for_each_point(q, x, [&](int32_t, double w, const Mat930&, const Mat3& H) {
    v += w * (1.0 + det_minus_one(H));
    return true;
  });
  return v;
}

void internal_forces(const QuadraticModel& q, const std::vector<double>& x, std::vector<double>& f) {
  f.assign(3 * static_cast<size_t>(q.nnode), 0.0);
  for_each_point(q, x, [&](int32_t t, double w, const Mat930& B, const Mat3& H) {
    const Vec30 fe = -w * B.transpose() * vec(neo_hookean(q, H).P);
    for (int n = 0; n < 10; ++n)
      for (int c = 0; c < 3; ++c) f[3 * q.tets[10 * t + n] + c] += fe[3 * n + c];
    return true;
  });
}

void tangent_times(const QuadraticModel& q, const std::vector<double>& x, const std::vector<double>& v,
                   std::vector<double>& y) {
  y.assign(3 * static_cast<size_t>(q.nnode), 0.0);
  for (int32_t t = 0; t < q.ntet; ++t) {
    const Vec30 ye = element_tangent(q, t, x) * gather_element(q, t, v);
    for (int n = 0; n < 10; ++n)
      for (int c = 0; c < 3; ++c) y[3 * q.tets[10 * t + n] + c] += ye[3 * n + c];
  }
}

StaticReport solve_static(const QuadraticModel& q, const Load& load, std::vector<double>& x, const StaticOptions& opt) {
  StaticReport rep;
  const size_t ndof = 3 * static_cast<size_t>(q.nnode);
  if (x.size() != ndof || load.force.size() != ndof || load.dof_fixed.size() != ndof || load.dof_disp.size() != ndof)
    throw InputError("solve_static", "positions and load must have 3 values per node (" + std::to_string(ndof) + ")");
  std::vector<int32_t> dof(ndof, -1);
  int32_t nfree = 0;
  for (size_t d = 0; d < ndof; ++d)
    if (!load.dof_fixed[d]) dof[d] = nfree++;
  double fnorm = 0.0;
  for (double f : load.force) fnorm += f * f;
  fnorm = std::sqrt(fnorm);
  const double size = box_size(q.rest);
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt;
  bool analysed = false, factored = false;
  std::vector<double> fint, trial(ndof);
  std::vector<Eigen::Triplet<double>> trip;
  const int steps = std::max(1, opt.load_steps);

  // Residual r = lam f_ext + f_int on the free DOFs; its norm relative to the load or reaction.
  auto residual = [&](const std::vector<double>& xx, double lam, Eigen::VectorXd& r) {
    internal_forces(q, xx, fint);
    r.resize(nfree);
    double react = 0.0;
    for (size_t d = 0; d < ndof; ++d) {
      if (dof[d] >= 0)
        r[dof[d]] = lam * load.force[d] + fint[d];
      else
        react += fint[d] * fint[d];
    }
    return r.norm() / (std::max(lam * fnorm, std::sqrt(react)) + 1e-300);
  };
  auto potential = [&](const std::vector<double>& xx, double lam) {
    double e = elastic_energy(q, xx);
    for (size_t d = 0; d < ndof; ++d) e -= lam * load.force[d] * (xx[d] - q.rest[d]);
    return e;
  };

  for (int s = 1; s <= steps; ++s) {
    const double lam = static_cast<double>(s) / steps;
    for (int it = 0; it < opt.max_iterations; ++it) {
      // What is left of the prescribed increment.
      Eigen::VectorXd dc = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(ndof));
      double dc_max = 0.0;
      for (size_t d = 0; d < ndof; ++d)
        if (dof[d] < 0) {
          dc[d] = q.rest[d] + lam * load.dof_disp[d] - x[d];
          dc_max = std::max(dc_max, std::abs(dc[d]));
        }
      const bool prescribed_reached = dc_max <= 1e-15 * size;
      Eigen::VectorXd r;
      rep.residual = residual(x, lam, r);
      if (prescribed_reached && rep.residual <= opt.tolerance) break;
      // Consistent tangent on the free DOFs, and K_fc dc.
      trip.clear();
      Eigen::VectorXd kc = Eigen::VectorXd::Zero(nfree);
      for (int32_t t = 0; t < q.ntet; ++t) {
        const Mat30 Ke = element_tangent(q, t, x);
        for (int a = 0; a < 30; ++a) {
          const int32_t ga = dof[3 * q.tets[10 * t + a / 3] + a % 3];
          if (ga < 0) continue;
          for (int b = 0; b < 30; ++b) {
            const size_t db = 3 * static_cast<size_t>(q.tets[10 * t + b / 3]) + b % 3;
            const int32_t gb = dof[db];
            if (gb >= 0)
              trip.emplace_back(ga, gb, Ke(a, b));
            else
              kc[ga] += Ke(a, b) * dc[static_cast<Eigen::Index>(db)];
          }
        }
      }
      Eigen::SparseMatrix<double> K(nfree, nfree);
      K.setFromTriplets(trip.begin(), trip.end());
      if (!analysed) {
        ldlt.analyzePattern(K);
        analysed = true;
      }
      // The step: preconditioned CG with the last factorisation while it converges in a few
      // iterations (the tangent changes little between Newton iterations; factorising is 90 % of
      // the cost), else a new factorisation, shifted while the tangent is indefinite.
      const Eigen::VectorXd rhs = r - kc;
      Eigen::VectorXd dx;
      if (!(factored && pcg(K, ldlt, rhs, dx) && (!prescribed_reached || dx.dot(r) > 0.0))) {
        const double diag_mean = K.diagonal().cwiseAbs().mean() + 1e-300;
        double shift = 0.0;
        dx.resize(0);
        for (int tries = 0; tries < 12; ++tries) {
          Eigen::SparseMatrix<double> Ks = K;
          if (shift > 0) {
            for (int32_t i = 0; i < nfree; ++i) Ks.coeffRef(i, i) += shift;
          }
          ldlt.factorize(Ks);
          factored = ldlt.info() == Eigen::Success && ldlt.vectorD().minCoeff() > 0.0;
          if (factored) {
            dx = ldlt.solve(rhs);
            if (dx.allFinite() && (!prescribed_reached || dx.dot(r) > 0.0)) break;
          }
          shift = shift > 0 ? 10.0 * shift : 1e-6 * diag_mean;
          dx.resize(0);
        }
      }
      if (dx.size() != nfree) return rep;  // no descent direction: the load does not hold the body
      // Backtracking: no inverted quadrature point; Armijo on the energy once the prescribed
      // values are reached.
      const double e0 = prescribed_reached ? potential(x, lam) : 0.0;
      const double slope = -dx.dot(r);
      double alpha = 1.0;
      bool accepted = false;
      for (int cut = 0; cut < 40 && !accepted; ++cut, alpha *= 0.5) {
        for (size_t d = 0; d < ndof; ++d) trial[d] = x[d] + alpha * (dof[d] >= 0 ? dx[dof[d]] : dc[d]);
        const double e = prescribed_reached ? potential(trial, lam) : elastic_energy(q, trial);
        accepted = std::isfinite(e) && (!prescribed_reached || e <= e0 + 1e-4 * alpha * slope);
        // Near the solution the energy's decrease falls below its rounding error: the full
        // Newton step is then taken when it lowers the residual.
        if (!accepted && cut == 0 && std::isfinite(e)) {
          Eigen::VectorXd rt;
          accepted = residual(trial, lam, rt) < rep.residual;
        }
      }
      if (!accepted) break;  // at the rounding floor: the final residual decides convergence
      x.swap(trial);
      ++rep.iterations;
      if (prescribed_reached && dx.lpNorm<Eigen::Infinity>() * alpha * 2.0 < 1e-14 * size) break;
    }
    if (opt.on_increment) opt.on_increment(lam, x);
  }
  Eigen::VectorXd r;
  rep.residual = residual(x, 1.0, r);
  rep.converged = std::isfinite(rep.residual) && rep.residual <= std::max(opt.tolerance, 1e-12) * 10.0;
  return rep;
}

std::array<double, 3> reaction_force(const QuadraticModel& q, const std::vector<double>& x,
                                     const std::vector<int32_t>& nodes) {
  std::vector<double> f;
  internal_forces(q, x, f);
  return node_sum(f, nodes);
}

void interpolate(const QuadraticModel& q, const Embedding& emb, const std::vector<double>& x,
                 std::vector<double>& out) {
  const size_t np = emb.tet.size();
  out.assign(3 * np, 0.0);
  for (size_t p = 0; p < np; ++p) {
    const int32_t t = emb.tet[p];
    const double* L = &emb.weight[4 * p];
    Vec3 u = Vec3::Zero();
    for (int a = 0; a < 4; ++a) {
      const int32_t n = q.tets[10 * t + a];
      u += L[a] * (2.0 * L[a] - 1.0) * (node(x, n) - node(q.rest, n));
    }
    for (int e = 0; e < 6; ++e) {
      const int32_t n = q.tets[10 * t + 4 + e];
      u += 4.0 * L[kEdge[e][0]] * L[kEdge[e][1]] * (node(x, n) - node(q.rest, n));
    }
    for (int c = 0; c < 3; ++c) out[3 * p + c] = u[c];
  }
}

}  // namespace softatlas::sim::fem
