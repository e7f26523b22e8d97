// The solid model's volumetric lattice: regular cells of 6 Kuhn tetrahedra clipped to the inside
// of a closed surface, and the barycentric embedding of the surface vertices (solid.hpp).
#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include "softatlas/sim/error.hpp"
#include "softatlas/sim/solid.hpp"

namespace softatlas::sim {
namespace {

constexpr int kSamples = 3;  // samples per cell and axis for the inside fraction (27 per cell)

// The 6 Kuhn tetrahedra of the unit cube: corner 0 -> +e_a -> +e_a+e_b -> (1,1,1) for each
// permutation (a, b, c) of the axes. Corners are bit sets (x = 1, y = 2, z = 4).
constexpr int kPerm[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};

int perm_index(int a, int b) {
  for (int p = 0; p < 6; ++p)
    if (kPerm[p][0] == a && kPerm[p][1] == b) return p;
  return 0;
}

// Crossings of the surface with lines parallel to x through the sample rows (y_j, z_k): sorted x
// values per row. Triangles are binned by their y/z extent.
struct Rows {
  int ny = 0, nz = 0;
  double y0 = 0, z0 = 0, step = 0;
  std::vector<std::vector<double>> x;  // ny * nz
};

Rows surface_rows(const std::vector<double>& V, const std::vector<int32_t>& F, double y0, double z0, double step,
                  int ny, int nz) {
  Rows rows{ny, nz, y0, z0, step, std::vector<std::vector<double>>(static_cast<size_t>(ny) * nz)};
  const size_t nf = F.size() / 3;
  for (size_t f = 0; f < nf; ++f) {
    const double* a = &V[3 * F[3 * f]];
    const double* b = &V[3 * F[3 * f + 1]];
    const double* c = &V[3 * F[3 * f + 2]];
    const double ylo = std::min({a[1], b[1], c[1]}), yhi = std::max({a[1], b[1], c[1]});
    const double zlo = std::min({a[2], b[2], c[2]}), zhi = std::max({a[2], b[2], c[2]});
    const int j0 = std::max(0, static_cast<int>(std::ceil((ylo - y0) / step)));
    const int j1 = std::min(ny - 1, static_cast<int>(std::floor((yhi - y0) / step)));
    const int k0 = std::max(0, static_cast<int>(std::ceil((zlo - z0) / step)));
    const int k1 = std::min(nz - 1, static_cast<int>(std::floor((zhi - z0) / step)));
    // 2-D barycentric coordinates of (y, z) in the projected triangle
    const double d = (b[1] - a[1]) * (c[2] - a[2]) - (c[1] - a[1]) * (b[2] - a[2]);
    if (d == 0.0) continue;  // edge-on to the rows
    for (int j = j0; j <= j1; ++j)
      for (int k = k0; k <= k1; ++k) {
        const double py = y0 + j * step, pz = z0 + k * step;
        const double u = ((py - a[1]) * (c[2] - a[2]) - (c[1] - a[1]) * (pz - a[2])) / d;
        const double v = ((b[1] - a[1]) * (pz - a[2]) - (py - a[1]) * (b[2] - a[2])) / d;
        if (u < 0 || v < 0 || u + v > 1) continue;
        rows.x[static_cast<size_t>(j) * nz + k].push_back(a[0] + u * (b[0] - a[0]) + v * (c[0] - a[0]));
      }
  }
  for (auto& r : rows.x) std::sort(r.begin(), r.end());
  return rows;
}

}  // namespace

SolidLattice solid_lattice(const std::vector<double>& V, const std::vector<int32_t>& F, double h) {
  const size_t nv = V.size() / 3;
  if (nv == 0 || F.empty()) throw InputError("solid lattice", "the surface has no vertices or faces");
  if (!(h > 0) || !std::isfinite(h)) throw InputError("solid lattice", "the spacing must be positive");
  std::vector<uint8_t> used(nv, 0);
  for (int32_t v : F) {
    if (v < 0 || static_cast<size_t>(v) >= nv) throw InputError("solid lattice", "face index out of range");
    used[v] = 1;
  }
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t i = 0; i < nv; ++i)
    if (used[i])
      for (int c = 0; c < 3; ++c) lo[c] = std::min(lo[c], V[3 * i + c]), hi[c] = std::max(hi[c], V[3 * i + c]);
  if (!(hi[0] > lo[0] && hi[1] > lo[1] && hi[2] > lo[2]))
    throw InputError("solid lattice", "the surface has no extent in some direction");
  int n[3];
  double o[3];
  for (int c = 0; c < 3; ++c) {
    n[c] = static_cast<int>(std::ceil((hi[c] - lo[c]) / h + 0.5));
    o[c] = 0.5 * (lo[c] + hi[c]) - 0.5 * n[c] * h;  // centred: the surface keeps >= h/4 margin
  }
  if (static_cast<double>(n[0]) * n[1] * n[2] > 5e7)
    throw InputError("solid lattice", "spacing too small for the organ");
  const auto cell_id = [&](int i, int j, int k) { return (static_cast<int64_t>(k) * n[1] + j) * n[0] + i; };
  const int64_t ncell = static_cast<int64_t>(n[0]) * n[1] * n[2];

  // Inside fraction: samples at cell-relative (s + 0.5) / kSamples, shifted by an irrational
  // fraction so that no sample row passes exactly through a surface vertex or edge.
  const double step = h / kSamples;
  const double jitter = 1e-4 * std::sqrt(2.0) * step;
  const int sy = n[1] * kSamples, sz = n[2] * kSamples, sx = n[0] * kSamples;
  const Rows rows = surface_rows(V, F, o[1] + 0.5 * step + jitter, o[2] + 0.5 * step + 1.37 * jitter, step, sy, sz);
  std::vector<float> fraction(static_cast<size_t>(ncell), 0.0f);
  for (int j = 0; j < sy; ++j)
    for (int k = 0; k < sz; ++k) {
      const std::vector<double>& xs = rows.x[static_cast<size_t>(j) * sz + k];
      if (xs.size() < 2) continue;
      size_t crossed = 0;
      for (int i = 0; i < sx; ++i) {
        const double px = o[0] + (i + 0.5) * step + 0.73 * jitter;
        while (crossed < xs.size() && xs[crossed] < px) ++crossed;
        if (crossed % 2 == 1) fraction[cell_id(i / kSamples, j / kSamples, k / kSamples)] += 1.0f;
      }
    }
  const float per = 1.0f / (kSamples * kSamples * kSamples);
  for (float& f : fraction) f *= per;

  // Cells holding a surface vertex are kept even when no sample of theirs is inside.
  const auto locate = [&](const double* p, int cell[3], double u[3]) {
    for (int c = 0; c < 3; ++c) {
      const double t = (p[c] - o[c]) / h;
      cell[c] = std::clamp(static_cast<int>(std::floor(t)), 0, n[c] - 1);
      u[c] = std::clamp(t - cell[c], 0.0, 1.0);
    }
  };
  const float min_fraction = 0.5f * per;
  for (size_t v = 0; v < nv; ++v) {
    if (!used[v]) continue;
    int cell[3];
    double u[3];
    locate(&V[3 * v], cell, u);
    float& f = fraction[cell_id(cell[0], cell[1], cell[2])];
    f = std::max(f, min_fraction);
  }

  SolidLattice L;
  L.spacing_m = h;
  std::vector<int32_t> node_of(static_cast<size_t>(n[0] + 1) * (n[1] + 1) * (n[2] + 1), -1);
  const auto node = [&](int i, int j, int k) {
    int32_t& id = node_of[(static_cast<size_t>(k) * (n[1] + 1) + j) * (n[0] + 1) + i];
    if (id < 0) {
      id = L.mesh.nnode();
      L.mesh.nodes.insert(L.mesh.nodes.end(), {o[0] + i * h, o[1] + j * h, o[2] + k * h});
    }
    return id;
  };
  std::vector<int32_t> first_tet(static_cast<size_t>(ncell), -1);
  for (int k = 0; k < n[2]; ++k)
    for (int j = 0; j < n[1]; ++j)
      for (int i = 0; i < n[0]; ++i) {
        const int64_t c = cell_id(i, j, k);
        if (fraction[c] <= 0.0f) continue;
        first_tet[c] = L.mesh.ntet();
        for (const auto& p : kPerm) {
          int corner[4] = {0, 0, 0, 7};
          corner[1] = 1 << p[0];
          corner[2] = corner[1] | (1 << p[1]);
          int32_t t[4];
          for (int q = 0; q < 4; ++q)
            t[q] = node(i + (corner[q] & 1), j + ((corner[q] >> 1) & 1), k + ((corner[q] >> 2) & 1));
          L.mesh.tets.insert(L.mesh.tets.end(), t, t + 4);
          L.tet_fraction.push_back(fraction[c]);
        }
      }
  // Barycentric weights in the Kuhn tetrahedron of the sorted local coordinates
  // u_a >= u_b >= u_c: (1 - u_a, u_a - u_b, u_b - u_c, u_c).
  L.embed_tet.assign(nv, -1);
  L.embed_w.assign(4 * nv, 0.0);
  for (size_t v = 0; v < nv; ++v) {
    if (!used[v]) continue;
    int cell[3];
    double u[3];
    locate(&V[3 * v], cell, u);
    int ax[3] = {0, 1, 2};
    std::sort(ax, ax + 3, [&](int a, int b) { return u[a] > u[b] || (u[a] == u[b] && a < b); });
    L.embed_tet[v] = first_tet[cell_id(cell[0], cell[1], cell[2])] + perm_index(ax[0], ax[1]);
    const double w[4] = {1 - u[ax[0]], u[ax[0]] - u[ax[1]], u[ax[1]] - u[ax[2]], u[ax[2]]};
    std::copy(w, w + 4, &L.embed_w[4 * v]);
  }
  // Orient every tetrahedron positively (odd permutations come out negative); swapping two
  // nodes swaps their weights.
  std::vector<uint8_t> swapped(static_cast<size_t>(L.mesh.ntet()), 0);
  for (int32_t t = 0; t < L.mesh.ntet(); ++t) {
    int32_t* q = &L.mesh.tets[4 * t];
    const double* p0 = &L.mesh.nodes[3 * q[0]];
    double e[3][3];
    for (int a = 0; a < 3; ++a)
      for (int c = 0; c < 3; ++c) e[a][c] = L.mesh.nodes[3 * q[a + 1] + c] - p0[c];
    const double det = e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1]) -
                       e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0]) +
                       e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]);
    if (det < 0) std::swap(q[2], q[3]), swapped[t] = 1;
  }
  for (size_t v = 0; v < nv; ++v) {
    if (L.embed_tet[v] < 0) continue;
    if (swapped[L.embed_tet[v]]) std::swap(L.embed_w[4 * v + 2], L.embed_w[4 * v + 3]);
  }
  return L;
}

SolidLattice solid_lattice_budget(const std::vector<double>& V, const std::vector<int32_t>& F, int node_budget) {
  node_budget = std::max(node_budget, 8);
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (int32_t v : F)
    if (v >= 0 && static_cast<size_t>(v) < V.size() / 3)
      for (int c = 0; c < 3; ++c) lo[c] = std::min(lo[c], V[3 * v + c]), hi[c] = std::max(hi[c], V[3 * v + c]);
  // Start from the bounding box's share per node, then coarsen until the budget holds.
  const double box = std::max((hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]), 1e-30);
  double h = std::cbrt(0.5 * box / node_budget);
  SolidLattice L = solid_lattice(V, F, h);
  for (int it = 0; it < 40 && L.mesh.nnode() > node_budget; ++it) {
    h *= std::max(1.03, std::cbrt(static_cast<double>(L.mesh.nnode()) / node_budget));
    L = solid_lattice(V, F, h);
  }
  return L;
}

}  // namespace softatlas::sim
