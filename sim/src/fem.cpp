// Tetrahedral FEM reference (see fem.hpp). Linear tetrahedra, constant strain per element.
//
// Element stiffness (linear isotropic elasticity, W = mu eps:eps + lambda/2 tr(eps)^2, with
// g_i the gradient of the shape function of node i and V the rest volume):
//   K_ij = V (lambda g_i g_j^T + mu g_j g_i^T + mu (g_i . g_j) I)              (3x3 block)
// which is also the node/edge tensor of the tensor-mass model (Delingette et al. 1999; paper 002
// eq 10 for triangles). Corotational: f_e = -R K_e (R^T x - X) with R the rotation of the polar
// decomposition of the deformation gradient F = Ds Dm^-1 (Mueller & Gross 2004).
#include "softatlas/sim/fem.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <unordered_map>

#include "fem_common.hpp"
#include "softatlas/sim/error.hpp"

namespace softatlas::sim::fem {

namespace {

using namespace detail;  // Mat3, Vec3, node(), box_size()

using Mat12 = Eigen::Matrix<double, 12, 12>;
using Vec12 = Eigen::Matrix<double, 12, 1>;

Mat3 dm_inv(const Model& m, int32_t t) {
  return Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(&m.tet_dm_inv[9 * t]);
}

Eigen::Map<const Eigen::Matrix<double, 12, 12, Eigen::RowMajor>> stiffness(const Model& m, int32_t t) {
  return Eigen::Map<const Eigen::Matrix<double, 12, 12, Eigen::RowMajor>>(&m.tet_stiffness[144 * t]);
}

// Rotation of the polar decomposition F = R S; inverted elements get det R = +1 by flipping the
// direction of the smallest singular value (Irving et al. 2004).
Mat3 rotation_of(const Mat3& F) {
  Eigen::JacobiSVD<Mat3> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Mat3 U = svd.matrixU();
  const Mat3 V = svd.matrixV();
  if ((U * V.transpose()).determinant() < 0.0) U.col(2) *= -1.0;
  return U * V.transpose();
}

Mat3 tet_rotation(const Model& m, int32_t t, const std::vector<double>& x) {
  if (m.material.elasticity == Elasticity::linear) return Mat3::Identity();
  const int32_t* n = &m.tets[4 * t];
  Mat3 Ds;
  const Vec3 x0 = node(x, n[0]);
  for (int c = 0; c < 3; ++c) Ds.col(c) = node(x, n[c + 1]) - x0;
  return rotation_of(Ds * dm_inv(m, t));
}

// Rotated displacement u_R = R^T x - X of the 4 nodes.
Vec12 rotated_displacement(const Model& m, int32_t t, const Mat3& R, const std::vector<double>& x) {
  const int32_t* n = &m.tets[4 * t];
  Vec12 u;
  for (int a = 0; a < 4; ++a) u.segment<3>(3 * a) = R.transpose() * node(x, n[a]) - node(m.rest, n[a]);
  return u;
}

// Free-DOF numbering: -1 for prescribed DOFs.
std::vector<int32_t> free_dofs(const Load& load, int32_t& nfree) {
  std::vector<int32_t> map(load.dof_fixed.size(), -1);
  nfree = 0;
  for (size_t d = 0; d < map.size(); ++d)
    if (!load.dof_fixed[d]) map[d] = nfree++;
  return map;
}

// Assembles a * M + b * K_T (K_T = R K R^T per element at x) over free DOFs.
Eigen::SparseMatrix<double> assemble(const Model& m, const std::vector<double>& x, const std::vector<int32_t>& dof,
                                     int32_t nfree, double a, double b) {
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(static_cast<size_t>(m.ntet) * 144 + static_cast<size_t>(m.nnode) * 3);
  for (int32_t t = 0; t < m.ntet; ++t) {
    const Mat3 R = tet_rotation(m, t, x);
    const auto K = stiffness(m, t);
    const int32_t* n = &m.tets[4 * t];
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) {
        const Mat3 blk = b * R * K.block<3, 3>(3 * i, 3 * j) * R.transpose();
        for (int r = 0; r < 3; ++r) {
          const int32_t gr = dof[3 * n[i] + r];
          if (gr < 0) continue;
          for (int c = 0; c < 3; ++c) {
            const int32_t gc = dof[3 * n[j] + c];
            if (gc >= 0) trip.emplace_back(gr, gc, blk(r, c));
          }
        }
      }
  }
  if (a != 0.0)
    for (int32_t i = 0; i < m.nnode; ++i)
      for (int r = 0; r < 3; ++r)
        if (dof[3 * i + r] >= 0) trip.emplace_back(dof[3 * i + r], dof[3 * i + r], a * m.node_mass[i]);
  Eigen::SparseMatrix<double> A(nfree, nfree);
  A.setFromTriplets(trip.begin(), trip.end());
  return A;
}

// y = K_T v over all DOFs (K_T at x), used for Rayleigh damping and the h K v term.
void stiffness_times(const Model& m, const std::vector<double>& x, const std::vector<double>& v,
                     std::vector<double>& y) {
  y.assign(v.size(), 0.0);
  for (int32_t t = 0; t < m.ntet; ++t) {
    const Mat3 R = tet_rotation(m, t, x);
    const int32_t* n = &m.tets[4 * t];
    Vec12 vr;
    for (int a = 0; a < 4; ++a) vr.segment<3>(3 * a) = R.transpose() * node(v, n[a]);
    const Vec12 k = stiffness(m, t) * vr;
    for (int a = 0; a < 4; ++a) {
      const Vec3 ya = R * k.segment<3>(3 * a);
      for (int c = 0; c < 3; ++c) y[3 * n[a] + c] += ya[c];
    }
  }
}

[[noreturn]] void bad(const std::string& where, const std::string& what) { throw InputError(where, what); }

}  // namespace

const char* to_string(Elasticity e) { return e == Elasticity::linear ? "linear" : "corotational"; }

void lame(double young_modulus, double poisson_ratio, double& lambda, double& mu) {
  lambda = young_modulus * poisson_ratio / ((1.0 + poisson_ratio) * (1.0 - 2.0 * poisson_ratio));
  mu = young_modulus / (2.0 * (1.0 + poisson_ratio));
}

// ---- meshes ------------------------------------------------------------------------------------

TetMesh read_gmsh(const std::string& path, double scale) {
  std::ifstream in(path);
  if (!in) bad(path, "cannot open the file (expected a Gmsh .msh mesh)");
  std::string line;
  int lineno = 0;
  auto next = [&](std::string& out) {
    if (!std::getline(in, out)) return false;
    ++lineno;
    if (!out.empty() && out.back() == '\r') out.pop_back();
    return true;
  };
  auto where = [&]() { return path + ":" + std::to_string(lineno); };
  std::unordered_map<long, int32_t> id_to_index;
  std::vector<double> raw_nodes;
  std::vector<long> raw_tets;
  bool saw_nodes = false, saw_elements = false;
  int version = 0;
  while (next(line)) {
    if (line == "$MeshFormat") {
      if (!next(line)) bad(where(), "unexpected end of file in $MeshFormat");
      std::istringstream ss(line);
      double v = 0;
      int file_type = 0;
      ss >> v >> file_type;
      if (!ss || v < 2.0 || v >= 3.0) bad(where(), "expected Gmsh format 2.x, got '" + line + "'");
      if (file_type != 0) bad(where(), "binary Gmsh files are not supported (expected ASCII)");
      version = 2;
    } else if (line == "$NOD" || line == "$Nodes") {
      if (line == "$NOD") version = 1;
      if (!next(line)) bad(where(), "unexpected end of file, expected the node count");
      long count = -1;
      std::istringstream(line) >> count;
      if (count <= 0) bad(where(), "expected a positive node count, got '" + line + "'");
      for (long i = 0; i < count; ++i) {
        if (!next(line)) bad(where(), "unexpected end of file inside the node list");
        std::istringstream ss(line);
        long id;
        double x, y, z;
        if (!(ss >> id >> x >> y >> z)) bad(where(), "expected 'id x y z', got '" + line + "'");
        if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) bad(where(), "non-finite node coordinate");
        if (!id_to_index.emplace(id, static_cast<int32_t>(raw_nodes.size() / 3)).second)
          bad(where(), "duplicate node id " + std::to_string(id));
        raw_nodes.insert(raw_nodes.end(), {x * scale, y * scale, z * scale});
      }
      saw_nodes = true;
    } else if (line == "$ELM" || line == "$Elements") {
      if (!next(line)) bad(where(), "unexpected end of file, expected the element count");
      long count = -1;
      std::istringstream(line) >> count;
      if (count < 0) bad(where(), "expected an element count, got '" + line + "'");
      for (long i = 0; i < count; ++i) {
        if (!next(line)) bad(where(), "unexpected end of file inside the element list");
        std::istringstream ss(line);
        long id, type;
        if (!(ss >> id >> type)) bad(where(), "expected 'id type ...', got '" + line + "'");
        long nnodes = 0;
        if (version == 1) {
          long reg_phys, reg_elem;
          if (!(ss >> reg_phys >> reg_elem >> nnodes)) bad(where(), "expected 'id type phys elem n nodes...'");
        } else {
          long ntags;
          if (!(ss >> ntags) || ntags < 0) bad(where(), "expected the tag count");
          for (long k = 0; k < ntags; ++k) {
            long tag;
            if (!(ss >> tag)) bad(where(), "expected " + std::to_string(ntags) + " tags");
          }
          nnodes = type == 4 ? 4 : 0;
        }
        if (type != 4) continue;  // only 4-node tetrahedra
        if (nnodes != 4) bad(where(), "tetrahedron with " + std::to_string(nnodes) + " nodes (expected 4)");
        for (int k = 0; k < 4; ++k) {
          long nid;
          if (!(ss >> nid)) bad(where(), "expected 4 node ids for the tetrahedron");
          raw_tets.push_back(nid);
        }
      }
      saw_elements = true;
    }
  }
  if (!saw_nodes) bad(path, "no $NOD/$Nodes section (expected a Gmsh 1 or 2 ASCII mesh)");
  if (!saw_elements) bad(path, "no $ELM/$Elements section");
  if (raw_tets.empty()) bad(path, "no tetrahedra (element type 4) in the mesh");
  // Keep used nodes only, in file order.
  std::vector<int32_t> used(raw_nodes.size() / 3, -1);
  std::vector<int32_t> tet_index(raw_tets.size());
  for (size_t k = 0; k < raw_tets.size(); ++k) {
    auto it = id_to_index.find(raw_tets[k]);
    if (it == id_to_index.end())
      bad(path, "tetrahedron " + std::to_string(k / 4 + 1) + " uses unknown node id " + std::to_string(raw_tets[k]));
    tet_index[k] = it->second;
    used[it->second] = 0;
  }
  TetMesh mesh;
  int32_t n = 0;
  for (size_t i = 0; i < used.size(); ++i)
    if (used[i] == 0) {
      used[i] = n++;
      mesh.nodes.insert(mesh.nodes.end(), {raw_nodes[3 * i], raw_nodes[3 * i + 1], raw_nodes[3 * i + 2]});
    }
  mesh.tets.resize(tet_index.size());
  for (size_t k = 0; k < tet_index.size(); ++k) mesh.tets[k] = used[tet_index[k]];
  return mesh;
}

TetMesh box_mesh(double lx, double ly, double lz, int nx, int ny, int nz) {
  if (nx < 1 || ny < 1 || nz < 1 || !(lx > 0) || !(ly > 0) || !(lz > 0))
    bad("box_mesh", "expected positive sizes and cell counts");
  TetMesh mesh;
  auto id = [&](int i, int j, int k) { return i + (nx + 1) * (j + (ny + 1) * k); };
  for (int k = 0; k <= nz; ++k)
    for (int j = 0; j <= ny; ++j)
      for (int i = 0; i <= nx; ++i) mesh.nodes.insert(mesh.nodes.end(), {lx * i / nx, ly * j / ny, lz * k / nz});
  static const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i)
        for (const auto& p : perms) {
          int c[3] = {0, 0, 0};
          mesh.tets.push_back(id(i, j, k));
          for (int s = 0; s < 3; ++s) {
            c[p[s]] = 1;
            mesh.tets.push_back(id(i + c[0], j + c[1], k + c[2]));
          }
        }
  return mesh;
}

std::vector<int32_t> boundary_faces(const TetMesh& mesh) {
  std::map<std::array<int32_t, 3>, std::pair<int, std::array<int32_t, 3>>> faces;
  static const int opp[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  for (int32_t t = 0; t < mesh.ntet(); ++t) {
    const int32_t* n = &mesh.tets[4 * t];
    const Vec3 x0 = node(mesh.nodes, n[0]);
    const double det =
        (node(mesh.nodes, n[1]) - x0).cross(node(mesh.nodes, n[2]) - x0).dot(node(mesh.nodes, n[3]) - x0);
    for (const auto& f : opp) {
      std::array<int32_t, 3> tri = {n[f[0]], n[f[1]], n[f[2]]};
      if (det < 0) std::swap(tri[1], tri[2]);
      std::array<int32_t, 3> key = tri;
      std::sort(key.begin(), key.end());
      auto& e = faces[key];
      e.first += 1;
      e.second = tri;
    }
  }
  std::vector<int32_t> out;
  for (const auto& kv : faces)
    if (kv.second.first == 1) out.insert(out.end(), kv.second.second.begin(), kv.second.second.end());
  return out;
}

double mesh_volume(const TetMesh& mesh, const std::vector<double>& x) {
  double v = 0.0;
  for (int32_t t = 0; t < mesh.ntet(); ++t) {
    const int32_t* n = &mesh.tets[4 * t];
    const Vec3 x0 = node(x, n[0]);
    v += (node(x, n[1]) - x0).cross(node(x, n[2]) - x0).dot(node(x, n[3]) - x0) / 6.0;
  }
  return v;
}

// ---- model -------------------------------------------------------------------------------------

Model compile(const TetMesh& mesh, const Material& material) {
  const std::string where = "tetrahedral mesh";
  if (mesh.nodes.empty() || mesh.tets.empty() || mesh.nodes.size() % 3 || mesh.tets.size() % 4)
    bad(where, "expected nodes (#N*3) and tetrahedra (#T*4), got an empty or ragged mesh");
  if (!(material.young_modulus_pa > 0) || !std::isfinite(material.young_modulus_pa))
    bad(where + ": young_modulus_pa", "expected a positive number");
  if (!(material.poisson_ratio > -1.0 && material.poisson_ratio < 0.5))
    bad(where + ": poisson_ratio", "expected a value in (-1, 0.5)");
  if (!(material.density_kg_m3 > 0)) bad(where + ": density_kg_m3", "expected a positive number");
  if (material.rayleigh_mass < 0 || material.rayleigh_stiffness < 0)
    bad(where + ": rayleigh", "expected non-negative Rayleigh coefficients");
  Model m;
  m.material = material;
  m.nnode = mesh.nnode();
  m.ntet = mesh.ntet();
  m.rest = mesh.nodes;
  m.tets = mesh.tets;
  for (double c : m.rest)
    if (!std::isfinite(c)) bad(where, "non-finite node coordinate");
  lame(material.young_modulus_pa, material.poisson_ratio, m.lame_lambda, m.lame_mu);
  m.tet_volume.resize(m.ntet);
  m.tet_dm_inv.resize(9 * static_cast<size_t>(m.ntet));
  m.tet_stiffness.resize(144 * static_cast<size_t>(m.ntet));
  m.node_mass.assign(m.nnode, 0.0);
  const double size = box_size(m.rest);
  for (int32_t t = 0; t < m.ntet; ++t) {
    int32_t* n = &m.tets[4 * t];
    for (int a = 0; a < 4; ++a)
      if (n[a] < 0 || n[a] >= m.nnode)
        bad(where, "tetrahedron " + std::to_string(t) + " has node index " + std::to_string(n[a]) + " outside [0, " +
                       std::to_string(m.nnode) + ")");
    Mat3 Dm;
    for (int c = 0; c < 3; ++c) Dm.col(c) = node(m.rest, n[c + 1]) - node(m.rest, n[0]);
    double det = Dm.determinant();
    if (det < 0) {  // reorder so that every element has positive volume
      std::swap(n[2], n[3]);
      for (int c = 0; c < 3; ++c) Dm.col(c) = node(m.rest, n[c + 1]) - node(m.rest, n[0]);
      det = -det;
    }
    if (!(det > 1e-14 * size * size * size))
      bad(where, "tetrahedron " + std::to_string(t) + " is degenerate (volume " + std::to_string(det / 6) + ")");
    const double vol = det / 6.0;
    m.tet_volume[t] = vol;
    const Mat3 inv = Dm.inverse();
    Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(&m.tet_dm_inv[9 * t]) = inv;
    // Shape gradients: rows of Dm^-1 for nodes 1..3, node 0 the negative sum.
    Vec3 g[4];
    for (int a = 1; a < 4; ++a) g[a] = inv.row(a - 1).transpose();
    g[0] = -(g[1] + g[2] + g[3]);
    Eigen::Map<Eigen::Matrix<double, 12, 12, Eigen::RowMajor>> K(&m.tet_stiffness[144 * t]);
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j)
        K.block<3, 3>(3 * i, 3 * j) =
            vol * (m.lame_lambda * g[i] * g[j].transpose() + m.lame_mu * g[j] * g[i].transpose() +
                   m.lame_mu * g[i].dot(g[j]) * Mat3::Identity());
    for (int a = 0; a < 4; ++a) m.node_mass[n[a]] += material.density_kg_m3 * vol / 4.0;
  }
  return m;
}

Load make_load(const Model& model) { return empty_load(model.nnode); }

void fix_nodes(Load& load, const std::vector<int32_t>& nodes, const std::array<double, 3>& disp_m) {
  for (int32_t n : nodes)
    for (int c = 0; c < 3; ++c) {
      load.dof_fixed[3 * n + c] = 1;
      load.dof_disp[3 * n + c] = disp_m[c];
    }
}

void add_force(Load& load, const std::vector<int32_t>& nodes, const std::array<double, 3>& force_N) {
  if (nodes.empty()) return;
  for (int32_t n : nodes)
    for (int c = 0; c < 3; ++c) load.force[3 * n + c] += force_N[c] / static_cast<double>(nodes.size());
}

void internal_forces(const Model& m, const std::vector<double>& x, std::vector<double>& f) {
  f.assign(3 * static_cast<size_t>(m.nnode), 0.0);
  for (int32_t t = 0; t < m.ntet; ++t) {
    const Mat3 R = tet_rotation(m, t, x);
    const Vec12 k = stiffness(m, t) * rotated_displacement(m, t, R, x);
    const int32_t* n = &m.tets[4 * t];
    for (int a = 0; a < 4; ++a) {
      const Vec3 fa = -(R * k.segment<3>(3 * a));
      for (int c = 0; c < 3; ++c) f[3 * n[a] + c] += fa[c];
    }
  }
}

StaticReport solve_static(const Model& m, const Load& load, std::vector<double>& x, const StaticOptions& opt) {
  StaticReport rep;
  int32_t nfree = 0;
  const std::vector<int32_t> dof = free_dofs(load, nfree);
  const double size = box_size(m.rest);
  double fnorm = 0.0;
  for (double f : load.force) fnorm += f * f;
  fnorm = std::sqrt(fnorm);
  const bool linear = m.material.elasticity == Elasticity::linear;
  const int steps = linear ? 1 : std::max(1, opt.load_steps);
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt;
  bool analysed = false;
  std::vector<double> fint;
  for (int s = 1; s <= steps; ++s) {
    const double lam = static_cast<double>(s) / steps;
    for (size_t d = 0; d < x.size(); ++d)
      if (load.dof_fixed[d]) x[d] = m.rest[d] + lam * load.dof_disp[d];
    const int iters = linear ? 1 : opt.max_iterations;
    for (int it = 0; it < iters; ++it) {
      internal_forces(m, x, fint);
      Eigen::VectorXd r(nfree);
      double rnorm = 0.0, react = 0.0;
      for (size_t d = 0; d < x.size(); ++d) {
        if (dof[d] >= 0) {
          r[dof[d]] = lam * load.force[d] + fint[d];
          rnorm += r[dof[d]] * r[dof[d]];
        } else {
          react += fint[d] * fint[d];
        }
      }
      rnorm = std::sqrt(rnorm);
      const double scale = std::max(lam * fnorm, std::sqrt(react)) + 1e-300;
      rep.residual = rnorm / scale;
      if (!linear && it > 0 && rep.residual < opt.tolerance) break;
      const Eigen::SparseMatrix<double> K = assemble(m, x, dof, nfree, 0.0, 1.0);
      if (!analysed) {
        ldlt.analyzePattern(K);
        analysed = true;
      }
      ldlt.factorize(K);
      if (ldlt.info() != Eigen::Success) {
        rep.converged = false;
        return rep;  // singular: the load does not hold the body in place
      }
      const Eigen::VectorXd dx = ldlt.solve(r);
      for (size_t d = 0; d < x.size(); ++d)
        if (dof[d] >= 0) x[d] += dx[dof[d]];
      ++rep.iterations;
      if (!linear && dx.lpNorm<Eigen::Infinity>() < opt.tolerance * size && it > 0) break;
    }
    if (opt.on_increment) opt.on_increment(lam, x);
  }
  // Final residual.
  internal_forces(m, x, fint);
  double rnorm = 0.0, react = 0.0;
  for (size_t d = 0; d < x.size(); ++d) {
    if (dof[d] >= 0) {
      const double r = load.force[d] + fint[d];
      rnorm += r * r;
    } else {
      react += fint[d] * fint[d];
    }
  }
  rep.residual = std::sqrt(rnorm) / (std::max(fnorm, std::sqrt(react)) + 1e-300);
  rep.converged = std::isfinite(rep.residual) && rep.residual < std::max(opt.tolerance, 1e-8) * 10.0;
  return rep;
}

State make_state(const Model& model) {
  State s;
  s.x = model.rest;
  s.v.assign(model.rest.size(), 0.0);
  return s;
}

void step_implicit(const Model& m, const Load& load, State& st, double h) {
  int32_t nfree = 0;
  const std::vector<int32_t> dof = free_dofs(load, nfree);
  for (size_t d = 0; d < st.x.size(); ++d)
    if (load.dof_fixed[d]) {
      st.x[d] = m.rest[d] + load.dof_disp[d];
      st.v[d] = 0.0;
    }
  const double alpha = m.material.rayleigh_mass, beta = m.material.rayleigh_stiffness;
  std::vector<double> fint, kv;
  internal_forces(m, st.x, fint);
  stiffness_times(m, st.x, st.v, kv);
  Eigen::VectorXd rhs(nfree);
  for (size_t d = 0; d < st.x.size(); ++d)
    if (dof[d] >= 0) {
      const double mass = m.node_mass[d / 3];
      rhs[dof[d]] = h * (load.force[d] + fint[d] - alpha * mass * st.v[d] - (beta + h) * kv[d]);
    }
  const Eigen::SparseMatrix<double> A = assemble(m, st.x, dof, nfree, 1.0 + h * alpha, h * beta + h * h);
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(A);
  if (ldlt.info() != Eigen::Success) return;
  const Eigen::VectorXd dv = ldlt.solve(rhs);
  for (size_t d = 0; d < st.x.size(); ++d)
    if (dof[d] >= 0) {
      st.v[d] += dv[dof[d]];
      st.x[d] += h * st.v[d];
    }
  st.time_s += h;
}

std::array<double, 3> reaction_force(const Model& m, const std::vector<double>& x, const std::vector<int32_t>& nodes) {
  std::vector<double> f;
  internal_forces(m, x, f);
  return node_sum(f, nodes);
}

double energy(const Model& m, const std::vector<double>& x, const std::vector<double>& v) {
  double e = 0.0;
  for (int32_t t = 0; t < m.ntet; ++t) {
    const Mat3 R = tet_rotation(m, t, x);
    const Vec12 u = rotated_displacement(m, t, R, x);
    e += 0.5 * u.dot(stiffness(m, t) * u);
  }
  if (!v.empty())
    for (int32_t i = 0; i < m.nnode; ++i) e += 0.5 * m.node_mass[i] * node(v, i).squaredNorm();
  return e;
}

// ---- embedding ---------------------------------------------------------------------------------

Embedding embed_points(const Model& m, const std::vector<double>& pts) {
  Embedding emb;
  const size_t np = pts.size() / 3;
  emb.tet.assign(np, -1);
  emb.weight.assign(4 * np, 0.0);
  emb.distance.assign(np, 0.0);
  // Uniform grid of tetrahedron bounding boxes.
  Vec3 lo = node(m.rest, 0), hi = lo;
  for (int32_t i = 0; i < m.nnode; ++i) {
    lo = lo.cwiseMin(node(m.rest, i));
    hi = hi.cwiseMax(node(m.rest, i));
  }
  double total = 0.0;
  for (double v : m.tet_volume) total += v;
  const double cell = std::max(2.0 * std::cbrt(total / m.ntet), 1e-12);
  const Eigen::Vector3i dims = (((hi - lo) / cell).array().floor().cast<int>() + 1).matrix();
  auto cell_of = [&](const Vec3& p) {
    Eigen::Vector3i c = ((p - lo) / cell).array().floor().cast<int>().matrix();
    return c.cwiseMax(Eigen::Vector3i::Zero()).cwiseMin(dims - Eigen::Vector3i::Ones()).eval();
  };
  auto flat = [&](const Eigen::Vector3i& c) { return c[0] + dims[0] * (c[1] + dims[1] * c[2]); };
  std::vector<std::vector<int32_t>> grid(static_cast<size_t>(dims[0]) * dims[1] * dims[2]);
  for (int32_t t = 0; t < m.ntet; ++t) {
    Vec3 tl = node(m.rest, m.tets[4 * t]), th = tl;
    for (int a = 1; a < 4; ++a) {
      tl = tl.cwiseMin(node(m.rest, m.tets[4 * t + a]));
      th = th.cwiseMax(node(m.rest, m.tets[4 * t + a]));
    }
    const Eigen::Vector3i cl = cell_of(tl), ch = cell_of(th);
    for (int k = cl[2]; k <= ch[2]; ++k)
      for (int j = cl[1]; j <= ch[1]; ++j)
        for (int i = cl[0]; i <= ch[0]; ++i) grid[flat({i, j, k})].push_back(t);
  }
  auto bary = [&](int32_t t, const Vec3& p) {
    const Vec3 w = dm_inv(m, t) * (p - node(m.rest, m.tets[4 * t]));
    return Eigen::Vector4d(1.0 - w.sum(), w[0], w[1], w[2]);
  };
  for (size_t q = 0; q < np; ++q) {
    const Vec3 p(pts[3 * q], pts[3 * q + 1], pts[3 * q + 2]);
    const Eigen::Vector3i c = cell_of(p);
    int32_t best = -1;
    double best_min = -std::numeric_limits<double>::infinity();
    Eigen::Vector4d best_w;
    auto consider = [&](int32_t t) {
      const Eigen::Vector4d w = bary(t, p);
      if (w.minCoeff() > best_min) {
        best_min = w.minCoeff();
        best = t;
        best_w = w;
      }
    };
    for (int ring = 0; ring <= 2 && best_min < -1e-12; ++ring) {
      for (int k = c[2] - ring; k <= c[2] + ring; ++k)
        for (int j = c[1] - ring; j <= c[1] + ring; ++j)
          for (int i = c[0] - ring; i <= c[0] + ring; ++i) {
            if (std::max({std::abs(i - c[0]), std::abs(j - c[1]), std::abs(k - c[2])}) != ring) continue;
            if (i < 0 || j < 0 || k < 0 || i >= dims[0] || j >= dims[1] || k >= dims[2]) continue;
            for (int32_t t : grid[flat({i, j, k})]) consider(t);
          }
    }
    if (best < 0)
      for (int32_t t = 0; t < m.ntet; ++t) consider(t);
    Eigen::Vector4d w = best_w.cwiseMax(0.0);
    w /= w.sum();
    emb.tet[q] = best;
    for (int a = 0; a < 4; ++a) emb.weight[4 * q + a] = w[a];
    Vec3 at = Vec3::Zero();
    for (int a = 0; a < 4; ++a) at += w[a] * node(m.rest, m.tets[4 * best + a]);
    emb.distance[q] = (at - p).norm();
  }
  return emb;
}

void interpolate(const Model& m, const Embedding& emb, const std::vector<double>& x, std::vector<double>& out) {
  const size_t np = emb.tet.size();
  out.assign(3 * np, 0.0);
  for (size_t q = 0; q < np; ++q) {
    // Displacements, not positions: a point slightly outside the tetrahedra keeps its own rest
    // position and takes the displacement of the nearest point inside.
    Vec3 u = Vec3::Zero();
    for (int a = 0; a < 4; ++a) {
      const int32_t n = m.tets[4 * emb.tet[q] + a];
      u += emb.weight[4 * q + a] * (node(x, n) - node(m.rest, n));
    }
    for (int c = 0; c < 3; ++c) out[3 * q + c] = u[c];
  }
}

}  // namespace softatlas::sim::fem
