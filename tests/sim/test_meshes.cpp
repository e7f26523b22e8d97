#include "test_meshes.hpp"

#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>

namespace softatlas::test {

Mesh icosphere(int subdivisions, double radius) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  Mesh m;
  m.V = {-1, t,  0,  1, t, 0,  -1, -t, 0,  1, -t, 0, 0,  -1, t,  0,  1, t,
         0,  -1, -t, 0, 1, -t, t,  0,  -1, t, 0,  1, -t, 0,  -1, -t, 0, 1};
  m.F = {0, 11, 5, 0, 5, 1, 0, 1, 7, 0, 7, 10, 0, 10, 11, 1, 5, 9, 5, 11, 4,  11, 10, 2,  10, 7, 6, 7, 1, 8,
         3, 9,  4, 3, 4, 2, 3, 2, 6, 3, 6, 8,  3, 8,  9,  4, 9, 5, 2, 4,  11, 6,  2,  10, 8,  6, 7, 9, 8, 1};
  auto normalize = [&](int v) {
    double* p = &m.V[3 * v];
    const double l = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    p[0] /= l, p[1] /= l, p[2] /= l;
  };
  for (int v = 0; v < 12; ++v) normalize(v);
  for (int s = 0; s < subdivisions; ++s) {
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      const auto key = std::make_pair(std::min(a, b), std::max(a, b));
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      const int id = static_cast<int>(m.V.size() / 3);
      for (int c = 0; c < 3; ++c) m.V.push_back(0.5 * (m.V[3 * a + c] + m.V[3 * b + c]));
      normalize(id);
      mid[key] = id;
      return id;
    };
    std::vector<int32_t> F;
    for (size_t f = 0; f < m.F.size(); f += 3) {
      const int a = m.F[f], b = m.F[f + 1], c = m.F[f + 2];
      const int ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
      F.insert(F.end(), {a, ab, ca, b, bc, ab, c, ca, bc, ab, bc, ca});
    }
    m.F = F;
  }
  for (double& x : m.V) x *= radius;
  return m;
}

Mesh cube(double s) {
  Mesh m;
  m.V = {0, 0, 0, s, 0, 0, s, s, 0, 0, s, 0, 0, 0, s, s, 0, s, s, s, s, 0, s, s};
  m.F = {0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4, 1, 2, 6, 1, 6, 5, 2, 3, 7, 2, 7, 6, 3, 0, 4, 3, 4, 7};
  return m;
}

Mesh plane_grid(int n, double size) {
  Mesh m;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) m.V.insert(m.V.end(), {size * i / n, size * j / n, 0.0});
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
      m.F.insert(m.F.end(), {a, b, d, a, d, c});
    }
  return m;
}

Mesh read_obj(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open " + path);
  Mesh m;
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream ls(line);
    std::string kw;
    ls >> kw;
    if (kw == "v") {
      double x, y, z;
      ls >> x >> y >> z;
      m.V.insert(m.V.end(), {x, y, z});
    } else if (kw == "f") {
      std::vector<int32_t> poly;
      std::string tok;
      while (ls >> tok) poly.push_back(std::stoi(tok.substr(0, tok.find('/'))) - 1);
      for (size_t k = 1; k + 1 < poly.size(); ++k) m.F.insert(m.F.end(), {poly[0], poly[k], poly[k + 1]});
    }
  }
  return m;
}

std::string shared_data(const std::string& rel) { return std::string(SOFTATLAS_SHARED_DATA) + "/" + rel; }
std::string project_data(const std::string& rel) { return std::string(SOFTATLAS_SOURCE_DIR) + "/data/" + rel; }

sim::OrganDesc organ(const std::string& name, const Mesh& mesh, double scale) {
  sim::OrganDesc d;
  d.name = name;
  d.vertices = mesh.V;
  for (double& x : d.vertices) x *= scale;
  d.faces = mesh.F;
  return d;
}

}  // namespace softatlas::test
