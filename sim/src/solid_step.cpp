// The solid organ model: compile (masses, weights, damping, prefactored matrix) and the
// projective-dynamics step (solid.hpp). Equations:
//   implicit Euler as minimisation      Liu et al. 2013 eq 4 / Bouaziz et al. 2014 eq 5:
//     x = argmin 1/(2 h^2) |x - s|_M^2 + sum_e W_e(x) - f_ext . x,   s = x_n + h v_n
//   constraint energy                   Bouaziz et al. 2014 eq 9: w/2 |G_e x - p_e|^2, p_e the
//                                       projection of the element's F onto its constraint set
//   strain (corotational, per tet)      p = R, w = 2 mu V      (mu |F - R|^2)
//   volume (per lattice cell)           p = F_c + t R_c, det(R_c^T F_c + t I) = 1, w = 3 lambda V_c
//                                       (3 lambda/2 t^2; to first order Mueller & Gross 2004's
//                                       lambda/2 (tr(R^T F) - 3)^2), F_c the mean of the cell's 6
//                                       tetrahedra (mean dilatation: no volumetric locking)
//   connection springs                  Liu et al. 2013 spring projection, other end held
//   Rayleigh damping beta K, rotated    p = F_n + R - R_n, w = beta/h 2 mu V
//   global step                         Bouaziz et al. 2014 eq 12:
//     (M/h^2 + sum_e w_e G_e^T G_e) x = M s/h^2 + sum_e w_e G_e^T p_e + f_ext
//   rotation fit                        Mueller et al. 2016 (warm-started quaternion iteration)
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>

#include "engine.hpp"
#include "workers.hpp"
#include "softatlas/sim/error.hpp"
#include "softatlas/sim/geometry.hpp"
#include "softatlas/sim/sim.hpp"
#include "softatlas/sim/solid.hpp"
#include "solid_factor.hpp"

namespace softatlas::sim {

namespace {

using Mat3 = Eigen::Matrix3d;
using ColMatX3 = Eigen::Matrix<double, Eigen::Dynamic, 3>;

constexpr int kDefaultNodes = 300;            // lattice nodes per organ when the material gives none
constexpr int kMaxVolumePieces = 8;           // closed surface pieces of one organ with a volume constraint
constexpr double kVolumeBand = 0.005;         // a piece's volume is kept within +-0.5 % of its rest volume
constexpr double kVolumeStep = 1.0;           // cells a node may move per step to keep a piece's volume
constexpr double kVolumeGiveBack = 0.3;       // cells a node may move per step to give back what contact took
constexpr int kDefaultIterations = 4;         // local/global iterations per step (docs/physics.md)
constexpr double kDefaultDampingRatio = 0.5;  // Rayleigh ratio at the lowest shear mode
constexpr int kRotationIterations = 1;        // warm-started rotation-fit iterations per local step
constexpr int kSceneNodes = 1500;             // lattice nodes of all solid organs of a scene together
constexpr int kMinNodes = 80;                 // the smallest organ's lattice when the scene total shares
constexpr int kMaxThinNodes = 400;            // most nodes the thickness rule may give one organ
constexpr int kSceneThinNodes = 4000;         // ... and all organs of a scene together (real time, docs/physics.md)
// Cells no larger than kThicknessCell * V / A: a long tube of diameter d (V / A = d / 4) gets 3
// cells across, a slab of thickness t (V / A = t / 2) 1.5. Coarser lattices of thin organs
// (aorta, veins, pancreas: 1-2 cells across) lost 10-120 % of their volume under a 30 mm pull.
constexpr double kThicknessCell = 4.0 / 3.0;

Mat3 quat_matrix(const double* q) {
  const double w = q[0], x = q[1], y = q[2], z = q[3];
  Mat3 R;
  R << 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y), 2 * (x * y + w * z), 1 - 2 * (x * x + z * z),
      2 * (y * z - w * x), 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y);
  return R;
}

// Rotation of F by the iteration of Mueller et al. 2016 ("A robust method to extract the
// rotational part of deformations", Algorithm 1), warm-started from the unit quaternion q (w, x,
// y, z) and its matrix R (kept beside it, so that no iteration rebuilds it), both updated. The
// quaternion exponential of small steps (|omega| < 0.1) by its Taylor series (error < 1e-10),
// without sin/cos.
void rotation_fit(const Mat3& A, double* q, double* Rm, int iterations) {
  Eigen::Map<Mat3> R(Rm);
  for (int it = 0; it < iterations; ++it) {
    const Eigen::Vector3d omega =
        (R.col(0).cross(A.col(0)) + R.col(1).cross(A.col(1)) + R.col(2).cross(A.col(2))) *
        (1.0 / (std::fabs(R.col(0).dot(A.col(0)) + R.col(1).dot(A.col(1)) + R.col(2).dot(A.col(2))) + 1e-9));
    const double w2 = omega.squaredNorm();
    if (w2 < 1e-24) break;
    double c, sw;  // cos(w/2), sin(w/2)/w
    if (w2 < 0.01) {
      c = 1.0 - w2 * (1.0 / 8.0) + w2 * w2 * (1.0 / 384.0);  // constants folded: no divisions
      sw = 0.5 - w2 * (1.0 / 48.0) + w2 * w2 * (1.0 / 3840.0);
    } else {
      const double w = std::sqrt(w2);
      c = std::cos(0.5 * w), sw = std::sin(0.5 * w) / w;
    }
    const double dx = sw * omega[0], dy = sw * omega[1], dz = sw * omega[2];
    const double nq[4] = {c * q[0] - dx * q[1] - dy * q[2] - dz * q[3], c * q[1] + dx * q[0] + dy * q[3] - dz * q[2],
                          c * q[2] - dx * q[3] + dy * q[0] + dz * q[1], c * q[3] + dx * q[2] - dy * q[1] + dz * q[0]};
    const double inv = 1.0 / std::sqrt(nq[0] * nq[0] + nq[1] * nq[1] + nq[2] * nq[2] + nq[3] * nq[3]);
    for (int k = 0; k < 4; ++k) q[k] = nq[k] * inv;
    R = quat_matrix(q);
  }
}

// The volume constraint's projection p = F + t R = R (S + t I), S = R^T F: the shift t along the
// identity with det(S + t I) = 1 (volume kept exactly, not only to first order as the trace
// form tr(S + t I) = 3 of Mueller & Gross 2004 does: a 30 % stretch at constant trace loses 6 %
// of the volume). Newton on the cubic from the trace form's t = (3 - tr S) / 3, which it equals to
// first order; falls back to it when Newton leaves |t| < 0.5.
double volume_shift(const Mat3& S) {
  // det(S + t I) = t^3 + c2 t^2 + c1 t + c0: c2 = tr S, c1 = sum of principal 2x2 minors, c0 = det S
  const double c2 = S.trace();
  const double c1 = S(1, 1) * S(2, 2) - S(1, 2) * S(2, 1) + S(0, 0) * S(2, 2) - S(0, 2) * S(2, 0) + S(0, 0) * S(1, 1) -
                    S(0, 1) * S(1, 0);
  const double c0 = S.determinant() - 1.0;
  const double t0 = (3.0 - c2) * (1.0 / 3.0);
  double t = t0;
  for (int it = 0; it < 3; ++it) {
    const double f = ((t + c2) * t + c1) * t + c0, df = (3.0 * t + 2.0 * c2) * t + c1;
    if (!(df > 1e-3)) return t0;
    t -= f / df;
  }
  return std::fabs(t) < 0.5 ? t : t0;
}

// An element (a tetrahedron: 4 nodes, a lattice cell: 8) is its nodes n and the gradients g
// (3 per node) of F = sum_i x_i g_i^T; the helpers below serve both.

// F of an element at positions x (#nnode*3 row-major).
Mat3 element_deformation(const int32_t* n, const double* g, int k, const double* x) {
  Mat3 F = Mat3::Zero();
  for (int i = 0; i < k; ++i) {
    const double* p = x + 3 * n[i];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) F(r, c) += p[r] * g[3 * i + c];
  }
  return F;
}
Mat3 deformation(const SolidBody& b, int32_t t, const double* x) {
  return element_deformation(&b.tets[4 * t], &b.grad[12 * t], 4, x);
}
Mat3 cell_deformation(const SolidBody& b, int32_t c, const double* x) {
  return element_deformation(&b.cell_nodes[8 * c], &b.cell_grad[24 * c], 8, x);
}

// The projection's pull Y g_i on each node of an element, into the column-major right-hand side.
void add_element_rhs(const int32_t* n, const double* g, int k, const Mat3& Y, int32_t nnode, double* sol) {
  for (int i = 0; i < k; ++i) {
    const Eigen::Vector3d y = Y * Eigen::Vector3d(g[3 * i], g[3 * i + 1], g[3 * i + 2]);
    for (int c = 0; c < 3; ++c) sol[c * nnode + n[i]] += y[c];
  }
}

// Unit quaternions and identity matrices: the rotation fits' warm start, n of them.
void reset_rotations(double* quat, double* rot, int32_t n) {
  for (int32_t e = 0; e < n; ++e) {
    quat[4 * e] = 1, quat[4 * e + 1] = quat[4 * e + 2] = quat[4 * e + 3] = 0;
    Eigen::Map<Mat3>(rot + 9 * e).setIdentity();
  }
}

using Triplets = std::vector<Eigen::Triplet<double>>;

// w G^T G of an element as triplets (scalar: the same matrix acts on x, y and z).
void add_element_gram(const int32_t* n, const double* g, int k, double w, Triplets& T) {
  for (int i = 0; i < k; ++i)
    for (int j = 0; j < k; ++j)
      T.emplace_back(n[i], n[j], w * (g[3 * i] * g[3 * j] + g[3 * i + 1] * g[3 * j + 1] + g[3 * i + 2] * g[3 * j + 2]));
}

// sum_t w_t G_t^T G_t over the tetrahedra.
void add_laplacian(const SolidBody& b, const std::vector<double>& w, Triplets& T) {
  for (int32_t t = 0; t < b.ntet; ++t) add_element_gram(&b.tets[4 * t], &b.grad[12 * t], 4, w[t], T);
}

// sum_c w_c G_c^T G_c of the cells' volume constraints.
void add_cell_laplacian(const SolidBody& b, Triplets& T) {
  for (int32_t c = 0; c < b.ncell; ++c)
    add_element_gram(&b.cell_nodes[8 * c], &b.cell_grad[24 * c], 8, b.w_volume[c], T);
}

// Lowest nonzero shear frequency of the free lattice: L_mu u = omega^2 M u with the scalar
// Laplacian of weight mu V f, by inverse iteration M-orthogonal to the constants of each
// connected piece (an organ in two pieces, as the portal and splenic veins cut by a CT slab, has a
// zero mode per piece; it gave omega_1 = 0 and no damping).
double lowest_shear_mode(const SolidBody& b) {
  std::vector<double> w(b.ntet);
  for (int32_t t = 0; t < b.ntet; ++t) w[t] = 0.5 * b.w_strain[t];  // 2 mu V f / 2
  Triplets T;
  add_laplacian(b, w, T);
  Eigen::SparseMatrix<double> L(b.nnode, b.nnode);
  L.setFromTriplets(T.begin(), T.end());
  const Eigen::Map<const Eigen::VectorXd> M(b.mass.data(), b.nnode);
  // connected pieces (union-find over the tetrahedra)
  std::vector<int32_t> root(b.nnode);
  for (int32_t i = 0; i < b.nnode; ++i) root[i] = i;
  const auto find = [&](int32_t i) {
    while (root[i] != i) i = root[i] = root[root[i]];
    return i;
  };
  for (int32_t t = 0; t < b.ntet; ++t)
    for (int i = 1; i < 4; ++i) root[find(b.tets[4 * t + i])] = find(b.tets[4 * t]);
  std::vector<int32_t> piece(b.nnode);
  for (int32_t i = 0; i < b.nnode; ++i) piece[i] = find(i);
  std::vector<double> pm(b.nnode, 0.0), pu(b.nnode, 0.0);
  const auto remove_constants = [&](Eigen::VectorXd& u) {
    std::fill(pm.begin(), pm.end(), 0.0), std::fill(pu.begin(), pu.end(), 0.0);
    for (int32_t i = 0; i < b.nnode; ++i) pm[piece[i]] += M[i], pu[piece[i]] += M[i] * u[i];
    for (int32_t i = 0; i < b.nnode; ++i) u[i] -= pm[piece[i]] > 0 ? pu[piece[i]] / pm[piece[i]] : 0.0;
  };
  const double shift = 1e-6 * L.diagonal().sum() / M.sum();
  Eigen::SparseMatrix<double> S = L;
  for (int i = 0; i < b.nnode; ++i) S.coeffRef(i, i) += shift * M[i];
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(S);
  if (ldlt.info() != Eigen::Success) return 0.0;
  Eigen::VectorXd u(b.nnode);  // a non-constant start
  for (int i = 0; i < b.nnode; ++i) u[i] = b.rest[3 * i] + 0.3 * b.rest[3 * i + 1] + 0.1 * b.rest[3 * i + 2];
  for (int it = 0; it < 40; ++it) {
    remove_constants(u);  // the rigid translations of each piece
    const double n = std::sqrt(u.dot(M.cwiseProduct(u)));
    if (!(n > 0)) return 0.0;
    u /= n;
    u = ldlt.solve(M.cwiseProduct(u)).eval();
  }
  remove_constants(u);
  const double num = u.dot(L * u), den = u.dot(M.cwiseProduct(u));
  return den > 0 ? std::sqrt(std::max(num / den, 0.0)) : 0.0;
}

// The enclosed volume of each closed piece of the organ's surface embedded in the lattice at nodes
// q (row-major) into vol[piece], and its gradient on the nodes, g_n = sum_v w_vn grad_v V (003 eqs
// 27-30 through the barycentric weights) into gn (piece p's at p * #nnode * 3); p and g are scratch
// (#organ vertices * 3). The pieces share no vertex, so one gradient array holds them all.
void embedded_volume(const Model& m, const SolidBody& b, const double* q, std::vector<double>& p,
                     std::vector<double>& g, std::vector<double>& gn, double* vol) {
  const OrganRange& r = m.organs[b.organ];
  const int32_t nv = r.vert_end - r.vert_begin;
  double* px = p.data();
  double* py = px + nv;
  double* pz = py + nv;
  double* gx = g.data();
  double* gy = gx + nv;
  double* gz = gy + nv;
  for (int32_t v = 0; v < nv; ++v) {
    px[v] = py[v] = pz[v] = gx[v] = gy[v] = gz[v] = 0.0;
    const int32_t t = b.embed_tet[v];
    if (t < 0) continue;
    const int32_t* n = &b.tets[4 * t];
    for (int i = 0; i < 4; ++i) {
      const double wi = b.embed_w[4 * v + i];
      px[v] += wi * q[3 * n[i]], py[v] += wi * q[3 * n[i] + 1], pz[v] += wi * q[3 * n[i] + 2];
    }
  }
  add_volume_gradient(px, py, pz, m.face_vert.data(), r.face_begin, r.face_end, r.vert_begin, gx, gy, gz);
  std::fill(gn.begin(), gn.end(), 0.0);
  std::fill(vol, vol + b.npiece, 0.0);
  const size_t n3 = 3 * static_cast<size_t>(b.nnode);
  for (int32_t v = 0; v < nv; ++v) {
    const int32_t t = b.embed_tet[v], pc = b.vert_piece[v];
    if (t < 0 || pc < 0) continue;
    vol[pc] += (px[v] * gx[v] + py[v] * gy[v] + pz[v] * gz[v]) / 3.0;  // x . grad V = 3 V (degree 3)
    const int32_t* n = &b.tets[4 * t];
    double* G = gn.data() + pc * n3;
    for (int i = 0; i < 4; ++i) {
      const double wi = b.embed_w[4 * v + i];
      G[3 * n[i]] += wi * gx[v], G[3 * n[i] + 1] += wi * gy[v], G[3 * n[i] + 2] += wi * gz[v];
    }
  }
}

// What a piece's volume lies outside the band kVolumeBand around its rest volume (0 inside it):
// the constraint leaves small changes to the elasticity (a one-sided band, as the tissue's own
// compressibility at nu 0.49 allows) and stops the large ones of thin organs.
double volume_excess(double volume, double rest) {
  const double band = kVolumeBand * std::fabs(rest), d = volume - rest;
  return d > band ? d - band : d < -band ? d + band : 0.0;
}

// The closed pieces of an organ's surface (faces F over #nv vertices, organ-local): a piece index
// per vertex, the kMaxVolumePieces largest by face count (-1: a smaller piece, or unused).
std::vector<int32_t> surface_pieces(const std::vector<int32_t>& F, int32_t nv, int32_t& npiece) {
  std::vector<int32_t> parent(nv);
  for (int32_t v = 0; v < nv; ++v) parent[v] = v;
  const auto find = [&](int32_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  for (size_t f = 0; f + 2 < F.size(); f += 3)
    for (int e = 0; e < 2; ++e) parent[find(F[f + e])] = find(F[f + e + 1]);
  std::vector<int32_t> faces(nv, 0);
  for (size_t f = 0; f + 2 < F.size(); f += 3) ++faces[find(F[f])];
  std::vector<int32_t> roots;
  for (int32_t v = 0; v < nv; ++v)
    if (faces[v] > 0) roots.push_back(v);
  std::stable_sort(roots.begin(), roots.end(), [&](int32_t a, int32_t c) { return faces[a] > faces[c]; });
  if (roots.size() > static_cast<size_t>(kMaxVolumePieces)) roots.resize(kMaxVolumePieces);
  npiece = static_cast<int32_t>(roots.size());
  std::vector<int32_t> index(nv, -1), piece(nv, -1);
  for (int32_t i = 0; i < npiece; ++i) index[roots[i]] = i;
  for (int32_t v = 0; v < nv; ++v) piece[v] = index[find(v)];
  return piece;
}

// The organ's lattice: the scene share's node budget, refined for thin organs (kThicknessCell)
// up to max_nodes nodes.
SolidLattice organ_lattice(const std::vector<double>& V, const std::vector<int32_t>& F, double volume_m3, int budget,
                           int max_nodes) {
  SolidLattice L = solid_lattice_budget(V, F, budget);
  double area = 0.0;
  for (size_t f = 0; f + 2 < F.size(); f += 3) {
    const Eigen::Vector3d a(&V[3 * F[f]]), b(&V[3 * F[f + 1]]), c(&V[3 * F[f + 2]]);
    area += 0.5 * (b - a).cross(c - a).norm();
  }
  if (!(area > 0) || !(volume_m3 > 0)) return L;
  const double h_thin = kThicknessCell * volume_m3 / area;
  if (L.spacing_m <= h_thin || L.mesh.nnode() >= max_nodes) return L;
  SolidLattice thin = solid_lattice(V, F, h_thin);
  if (thin.mesh.nnode() > max_nodes) thin = solid_lattice_budget(V, F, max_nodes);
  return thin.spacing_m < L.spacing_m ? thin : L;
}

}  // namespace

void compile_solids(const SceneDesc& scene, Model& m) {
  const int32_t norg = static_cast<int32_t>(m.organs.size());
  m.solids.clear();
  m.organ_solid.assign(norg, -1);
  int32_t node_total = 0;
  const double h = m.dt_s;
  // Node budgets: the scene's kSceneNodes shared by volume (one cell size for every organ), each
  // organ between kMinNodes and kDefaultNodes; a material's solid_nodes overrides its share.
  double solid_volume = 0.0;
  for (const OrganRange& r : m.organs)
    if (r.model == ModelKind::solid) solid_volume += std::fabs(r.rest_volume_m3);
  const auto budget_of = [&](const OrganRange& r, const Material& mat) {
    const double share = solid_volume > 0 ? std::fabs(r.rest_volume_m3) / solid_volume : 1.0;
    return mat.solid_nodes > 0
               ? mat.solid_nodes
               : std::clamp(static_cast<int>(std::lround(kSceneNodes * share)), kMinNodes, kDefaultNodes);
  };
  // each solid organ's rest surface with organ-local vertex indices
  std::vector<std::vector<double>> surf_v(norg);
  std::vector<std::vector<int32_t>> surf_f(norg);
  for (int32_t o = 0; o < norg; ++o) {
    const OrganRange& r = m.organs[o];
    if (r.model != ModelKind::solid) continue;
    const int32_t nv = r.vert_end - r.vert_begin;
    std::vector<double>& V = surf_v[o];
    V.resize(3 * static_cast<size_t>(nv));
    for (int32_t v = 0; v < nv; ++v)
      V[3 * v] = m.vert_rest_x[r.vert_begin + v], V[3 * v + 1] = m.vert_rest_y[r.vert_begin + v],
            V[3 * v + 2] = m.vert_rest_z[r.vert_begin + v];
    surf_f[o].assign(m.face_vert.begin() + 3 * r.face_begin, m.face_vert.begin() + 3 * r.face_end);
    for (int32_t& f : surf_f[o]) f -= r.vert_begin;
  }
  // Lattices: the share's, refined for thin organs; when the refinements together pass
  // kSceneThinNodes, each refined organ gets the same fraction of what it asked for.
  std::vector<SolidLattice> lattice(norg);
  std::vector<uint8_t> refined(norg, 0);
  int64_t plain_nodes = 0, thin_nodes = 0;
  for (int32_t o = 0; o < norg; ++o) {
    const OrganRange& r = m.organs[o];
    if (r.model != ModelKind::solid) continue;
    const Material& mat = scene.organs[r.source_index].material;
    const std::vector<double>& V = surf_v[o];
    const std::vector<int32_t>& F = surf_f[o];
    const int budget = budget_of(r, mat);
    lattice[o] = mat.solid_nodes != 0 ? solid_lattice_budget(V, F, budget)
                                      : organ_lattice(V, F, std::fabs(r.rest_volume_m3), budget, kMaxThinNodes);
    refined[o] = mat.solid_nodes == 0 && lattice[o].mesh.nnode() > budget;
    (refined[o] ? thin_nodes : plain_nodes) += lattice[o].mesh.nnode();
  }
  if (plain_nodes + thin_nodes > kSceneThinNodes && thin_nodes > 0) {
    const double scale =
        std::max(0.0, static_cast<double>(kSceneThinNodes - plain_nodes)) / static_cast<double>(thin_nodes);
    for (int32_t o = 0; o < norg; ++o) {
      if (!refined[o]) continue;
      const OrganRange& r = m.organs[o];
      const int budget = budget_of(r, scene.organs[r.source_index].material);
      const int nodes = std::max(budget, static_cast<int>(scale * lattice[o].mesh.nnode()));
      lattice[o] = organ_lattice(surf_v[o], surf_f[o], std::fabs(r.rest_volume_m3), budget, nodes);
    }
  }
  for (int32_t o = 0; o < norg; ++o) {
    const OrganRange& r = m.organs[o];
    if (r.model != ModelKind::solid) continue;
    const Material& mat = scene.organs[r.source_index].material;
    // the surface passes do not apply: the lattice carries the organ
    m.organs[o].volume_stiffness = 0.0, m.organs[o].compensation_iterations = 0;
    m.organs[o].curvature = false, m.organs[o].damping = false;
    const std::string where = "organ " + r.name + ": material";
    if (!(mat.poisson_ratio > -1.0 && mat.poisson_ratio < 0.5))
      throw InputError(where, "poisson_ratio must lie in (-1, 0.5)");
    if (!std::isfinite(mat.damping_ratio))
      throw InputError(where, "damping_ratio must be finite (< 0: the default 0.5)");
    if (!(mat.young_modulus_pa > 0.0) || !std::isfinite(mat.young_modulus_pa))
      throw InputError(where, "young_modulus_pa must be > 0 for the solid model");
    if (mat.solid_nodes < 0 || mat.solid_iterations < 0)
      throw InputError(where, "solid_nodes and solid_iterations must be >= 0");

    const int32_t nv = r.vert_end - r.vert_begin;
    const std::vector<double>& V = surf_v[o];
    const std::vector<int32_t>& F = surf_f[o];
    const SolidLattice& L = lattice[o];

    SolidBody b;
    b.organ = o;
    b.node_begin = node_total;
    b.nnode = L.mesh.nnode();
    b.ntet = L.mesh.ntet();
    b.spacing_m = L.spacing_m;
    b.rest = L.mesh.nodes;
    b.tets = L.mesh.tets;
    b.embed_tet = L.embed_tet;
    b.embed_w = L.embed_w;
    b.vert_piece = surface_pieces(F, nv, b.npiece);
    {
      std::vector<double> p(3 * static_cast<size_t>(nv)), g(3 * static_cast<size_t>(nv)),
          gn(3 * static_cast<size_t>(b.nnode) * b.npiece);
      b.piece_rest_volume.assign(b.npiece, 0.0);
      embedded_volume(m, b, b.rest.data(), p, g, gn, b.piece_rest_volume.data());
    }
    b.young_modulus_pa = mat.young_modulus_pa;
    b.poisson_ratio = mat.poisson_ratio;
    b.damping_ratio = mat.damping_ratio < 0.0 ? kDefaultDampingRatio : mat.damping_ratio;
    b.dt_s = h;
    b.iterations = mat.solid_iterations > 0 ? mat.solid_iterations : kDefaultIterations;
    double lambda = 0.0, mu = 0.0;
    fem::lame(mat.young_modulus_pa, mat.poisson_ratio, lambda, mu);

    b.grad.resize(12 * static_cast<size_t>(b.ntet));
    b.w_strain.resize(b.ntet);
    b.ncell = b.ntet / 6;
    b.w_volume.assign(b.ncell, 0.0);
    b.cell_nodes.assign(8 * static_cast<size_t>(b.ncell), -1);
    b.cell_grad.assign(24 * static_cast<size_t>(b.ncell), 0.0);
    b.mass.assign(b.nnode, 0.0);
    for (int32_t t = 0; t < b.ntet; ++t) {
      const int32_t* n = &b.tets[4 * t];
      Mat3 Dm;
      for (int a = 0; a < 3; ++a)
        for (int c = 0; c < 3; ++c) Dm(c, a) = b.rest[3 * n[a + 1] + c] - b.rest[3 * n[0] + c];
      const double vol = Dm.determinant() / 6.0;
      const Mat3 Di = Dm.inverse();
      double* g = &b.grad[12 * t];
      for (int c = 0; c < 3; ++c) {
        g[c] = -(Di(0, c) + Di(1, c) + Di(2, c));
        for (int a = 0; a < 3; ++a) g[3 * (a + 1) + c] = Di(a, c);
      }
      const double f = L.tet_fraction[t];
      b.w_strain[t] = 2.0 * mu * vol * f;
      b.w_volume[t / 6] += 3.0 * lambda * vol * f;
      for (int i = 0; i < 4; ++i) b.mass[n[i]] += 0.25 * vol * f;
      // the cell's mean gradient: 1/6 of each of its (equal-volume) tetrahedra's
      int32_t* cn = &b.cell_nodes[8 * (t / 6)];
      double* cg = &b.cell_grad[24 * (t / 6)];
      for (int i = 0; i < 4; ++i) {
        int slot = 0;
        while (cn[slot] >= 0 && cn[slot] != n[i]) ++slot;  // a cell has 8 nodes
        cn[slot] = n[i];
        for (int c = 0; c < 3; ++c) cg[3 * slot + c] += g[3 * i + c] / 6.0;
      }
    }
    const double organ_mass =
        mat.total_mass_kg > 0 ? mat.total_mass_kg : mat.density_kg_m3 * std::fabs(enclosed_volume(V, F));
    double msum = 0.0;
    for (double mi : b.mass) msum += mi;
    for (double& mi : b.mass) mi *= organ_mass / msum;

    // Rayleigh stiffness-proportional damping: zeta = beta omega / 2 at the lowest shear mode.
    b.omega1_rad_s = lowest_shear_mode(b);
    b.beta_s = b.omega1_rad_s > 0 ? 2.0 * b.damping_ratio / b.omega1_rad_s : 0.0;

    // System matrix.
    std::vector<double> w(b.ntet);
    for (int32_t t = 0; t < b.ntet; ++t) w[t] = b.w_strain[t] * (1.0 + b.beta_s / h);
    Triplets T;
    add_laplacian(b, w, T);
    add_cell_laplacian(b, T);
    double diag_max = 0.0;
    {
      std::vector<double> diag(b.nnode, 0.0);
      for (const auto& e : T)
        if (e.row() == e.col()) diag[e.row()] += e.value();
      for (int32_t i = 0; i < b.nnode; ++i) {
        diag[i] += b.mass[i] / (h * h);
        diag_max = std::max(diag_max, diag[i]);
      }
    }
    for (int32_t i = 0; i < b.nnode; ++i) T.emplace_back(i, i, b.mass[i] / (h * h));
    // Fixed surface vertices: zero-length anchors to their rest position, 1e3 times stiffer than
    // the stiffest node (their motion under a load is 1e-3 of the organ's).
    b.anchor_weight = std::max(1e4, 1e3 * diag_max);
    auto factor = std::make_shared<SolidFactor>();
    factor->base_rhs = Eigen::VectorXd::Zero(3 * static_cast<Eigen::Index>(b.nnode));
    b.node_anchored.assign(b.nnode, 0);
    for (int32_t v = 0; v < nv; ++v) {
      if (m.vert_inv_mass[r.vert_begin + v] > 0 || b.embed_tet[v] < 0) continue;
      ++b.nfixed;
      const int32_t* n = &b.tets[4 * b.embed_tet[v]];
      for (int i = 0; i < 4; ++i) b.node_anchored[n[i]] = 1;
      const double* bw = &b.embed_w[4 * v];
      for (int i = 0; i < 4; ++i) {
        for (int j = 0; j < 4; ++j) T.emplace_back(n[i], n[j], b.anchor_weight * bw[i] * bw[j]);
        for (int c = 0; c < 3; ++c) factor->base_rhs[c * b.nnode + n[i]] += b.anchor_weight * bw[i] * V[3 * v + c];
      }
    }
    // Connection springs to other organs, implicit on this organ's side (the other end held at
    // its start-of-step state, organs coupled Jacobi-style): (k + d/h) w w^T per endpoint. Explicit
    // forces were unstable above dt = 2 ms on CT-built sets (50 N/m on light organs).
    for (int32_t q = 0; q < m.nconn; ++q)
      for (const int32_t end : {m.conn_a[q], m.conn_b[q]}) {
        if (m.vert_organ[end] != o || b.embed_tet[end - r.vert_begin] < 0) continue;
        const int32_t* n = &b.tets[4 * b.embed_tet[end - r.vert_begin]];
        const double* bw = &b.embed_w[4 * (end - r.vert_begin)];
        const double kc = m.conn_k[q] + m.conn_d[q] / h;
        for (int i = 0; i < 4; ++i)
          for (int j = 0; j < 4; ++j) T.emplace_back(n[i], n[j], kc * bw[i] * bw[j]);
      }
    Eigen::SparseMatrix<double> A(b.nnode, b.nnode);
    A.setFromTriplets(T.begin(), T.end());
    factor->ldlt.compute(A);
    if (factor->ldlt.info() != Eigen::Success)
      throw InputError("organ " + r.name, "solid model: the lattice's system matrix could not be factorised");
    b.factor = factor;
    node_total += b.nnode;
    m.organ_solid[o] = static_cast<int32_t>(m.solids.size());
    m.solids.push_back(std::move(b));
  }
}

std::string solid_plan(const SolidBody& b) {
  char buf[400];
  std::snprintf(
      buf, sizeof buf,
      "lattice of %d nodes / %d tetrahedra (cell %.1f mm), corotational E = %g Pa, nu = %g, "
      "Rayleigh beta = %.3g s (damping ratio %g at %.1f Hz), %d local/global iterations, %d anchored vertices",
      b.nnode, b.ntet, 1e3 * b.spacing_m, b.young_modulus_pa, b.poisson_ratio, b.beta_s, b.damping_ratio,
      b.omega1_rad_s / (2 * M_PI), b.iterations, b.nfixed);
  return buf;
}

bool solid_vertex(const Model& m, int32_t v) { return !m.organ_solid.empty() && m.organ_solid[m.vert_organ[v]] >= 0; }

void init_solid_state(const Model& m, State& s) {
  size_t n = 0;
  for (const SolidBody& b : m.solids) n += 3 * static_cast<size_t>(b.nnode);
  s.solid_x.resize(n);
  s.solid_v.assign(n, 0.0);
  for (const SolidBody& b : m.solids) std::copy(b.rest.begin(), b.rest.end(), s.solid_x.begin() + 3 * b.node_begin);
}

std::vector<SolidWork> make_solid_work(const Model& m) {
  std::vector<SolidWork> out(m.solids.size());
  for (size_t i = 0; i < m.solids.size(); ++i) {
    const SolidBody& b = m.solids[i];
    SolidWork& w = out[i];
    const size_t n3 = 3 * static_cast<size_t>(b.nnode);
    w.q.assign(n3, 0.0), w.s.assign(n3, 0.0), w.rhs.assign(n3, 0.0), w.sol.assign(n3, 0.0), w.fext.assign(n3, 0.0);
    w.quat.resize(4 * static_cast<size_t>(b.ntet)), w.rot.resize(9 * static_cast<size_t>(b.ntet));
    w.cell_quat.resize(4 * static_cast<size_t>(b.ncell)), w.cell_rot.resize(9 * static_cast<size_t>(b.ncell));
    reset_rotations(w.quat.data(), w.rot.data(), b.ntet);
    reset_rotations(w.cell_quat.data(), w.cell_rot.data(), b.ncell);
    w.f_prev.assign(9 * static_cast<size_t>(b.ntet), 0.0);
    w.r_prev.assign(9 * static_cast<size_t>(b.ntet), 0.0);
    const size_t nv = static_cast<size_t>(m.organs[b.organ].vert_end - m.organs[b.organ].vert_begin);
    w.vol_p.assign(3 * nv, 0.0), w.vol_g.assign(3 * nv, 0.0), w.vol_gn.assign(n3 * b.npiece, 0.0),
        w.vol_u.assign(n3 * b.npiece, 0.0);
  }
  // Organs to the step's worker threads (make_work() starts min(threads, organs) of them when
  // there are two or more): largest lattice first onto the least loaded, by tetrahedra.
  const int threads = std::max(1, std::min<int>(m.threads, static_cast<int>(m.organs.size())));
  std::vector<size_t> order(out.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return m.solids[a].ntet > m.solids[b].ntet; });
  std::vector<int64_t> load(threads, 0);
  for (size_t i : order) {
    const int t = static_cast<int>(std::min_element(load.begin(), load.end()) - load.begin());
    out[i].thread = t;
    load[t] += m.solids[i].ntet;
  }
  return out;
}

// A held vertex whose tetrahedron has a node of an anchored tetrahedron gets no row (row -1): an
// exact hold one tetrahedron from an anchor (1e3 times stiffer than the lattice) demands a strain
// the lattice cannot take, and the organ's far side flew (a CT pancreas 9 mm thick, pushed 5 mm
// 1.9 mm from two anchors: a vertex 22 mm away moved 47 mm; pushed 20 mm, 120 mm). The
// attachment holds what is next to it; the tool holds the rest of the patch.
GraspRows grasp_rows(const SolidBody& b, const std::vector<int32_t>& local) {
  GraspRows g;
  g.row.resize(local.size());
  std::vector<int32_t> tet_row;  // tetrahedra of the held vertices, in order of first appearance
  auto at_anchor = [&](int32_t t) {
    for (int i = 0; i < 4; ++i)
      if (b.node_anchored[b.tets[4 * t + i]]) return true;
    return false;
  };
  for (size_t j = 0; j < local.size(); ++j) {
    const int32_t t = b.embed_tet[local[j]];
    if (at_anchor(t)) {
      g.row[j] = -1;
      continue;
    }
    const auto it = std::find(tet_row.begin(), tet_row.end(), t);
    g.row[j] = static_cast<int32_t>(it - tet_row.begin());
    if (it == tet_row.end()) tet_row.push_back(t);
  }
  g.rows = static_cast<int32_t>(tet_row.size());
  std::vector<int32_t> count(tet_row.size(), 0);
  for (int32_t r : g.row)
    if (r >= 0) ++count[r];
  g.share.resize(local.size());
  for (size_t j = 0; j < local.size(); ++j) g.share[j] = g.row[j] < 0 ? 0.0 : 1.0 / count[g.row[j]];
  return g;
}

bool grasp_schur(const SolidBody& b, const std::vector<int32_t>& local, const GraspRows& g, Eigen::MatrixXd& Z,
                 Eigen::MatrixXd& L) {
  const int32_t k = g.rows;
  if (k == 0) {  // every held vertex sits at an anchor: nothing to hold
    Z.resize(b.nnode, 0);
    L.resize(0, 0);
    return true;
  }
  Eigen::MatrixXd Ct = Eigen::MatrixXd::Zero(b.nnode, k);
  for (size_t j = 0; j < local.size(); ++j) {
    if (g.row[j] < 0) continue;
    const int32_t* n = &b.tets[4 * b.embed_tet[local[j]]];
    for (int i = 0; i < 4; ++i) Ct(n[i], g.row[j]) += g.share[j] * b.embed_w[4 * local[j] + i];
  }
  Z = b.factor->ldlt.solve(Ct);
  Eigen::MatrixXd S = Ct.transpose() * Z;
  const double eps = 1e-10 * S.diagonal().maxCoeff();
  S.diagonal().array() += eps;
  const Eigen::LLT<Eigen::MatrixXd> llt(S);
  L = llt.matrixL();
  return llt.info() == Eigen::Success;
}

double solid_surface_update(const Model& m, const SolidBody& b, State& s) {
  const OrganRange& r = m.organs[b.organ];
  const double* X = s.solid_x.data() + 3 * static_cast<size_t>(b.node_begin);
  const double* Vn = s.solid_v.data() + 3 * static_cast<size_t>(b.node_begin);
  double max_speed2 = 0.0;
  for (int32_t v = r.vert_begin; v < r.vert_end; ++v) {
    const int32_t t = b.embed_tet[v - r.vert_begin];
    if (t < 0) continue;
    const int32_t* n = &b.tets[4 * t];
    const double* bw = &b.embed_w[4 * (v - r.vert_begin)];
    double p[3] = {0, 0, 0}, u[3] = {0, 0, 0};
    for (int i = 0; i < 4; ++i)
      for (int c = 0; c < 3; ++c) p[c] += bw[i] * X[3 * n[i] + c], u[c] += bw[i] * Vn[3 * n[i] + c];
    s.x[v] = p[0], s.y[v] = p[1], s.z[v] = p[2];
    s.vx[v] = u[0], s.vy[v] = u[1], s.vz[v] = u[2];
    max_speed2 = std::max(max_speed2, u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
  }
  return max_speed2;
}

namespace {

// Position and velocity of global vertex v: solid organs' from their lattice, others' from the state.
void vertex_state(const Model& m, const State& s, int32_t v, double p[3], double u[3]) {
  const int32_t o = m.vert_organ[v];
  const int32_t si = m.organ_solid[o];
  const int32_t t = si >= 0 ? m.solids[si].embed_tet[v - m.organs[o].vert_begin] : -1;
  if (t < 0) {
    p[0] = s.x[v], p[1] = s.y[v], p[2] = s.z[v];
    u[0] = s.vx[v], u[1] = s.vy[v], u[2] = s.vz[v];
    return;
  }
  const SolidBody& b = m.solids[si];
  const int32_t* n = &b.tets[4 * t];
  const double* w = &b.embed_w[4 * (v - m.organs[o].vert_begin)];
  const double* X = s.solid_x.data() + 3 * static_cast<size_t>(b.node_begin);
  const double* V = s.solid_v.data() + 3 * static_cast<size_t>(b.node_begin);
  for (int c = 0; c < 3; ++c) {
    p[c] = u[c] = 0.0;
    for (int i = 0; i < 4; ++i) p[c] += w[i] * X[3 * n[i] + c], u[c] += w[i] * V[3 * n[i] + c];
  }
}

// Spreads a force on organ vertex v (local index) to its tetrahedron's nodes.
void spread(const SolidBody& b, int32_t v, const double f[3], std::vector<double>& fext) {
  const int32_t t = b.embed_tet[v];
  if (t < 0) return;
  const int32_t* n = &b.tets[4 * t];
  const double* w = &b.embed_w[4 * v];
  for (int i = 0; i < 4; ++i)
    for (int c = 0; c < 3; ++c) fext[3 * n[i] + c] += w[i] * f[c];
}

// The tool's hold on this organ: one exact constraint per lattice tetrahedron that holds grasped
// vertices, on the mean position of those vertices (grasp_rows), Z = A^-1 C^T and the Cholesky
// factor of S = C Z. Not one constraint per vertex: four or more held vertices in a tetrahedron
// fix it whole, the held region grew to every cell the patch touches, and the grasp was 2.6-2.9x
// stiffer than the FEM reference's (docs/physics.md, "The grasp"). Each row's multiplier reaches
// the nodes as the consistent load of its vertices: spread evenly over them.
void prepare_grasp(const SolidBody& b, SolidWork& w, const std::vector<int32_t>& local) {
  w.grasp_verts = local;
  w.grasp = grasp_rows(b, local);
  const int32_t k = w.grasp.rows;
  Eigen::MatrixXd Z, Lf;
  grasp_schur(b, local, w.grasp, Z, Lf);
  w.grasp_z.assign(Z.data(), Z.data() + Z.size());
  w.grasp_chol.assign(Lf.data(), Lf.data() + Lf.size());
  w.grasp_lambda.assign(3 * static_cast<size_t>(k), 0.0);
  w.grasp_target.assign(3 * static_cast<size_t>(k), 0.0);
  w.grasp_rhs.assign(3 * static_cast<size_t>(k), 0.0);
  w.vol_res.assign(3 * static_cast<size_t>(k) * b.npiece, 0.0);
}

// The hold's exact constraints on the columns of X (one row per lattice node): with C the rows of
// prepare_grasp, res = target - C X (no target: -C X), then X += Z S^-1 res (Z = A^-1 C^T,
// S = C Z = Lc Lc^T). On return res holds the multipliers S^-1 res (the solve's reaction).
// res: k x X.cols(), column-major scratch.
template <class Nodes>
void grasp_project(const SolidBody& b, const SolidWork& w, Nodes& X, Eigen::Map<Eigen::MatrixXd>& res,
                   const double* target) {
  const int32_t k = w.grasp_active;
  for (int32_t r = 0; r < k; ++r)
    for (Eigen::Index col = 0; col < X.cols(); ++col) res(r, col) = target ? target[3 * r + col] : 0.0;
  for (size_t j = 0; j < w.grasp_verts.size(); ++j) {
    const int32_t v = w.grasp_verts[j];
    if (w.grasp.row[j] < 0) continue;  // at an anchor: not held
    const int32_t* nd = &b.tets[4 * b.embed_tet[v]];
    for (Eigen::Index col = 0; col < X.cols(); ++col) {
      double x = 0.0;
      for (int i = 0; i < 4; ++i) x += b.embed_w[4 * v + i] * X(nd[i], col);
      res(w.grasp.row[j], col) -= w.grasp.share[j] * x;
    }
  }
  const Eigen::Map<const Eigen::MatrixXd> Z(w.grasp_z.data(), b.nnode, k);
  const Eigen::Map<const Eigen::MatrixXd> Lc(w.grasp_chol.data(), k, k);
  Lc.triangularView<Eigen::Lower>().solveInPlace(res);
  Lc.transpose().triangularView<Eigen::Upper>().solveInPlace(res);
  X.noalias() += Z * res;
}

// The enclosed volume of each closed piece of the organ's surface as an exact constraint of the
// step (003 eq 25 to 003 eq 30 on the embedded surface, C_p = V_p(q) - V_p0 with the node gradients
// G of embedded_volume): the step's minimiser moved within span(U), U = A^-1 G (A the step's
// matrix: the correction spreads through the lattice as the elastic response to a pressure would,
// not vertex by vertex), U first made to leave the held vertices where they are through the
// grasp's Schur complement, then q -= U (G^T U)^-1 C. Once per step, after the local/global
// iterations; no node moves more than 1 cell per step. The cells' mean dilatation keeps the
// lattice's volume, but a thin organ's surface runs through partly filled cells whose tetrahedra
// do not each keep theirs (CT vessels changed by -6 % to +6 % under a 30 mm pull). One constraint
// per piece: with one for the organ, the portal vein's 90-face second piece took up its large
// piece's change and did not come back (2.9 mm residual).
void keep_volume(const Model& m, const SolidBody& b, SolidWork& w) {
  const int32_t P = b.npiece;
  if (P == 0) return;
  double C[kMaxVolumePieces];
  embedded_volume(m, b, w.q.data(), w.vol_p, w.vol_g, w.vol_gn, C);
  double cmax = 0.0;
  for (int32_t p = 0; p < P; ++p) {
    C[p] = volume_excess(C[p], b.piece_rest_volume[p]);
    if (!std::isfinite(C[p])) return;
    cmax = std::max(cmax, std::fabs(C[p]));
  }
  if (cmax == 0.0) return;
  const Eigen::Index n = b.nnode;
  Eigen::Map<Eigen::MatrixXd> U(w.vol_u.data(), n, 3 * P);  // column 3p + c: piece p, coordinate c
  for (int32_t p = 0; p < P; ++p)
    for (Eigen::Index i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) U(i, 3 * p + c) = w.vol_gn[(p * n + i) * 3 + c];
  U = b.factor->ldlt.solve(U);
  if (w.grasp_active > 0) {  // U leaves the held vertices where they are
    Eigen::Map<Eigen::MatrixXd> res(w.vol_res.data(), w.grasp_active, 3 * P);
    grasp_project(b, w, U, res, nullptr);
  }
  using Small = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxVolumePieces, kMaxVolumePieces>;
  using SmallVec = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxVolumePieces, 1>;
  Small M(P, P);
  SmallVec rhs(P);
  for (int32_t p = 0; p < P; ++p) {
    rhs(p) = C[p];
    for (int32_t q = 0; q < P; ++q) {
      double x = 0.0;
      for (Eigen::Index i = 0; i < n; ++i)
        for (int c = 0; c < 3; ++c) x += w.vol_gn[(p * n + i) * 3 + c] * U(i, 3 * q + c);
      M(p, q) = x;
    }
  }
  for (int32_t p = 0; p < P; ++p)  // a piece the grasp holds entirely cannot change: no constraint
    if (!(M(p, p) > 1e-12 * M.diagonal().cwiseAbs().maxCoeff()))
      M.row(p).setZero(), M.col(p).setZero(), M(p, p) = 1.0, rhs(p) = 0.0;
  const SmallVec lambda = M.ldlt().solve(rhs);
  if (!lambda.allFinite()) return;
  double step2 = 0.0;
  for (Eigen::Index i = 0; i < n; ++i) {
    double d[3] = {0, 0, 0};
    for (int32_t p = 0; p < P; ++p)
      for (int c = 0; c < 3; ++c) d[c] += lambda(p) * U(i, 3 * p + c);
    step2 = std::max(step2, d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  }
  const double cap = kVolumeStep * b.spacing_m;
  const double scale = step2 > cap * cap ? cap / std::sqrt(step2) : 1.0;
  for (Eigen::Index i = 0; i < n; ++i)
    for (int32_t p = 0; p < P; ++p)
      for (int c = 0; c < 3; ++c) w.q[3 * i + c] -= scale * lambda(p) * U(i, 3 * p + c);
}

// One awake solid organ's step from its loads (w.fext, the grasp targets): local/global
// iterations, velocities, the surface vertices. Touches only this organ's nodes, vertices and
// scratch, so organs run in parallel.
void solve_body(const Model& m, const SolidBody& b, SolidWork& w, State& s) {
  const double h = m.dt_s;
  double* X = s.solid_x.data() + 3 * static_cast<size_t>(b.node_begin);
  double* Vn = s.solid_v.data() + 3 * static_cast<size_t>(b.node_begin);
  const size_t n3 = 3 * static_cast<size_t>(b.nnode);
  const int32_t k = w.grasp_active;
  w.out_reaction[0] = w.out_reaction[1] = w.out_reaction[2] = 0.0;
  w.out_max_speed2 = 0.0;

  // Inertial prediction; deformation and rotation at the start of the step (the rotation
  // warm-started from the last local step's, one fit iteration).
  for (size_t i = 0; i < n3; ++i) w.s[i] = X[i] + h * Vn[i], w.q[i] = w.s[i];
  for (int32_t t = 0; t < b.ntet; ++t) {
    const Mat3 F = deformation(b, t, X);
    rotation_fit(F, &w.quat[4 * t], &w.rot[9 * t], kRotationIterations);
    Eigen::Map<Mat3>(&w.f_prev[9 * t]) = F;
    std::copy(&w.rot[9 * t], &w.rot[9 * t] + 9, &w.r_prev[9 * t]);
  }
  const double inv_h2 = 1.0 / (h * h);
  Eigen::Map<ColMatX3> sol(w.sol.data(), b.nnode, 3);
  for (int it = 0; it < b.iterations; ++it) {
    // local step: the constraint projections, summed into the right-hand side (column-major)
    for (int32_t i = 0; i < b.nnode; ++i)
      for (int c = 0; c < 3; ++c)
        w.sol[c * b.nnode + i] =
            b.factor->base_rhs[c * b.nnode + i] + b.mass[i] * inv_h2 * w.s[3 * i + c] + w.fext[3 * i + c];
    for (int32_t t = 0; t < b.ntet; ++t) {
      const Mat3 F = deformation(b, t, w.q.data());
      rotation_fit(F, &w.quat[4 * t], &w.rot[9 * t], kRotationIterations);
      const Eigen::Map<const Mat3> R(&w.rot[9 * t]);
      const double wd = b.w_strain[t] * b.beta_s / h;
      const Mat3 Y = b.w_strain[t] * R +
                     wd * (Eigen::Map<const Mat3>(&w.f_prev[9 * t]) + R - Eigen::Map<const Mat3>(&w.r_prev[9 * t]));
      add_element_rhs(&b.tets[4 * t], &b.grad[12 * t], 4, Y, b.nnode, w.sol.data());
    }
    for (int32_t cl = 0; cl < b.ncell; ++cl) {  // the cells' volume projections
      const Mat3 F = cell_deformation(b, cl, w.q.data());
      rotation_fit(F, &w.cell_quat[4 * cl], &w.cell_rot[9 * cl], kRotationIterations);
      const Eigen::Map<const Mat3> R(&w.cell_rot[9 * cl]);
      const Mat3 Y = b.w_volume[cl] * (F + volume_shift(R.transpose() * F) * R);
      add_element_rhs(&b.cell_nodes[8 * cl], &b.cell_grad[24 * cl], 8, Y, b.nnode, w.sol.data());
    }
    // global step: one prefactored solve, then the held vertices' exact constraints
    sol = b.factor->ldlt.solve(sol);
    if (k > 0) {
      Eigen::Map<Eigen::MatrixXd> lam(w.grasp_rhs.data(), k, 3);
      grasp_project(b, w, sol, lam, w.grasp_target.data());
      if (it + 1 == b.iterations)
        for (int32_t j = 0; j < k; ++j)
          for (int c = 0; c < 3; ++c) w.grasp_lambda[3 * j + c] = lam(j, c), w.out_reaction[c] -= lam(j, c);
    }
    for (int32_t i = 0; i < b.nnode; ++i)
      for (int c = 0; c < 3; ++c) w.q[3 * i + c] = sol(i, c);
  }
  keep_volume(m, b, w);
  double checksum = 0.0;
  for (size_t i = 0; i < n3; ++i) {
    Vn[i] = (w.q[i] - X[i]) / h;
    X[i] = w.q[i];
    checksum += X[i] + Vn[i];
  }
  if (!std::isfinite(checksum)) {  // cannot happen with finite input; keep the state usable
    std::copy(b.rest.begin(), b.rest.end(), X);
    std::fill(Vn, Vn + n3, 0.0);
    reset_rotations(w.quat.data(), w.rot.data(), b.ntet);
    reset_rotations(w.cell_quat.data(), w.cell_rot.data(), b.ncell);
    w.grasp_verts.clear();
  }
  w.out_checksum = checksum;
  w.out_max_speed2 = solid_surface_update(m, b, s);  // surface vertices follow the lattice
}

struct SolveJob {
  const Model* m;
  State* s;
  Work* work;
};

void solve_job(void* context, int thread) {
  const SolveJob& j = *static_cast<const SolveJob*>(context);
  for (size_t bi = 0; bi < j.m->solids.size(); ++bi) {
    SolidWork& w = j.work->solid[bi];
    if (w.thread == thread && w.active) solve_body(*j.m, j.m->solids[bi], w, *j.s);
  }
}

}  // namespace

SolidStats solid_step(const Model& m, State& s, Work& work) {
  SolidStats st;
  if (m.solids.empty()) return st;
  ToolState& tool = s.tool;
  std::array<double, 3> reaction{0, 0, 0};
  if (tool.mode == ToolMode::attach && !tool.verts.empty()) engine::attach_targets(m, s, work, 1.0);  // tool.cpp
  // Loads of every organ at the start-of-step positions (connection springs read both organs'
  // positions, so all loads are gathered before any organ moves).
  for (size_t bi = 0; bi < m.solids.size(); ++bi) {
    const SolidBody& b = m.solids[bi];
    SolidWork& w = work.solid[bi];
    const OrganRange& r = m.organs[b.organ];
    w.active = s.organ_awake[b.organ] != 0;
    w.grasp_active = 0;
    if (!w.active) {  // asleep: no work
      double* Vn = s.solid_v.data() + 3 * static_cast<size_t>(b.node_begin);
      std::fill(Vn, Vn + 3 * static_cast<size_t>(b.nnode), 0.0);
      continue;
    }
    std::fill(w.fext.begin(), w.fext.end(), 0.0);
    if (m.gravity)
      for (int32_t i = 0; i < b.nnode; ++i)
        for (int c = 0; c < 3; ++c) w.fext[3 * i + c] += b.mass[i] * m.gravity_m_s2[c];
    // Connection springs, the implicit half (the matrix holds (k + d/h) w w^T): the endpoint is
    // drawn to p = x_other - l0 u (Liu et al. 2013's spring projection, u at the start of the
    // step) with stiffness k, and to x_n + h v_other with d/h (damping of the relative velocity).
    for (int32_t q = 0; q < m.nconn; ++q) {
      const int32_t a = m.conn_a[q], c = m.conn_b[q];
      for (int side = 0; side < 2; ++side) {
        const int32_t self = side == 0 ? a : c, other = side == 0 ? c : a;
        if (m.vert_organ[self] != b.organ) continue;
        double ps[3], us[3], po[3], uo[3];
        vertex_state(m, s, self, ps, us);
        vertex_state(m, s, other, po, uo);
        const double d[3] = {ps[0] - po[0], ps[1] - po[1], ps[2] - po[2]};
        const double l = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        const double sc = l > 0 ? m.conn_rest[q] / l : 0.0;
        const double kd = m.conn_d[q] / m.dt_s;
        double f[3];
        for (int k = 0; k < 3; ++k)
          f[k] = m.conn_k[q] * (po[k] + m.dt_s * uo[k] + sc * d[k]) + kd * (ps[k] + m.dt_s * uo[k]);
        spread(b, self - r.vert_begin, f, w.fext);
      }
    }
    bool holds = false;
    if (tool.mode == ToolMode::force && !tool.verts.empty()) {
      double Fv[3] = {tool.force_N[0], tool.force_N[1], tool.force_N[2]};
      const double mag = std::sqrt(Fv[0] * Fv[0] + Fv[1] * Fv[1] + Fv[2] * Fv[2]);
      if (m.guard && mag > m.max_tool_force_N)
        for (double& f : Fv) f *= m.max_tool_force_N / mag;
      const double share = 1.0 / static_cast<double>(tool.verts.size());
      const double fs[3] = {Fv[0] * share, Fv[1] * share, Fv[2] * share};
      for (int32_t v : tool.verts)
        if (m.vert_organ[v] == b.organ) {
          spread(b, v - r.vert_begin, fs, w.fext);
          for (int c = 0; c < 3; ++c) reaction[c] -= fs[c];
          holds = true;
        }
    } else if (tool.mode == ToolMode::attach && !tool.verts.empty()) {
      // Held vertices of this organ, in tool order; a new set rebuilds the Schur complement.
      bool same = true;
      int32_t count = 0;
      for (int32_t v : tool.verts)
        if (m.vert_organ[v] == b.organ) {
          same = same && count < static_cast<int32_t>(w.grasp_verts.size()) && w.grasp_verts[count] == v - r.vert_begin;
          ++count;
        }
      same = same && count == static_cast<int32_t>(w.grasp_verts.size());
      if (count > 0 && !same) {
        std::vector<int32_t> local;
        for (int32_t v : tool.verts)
          if (m.vert_organ[v] == b.organ) local.push_back(v - r.vert_begin);
        prepare_grasp(b, w, local);
      }
      if (count > 0) {  // each row's target: the mean of its vertices' targets
        std::fill(w.grasp_target.begin(), w.grasp_target.end(), 0.0);
        int32_t j = 0;
        for (size_t q = 0; q < tool.verts.size(); ++q)
          if (m.vert_organ[tool.verts[q]] == b.organ) {
            if (w.grasp.row[j] >= 0)
              for (int c = 0; c < 3; ++c)
                w.grasp_target[3 * w.grasp.row[j] + c] += w.grasp.share[j] * work.tool_target[3 * q + c];
            ++j;
          }
        w.grasp_active = w.grasp.rows;
        holds = true;
      }
    }
    st.reaction = st.reaction || holds;
  }
  // The organs' solves, in parallel on the step's worker threads when there are any.
  SolveJob job{&m, &s, &work};
  if (work.workers && work.workers->threads() > 1)
    work.workers->run(solve_job, &job);
  else
    for (size_t bi = 0; bi < m.solids.size(); ++bi)
      if (work.solid[bi].active) solve_body(m, m.solids[bi], work.solid[bi], s);
  for (size_t bi = 0; bi < m.solids.size(); ++bi) {
    const SolidWork& w = work.solid[bi];
    if (!w.active) continue;
    st.max_speed2 = std::max(st.max_speed2, w.out_max_speed2);
    if (!std::isfinite(w.out_checksum))
      st.checksum = NAN;
    else if (std::isfinite(st.checksum))
      st.checksum += w.out_checksum;
    for (int c = 0; c < 3; ++c) reaction[c] += w.out_reaction[c];
  }
  if (st.reaction) tool.reaction_N = reaction;
  return st;
}

void solid_restore_volume(const Model& m, const SolidBody& b, SolidWork& w, State& s, const double* node_acc) {
  if (b.npiece == 0) return;
  double* X = s.solid_x.data() + 3 * static_cast<size_t>(b.node_begin);
  double C[kMaxVolumePieces];
  embedded_volume(m, b, X, w.vol_p, w.vol_g, w.vol_gn, C);
  const size_t n3 = 3 * static_cast<size_t>(b.nnode);
  const double cap = kVolumeGiveBack * b.spacing_m;
  auto moved_by_contact = [&](int32_t i) { return node_acc[4 * static_cast<size_t>(b.node_begin + i) + 3] > 0; };
  for (int32_t p = 0; p < b.npiece; ++p) {
    const double c = volume_excess(C[p], b.piece_rest_volume[p]);
    const double* G = w.vol_gn.data() + p * n3;
    // One pass: the denominator sum |G_i|^2 / m_i and the largest |G_i|^2 / m_i^2 (the step cap).
    double denom = 0.0, g2m2 = 0.0;
    for (int32_t i = 0; i < b.nnode; ++i) {
      if (moved_by_contact(i)) continue;
      const double g2 = G[3 * i] * G[3 * i] + G[3 * i + 1] * G[3 * i + 1] + G[3 * i + 2] * G[3 * i + 2];
      denom += g2 / b.mass[i];
      g2m2 = std::max(g2m2, g2 / (b.mass[i] * b.mass[i]));
    }
    if (!(denom > 0.0) || !std::isfinite(c)) continue;
    double lambda = c / denom;
    const double step2 = lambda * lambda * g2m2;
    if (step2 > cap * cap) lambda *= cap / std::sqrt(step2);
    for (int32_t i = 0; i < b.nnode; ++i) {
      if (moved_by_contact(i)) continue;
      for (int k = 0; k < 3; ++k) X[3 * i + k] -= lambda * G[3 * i + k] / b.mass[i];
    }
  }
}

double solid_energy(const Model& m, const State& s) {
  double e = 0.0;
  for (const SolidBody& b : m.solids) {
    const double* X = s.solid_x.data() + 3 * static_cast<size_t>(b.node_begin);
    const double* Vn = s.solid_v.data() + 3 * static_cast<size_t>(b.node_begin);
    for (int32_t i = 0; i < b.nnode; ++i)
      e += 0.5 * b.mass[i] * (Vn[3 * i] * Vn[3 * i] + Vn[3 * i + 1] * Vn[3 * i + 1] + Vn[3 * i + 2] * Vn[3 * i + 2]);
    const auto rotation = [](const Mat3& F) {
      Eigen::JacobiSVD<Mat3> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
      Mat3 U = svd.matrixU(), W = svd.matrixV();
      if ((U * W.transpose()).determinant() < 0) U.col(2) *= -1.0;
      return Mat3(U * W.transpose());
    };
    for (int32_t t = 0; t < b.ntet; ++t) {
      const Mat3 F = deformation(b, t, X);
      e += 0.5 * b.w_strain[t] * (F - rotation(F)).squaredNorm();
    }
    for (int32_t c = 0; c < b.ncell; ++c) {
      const Mat3 F = cell_deformation(b, c, X);
      const double tv = volume_shift(rotation(F).transpose() * F);  // |F - (F + t R)|^2 = 3 t^2
      e += 0.5 * b.w_volume[c] * 3.0 * tv * tv;
    }
    if (m.gravity)
      for (int32_t i = 0; i < b.nnode; ++i)
        for (int c = 0; c < 3; ++c) e -= b.mass[i] * m.gravity_m_s2[c] * (X[3 * i + c] - b.rest[3 * i + c]);
    const OrganRange& r = m.organs[b.organ];
    // anchors of the fixed vertices
    for (int32_t v = r.vert_begin; v < r.vert_end; ++v) {
      if (m.vert_inv_mass[v] > 0) continue;
      const int32_t t = b.embed_tet[v - r.vert_begin];
      if (t < 0) continue;
      const int32_t* n = &b.tets[4 * t];
      const double* bw = &b.embed_w[4 * (v - r.vert_begin)];
      const double rest[3] = {m.vert_rest_x[v], m.vert_rest_y[v], m.vert_rest_z[v]};
      for (int c = 0; c < 3; ++c) {
        double p = 0.0;
        for (int i = 0; i < 4; ++i) p += bw[i] * X[3 * n[i] + c];
        e += 0.5 * b.anchor_weight * (p - rest[c]) * (p - rest[c]);
      }
    }
  }
  return e;
}

}  // namespace softatlas::sim
