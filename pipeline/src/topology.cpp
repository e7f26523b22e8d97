// Plain-C++ surface checks: edge incidence (closed, edge-manifold, consistent orientation),
// components, genus by Euler characteristic, signed volume, triangle angles.
#include "softatlas/pipeline/topology.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <unordered_map>

namespace softatlas::pipeline {
namespace {

uint64_t edge_key(int32_t a, int32_t b) {
  const uint32_t lo = static_cast<uint32_t>(std::min(a, b)), hi = static_cast<uint32_t>(std::max(a, b));
  return (static_cast<uint64_t>(lo) << 32) | hi;
}

int find(std::vector<int>& p, int x) {
  while (p[x] != x) x = p[x] = p[p[x]];
  return x;
}

}  // namespace

std::vector<int> face_components(const io::TriMesh& mesh, int* count) {
  const size_t nf = mesh.face_count();
  std::vector<int> parent(nf);
  std::iota(parent.begin(), parent.end(), 0);
  std::unordered_map<uint64_t, int> first_face;
  first_face.reserve(nf * 2);
  for (size_t f = 0; f < nf; ++f)
    for (int e = 0; e < 3; ++e) {
      const auto key = edge_key(mesh.faces[3 * f + e], mesh.faces[3 * f + (e + 1) % 3]);
      auto it = first_face.find(key);
      if (it == first_face.end()) {
        first_face.emplace(key, static_cast<int>(f));
      } else {
        const int a = find(parent, static_cast<int>(f)), b = find(parent, it->second);
        if (a != b) parent[a] = b;
      }
    }
  std::vector<int> id(nf, -1), root_id(nf, -1);
  int n = 0;
  for (size_t f = 0; f < nf; ++f) {
    const int r = find(parent, static_cast<int>(f));
    if (root_id[r] < 0) root_id[r] = n++;
    id[f] = root_id[r];
  }
  if (count) *count = n;
  return id;
}

io::TriMesh select_faces(const io::TriMesh& mesh, const std::vector<char>& keep) {
  io::TriMesh out;
  std::vector<int32_t> remap(mesh.vertex_count(), -1);
  for (size_t f = 0; f < mesh.face_count(); ++f) {
    if (!keep[f]) continue;
    for (int c = 0; c < 3; ++c) {
      const int32_t v = mesh.faces[3 * f + c];
      if (remap[v] < 0) {
        remap[v] = static_cast<int32_t>(out.vertex_count());
        out.vertices.insert(out.vertices.end(), mesh.vertices.begin() + 3 * v, mesh.vertices.begin() + 3 * v + 3);
      }
      out.faces.push_back(remap[v]);
    }
  }
  return out;
}

SurfaceReport inspect_surface(const io::TriMesh& mesh) {
  SurfaceReport r;
  r.faces = mesh.face_count();
  const auto& V = mesh.vertices;
  const auto& F = mesh.faces;
  // Per undirected edge: number of faces and the net direction count (+1 a->b with a<b, -1 back).
  struct EdgeUse {
    int faces = 0;
    int net = 0;
  };
  std::unordered_map<uint64_t, EdgeUse> edges;
  edges.reserve(r.faces * 2);
  std::vector<char> used(mesh.vertex_count(), 0);
  double min_angle = 180.0;
  size_t good = 0;
  for (size_t f = 0; f < r.faces; ++f) {
    const int32_t* t = &F[3 * f];
    for (int e = 0; e < 3; ++e) {
      const int32_t a = t[e], b = t[(e + 1) % 3];
      used[a] = 1;
      EdgeUse& u = edges[edge_key(a, b)];
      ++u.faces;
      u.net += a < b ? 1 : -1;
    }
    const double* p[3] = {&V[3 * t[0]], &V[3 * t[1]], &V[3 * t[2]]};
    // Signed volume by the divergence theorem: sum of p0 . (p1 x p2) / 6.
    r.signed_volume_mm3 +=
        (p[0][0] * (p[1][1] * p[2][2] - p[1][2] * p[2][1]) - p[0][1] * (p[1][0] * p[2][2] - p[1][2] * p[2][0]) +
         p[0][2] * (p[1][0] * p[2][1] - p[1][1] * p[2][0])) /
        6.0;
    double smallest = 180.0;
    for (int c = 0; c < 3; ++c) {
      const double* o = p[c];
      const double* q = p[(c + 1) % 3];
      const double* s = p[(c + 2) % 3];
      const double u[3] = {q[0] - o[0], q[1] - o[1], q[2] - o[2]};
      const double w[3] = {s[0] - o[0], s[1] - o[1], s[2] - o[2]};
      const double cx = u[1] * w[2] - u[2] * w[1], cy = u[2] * w[0] - u[0] * w[2], cz = u[0] * w[1] - u[1] * w[0];
      const double cr = std::sqrt(cx * cx + cy * cy + cz * cz);
      const double dt = u[0] * w[0] + u[1] * w[1] + u[2] * w[2];
      smallest = std::min(smallest, std::atan2(cr, dt) * 180.0 / M_PI);
      if (c == 0) r.area_mm2 += 0.5 * cr;
    }
    min_angle = std::min(min_angle, smallest);
    if (smallest >= 20.0) ++good;
  }
  for (const auto& [key, u] : edges) {
    if (u.faces == 1) ++r.boundary_edges;
    if (u.faces > 2) ++r.nonmanifold_edges;
    if (u.faces == 2 && u.net != 0) ++r.misoriented_edges;
  }
  r.vertices = static_cast<size_t>(std::count(used.begin(), used.end(), 1));
  int comps = 0;
  face_components(mesh, &comps);
  r.components = static_cast<size_t>(comps);
  const long chi = static_cast<long>(r.vertices) - static_cast<long>(edges.size()) + static_cast<long>(r.faces);
  r.genus = static_cast<int>((2L * comps - chi) / 2);
  r.min_angle_deg = r.faces ? min_angle : 0.0;
  r.share_angle_ge_20 = r.faces ? static_cast<double>(good) / static_cast<double>(r.faces) : 0.0;
  return r;
}

}  // namespace softatlas::pipeline
