#include "softatlas/evidence/scenario.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "softatlas/sim/error.hpp"

namespace softatlas::evidence {

TriMesh icosphere(int level, double radius) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  TriMesh m;
  m.V = {-1, t,  0,  1, t, 0,  -1, -t, 0,  1, -t, 0, 0,  -1, t,  0,  1, t,
         0,  -1, -t, 0, 1, -t, t,  0,  -1, t, 0,  1, -t, 0,  -1, -t, 0, 1};
  m.F = {0, 11, 5, 0, 5, 1, 0, 1, 7, 0, 7, 10, 0, 10, 11, 1, 5, 9, 5, 11, 4,  11, 10, 2,  10, 7, 6, 7, 1, 8,
         3, 9,  4, 3, 4, 2, 3, 2, 6, 3, 6, 8,  3, 8,  9,  4, 9, 5, 2, 4,  11, 6,  2,  10, 8,  6, 7, 9, 8, 1};
  for (int l = 0; l < level; ++l) {
    std::map<std::pair<int32_t, int32_t>, int32_t> mid;
    auto midpoint = [&](int32_t a, int32_t b) {
      const auto key = std::make_pair(std::min(a, b), std::max(a, b));
      const auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      const int32_t id = m.nvert();
      for (int c = 0; c < 3; ++c) m.V.push_back(0.5 * (m.V[3 * a + c] + m.V[3 * b + c]));
      mid.emplace(key, id);
      return id;
    };
    std::vector<int32_t> out;
    for (int32_t f = 0; f < m.nface(); ++f) {
      const int32_t a = m.F[3 * f], b = m.F[3 * f + 1], c = m.F[3 * f + 2];
      const int32_t ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
      out.insert(out.end(), {a, ab, ca, b, bc, ab, c, ca, bc, ab, bc, ca});
    }
    m.F = out;
  }
  for (int32_t i = 0; i < m.nvert(); ++i) {
    const double n =
        std::sqrt(m.V[3 * i] * m.V[3 * i] + m.V[3 * i + 1] * m.V[3 * i + 1] + m.V[3 * i + 2] * m.V[3 * i + 2]);
    for (int c = 0; c < 3; ++c) m.V[3 * i + c] *= radius / n;
  }
  return m;
}

double enclosed_volume(const TriMesh& m) {
  double v = 0.0;
  for (int32_t f = 0; f < m.nface(); ++f) {
    const double* a = &m.V[3 * m.F[3 * f]];
    const double* b = &m.V[3 * m.F[3 * f + 1]];
    const double* c = &m.V[3 * m.F[3 * f + 2]];
    v +=
        (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0])) /
        6.0;
  }
  return v;
}

TriMesh normalise_organ(const TriMesh& in, double size_m) {
  TriMesh m = in;
  double lo[3], hi[3];
  for (int c = 0; c < 3; ++c) lo[c] = INFINITY, hi[c] = -INFINITY;
  for (int32_t i = 0; i < m.nvert(); ++i)
    for (int c = 0; c < 3; ++c) lo[c] = std::min(lo[c], m.V[3 * i + c]), hi[c] = std::max(hi[c], m.V[3 * i + c]);
  const double extent = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
  if (!(extent > 0)) throw InputError("organ", "the surface has no extent");
  const double s = size_m / extent;
  for (int32_t i = 0; i < m.nvert(); ++i)
    for (int c = 0; c < 3; ++c) m.V[3 * i + c] = (m.V[3 * i + c] - 0.5 * (lo[c] + hi[c])) * s;
  if (enclosed_volume(m) < 0)
    for (int32_t f = 0; f < m.nface(); ++f) std::swap(m.F[3 * f + 1], m.F[3 * f + 2]);
  return m;
}

std::vector<int32_t> support_vertices(const std::vector<double>& V, double fraction) {
  double lo = INFINITY, hi = -INFINITY;
  for (size_t i = 0; i < V.size() / 3; ++i) lo = std::min(lo, V[3 * i + 1]), hi = std::max(hi, V[3 * i + 1]);
  std::vector<int32_t> out;
  for (size_t i = 0; i < V.size() / 3; ++i)
    if (V[3 * i + 1] <= lo + fraction * (hi - lo)) out.push_back(static_cast<int32_t>(i));
  return out;
}

std::vector<int32_t> region(const std::vector<double>& V, const std::array<double, 3>& p, double radius) {
  std::vector<int32_t> out;
  int32_t best = -1;
  double bd = INFINITY;
  for (size_t i = 0; i < V.size() / 3; ++i) {
    double d2 = 0;
    for (int c = 0; c < 3; ++c) d2 += (V[3 * i + c] - p[c]) * (V[3 * i + c] - p[c]);
    if (d2 <= radius * radius) out.push_back(static_cast<int32_t>(i));
    if (d2 < bd) bd = d2, best = static_cast<int32_t>(i);
  }
  if (out.empty() && best >= 0) out.push_back(best);
  return out;
}

std::vector<int32_t> nearest_face(const TriMesh& m, const std::array<double, 3>& p) {
  int32_t best = 0;
  double bd = INFINITY;
  for (int32_t f = 0; f < m.nface(); ++f) {
    double d2 = 0;
    for (int c = 0; c < 3; ++c) {
      const double cc = (m.V[3 * m.F[3 * f] + c] + m.V[3 * m.F[3 * f + 1] + c] + m.V[3 * m.F[3 * f + 2] + c]) / 3.0;
      d2 += (cc - p[c]) * (cc - p[c]);
    }
    if (d2 < bd) bd = d2, best = f;
  }
  return {m.F[3 * best], m.F[3 * best + 1], m.F[3 * best + 2]};
}

std::array<double, 3> top_point(const TriMesh& m) {
  int32_t best = 0;
  for (int32_t i = 1; i < m.nvert(); ++i)
    if (m.V[3 * i + 1] > m.V[3 * best + 1]) best = i;
  return {m.V[3 * best], m.V[3 * best + 1], m.V[3 * best + 2]};
}

std::vector<LoadCase> accuracy_loads(bool quick) {
  // Paper 000 Table I forces (x 1e-3 N) and Table II displacements ([0, 20, 20], [0, 30, 30] mm
  // over 30 iterations), and the large 50 mm pull (upwards, +y).
  std::vector<LoadCase> all = {
      {"force_100", false, {1e-3, 0, 0}, 0},       {"force_110", false, {1e-3, 1e-3, 0}, 0},
      {"force_111", false, {1e-3, 1e-3, 1e-3}, 0}, {"attach_20", true, {0, 0.020, 0.020}, 30},
      {"attach_30", true, {0, 0.030, 0.030}, 30},  {"pull_50mm", true, {0, 0.050, 0}, 30},
  };
  if (quick) return {all[2], all[3], all[5]};
  return all;
}

void position_error_mm(const std::vector<double>& rest, const std::vector<double>& x,
                       const std::vector<double>& ref_disp, double& rms_mm, double& max_mm) {
  double s = 0.0, mx = 0.0;
  const size_t n = rest.size() / 3;
  for (size_t i = 0; i < n; ++i) {
    double d2 = 0;
    for (int c = 0; c < 3; ++c) {
      const double d = x[3 * i + c] - (rest[3 * i + c] + ref_disp[3 * i + c]);
      d2 += d * d;
    }
    s += d2;
    mx = std::max(mx, std::sqrt(d2));
  }
  rms_mm = 1e3 * std::sqrt(s / std::max<size_t>(n, 1));
  max_mm = 1e3 * mx;
  if (!std::isfinite(s)) rms_mm = max_mm = std::numeric_limits<double>::infinity();
}

void restoration_mm(const std::vector<double>& rest, const std::vector<double>& x, double& mean_mm, double& sd_mm) {
  const size_t n = rest.size() / 3;
  std::vector<double> d(n);
  double sum = 0;
  for (size_t i = 0; i < n; ++i) {
    double d2 = 0;
    for (int c = 0; c < 3; ++c) d2 += (x[3 * i + c] - rest[3 * i + c]) * (x[3 * i + c] - rest[3 * i + c]);
    d[i] = 1e3 * std::sqrt(d2);
    sum += d[i];
  }
  mean_mm = sum / std::max<size_t>(n, 1);
  double v = 0;
  for (double di : d) v += (di - mean_mm) * (di - mean_mm);
  sd_mm = n > 1 ? std::sqrt(v / (n - 1)) : 0.0;  // paper 003 eq 32
}

double norm3(const std::array<double, 3>& v) { return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }

}  // namespace softatlas::evidence
