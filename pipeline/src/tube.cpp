// Tube model for large vessels (see tube.hpp). Geometry runs in grid millimetres
// (i * spacing_x, j * spacing_y, k * spacing_z): distances and angles are those of the patient
// for any orthonormal direction matrix.
#include "tube.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <queue>

#include "grid.hpp"

namespace softatlas::pipeline {
namespace {

using Vec3 = std::array<double, 3>;

Vec3 operator+(const Vec3& a, const Vec3& b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
Vec3 operator-(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
Vec3 operator*(double s, const Vec3& a) { return {s * a[0], s * a[1], s * a[2]}; }
double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
double norm(const Vec3& a) { return std::sqrt(dot(a, a)); }
Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
Vec3 unit(const Vec3& a) {
  const double l = norm(a);
  return l > 0 ? (1.0 / l) * a : Vec3{0, 0, 1};
}

struct Grid {
  std::array<int, 3> d;
  double sp[3];
  size_t index(int i, int j, int k) const {
    return static_cast<size_t>(i) +
           static_cast<size_t>(d[0]) * (static_cast<size_t>(j) + static_cast<size_t>(d[1]) * k);
  }
  std::array<int, 3> ijk(size_t id) const {
    return {static_cast<int>(id % d[0]), static_cast<int>((id / d[0]) % d[1]),
            static_cast<int>(id / (static_cast<size_t>(d[0]) * d[1]))};
  }
  Vec3 mm(size_t id) const {
    const auto c = ijk(id);
    return {c[0] * sp[0], c[1] * sp[1], c[2] * sp[2]};
  }
  bool inside(const Vec3& p) const {
    for (int a = 0; a < 3; ++a)
      if (p[a] < -0.5 * sp[a] || p[a] > (d[a] - 0.5) * sp[a]) return false;
    return true;
  }
  size_t nearest(const Vec3& p) const {
    int c[3];
    for (int a = 0; a < 3; ++a) c[a] = std::clamp(static_cast<int>(std::lround(p[a] / sp[a])), 0, d[a] - 1);
    return index(c[0], c[1], c[2]);
  }
  // Trilinear sample (clamped at the border).
  double sample(const std::vector<float>& f, const Vec3& p) const {
    double x[3];
    int c[3];
    for (int a = 0; a < 3; ++a) {
      const double u = std::clamp(p[a] / sp[a], 0.0, d[a] - 1.0);
      c[a] = std::min(static_cast<int>(u), d[a] - 2 < 0 ? 0 : d[a] - 2);
      x[a] = u - c[a];
    }
    double v = 0;
    for (int corner = 0; corner < 8; ++corner) {
      const int o[3] = {corner & 1, (corner >> 1) & 1, (corner >> 2) & 1};
      double w = 1;
      int q[3];
      for (int a = 0; a < 3; ++a) {
        w *= o[a] ? x[a] : 1 - x[a];
        q[a] = std::min(c[a] + o[a], d[a] - 1);
      }
      if (w > 0) v += w * f[index(q[0], q[1], q[2])];
    }
    return v;
  }
};

// Shortest paths from `source` through the region (cost falls with the depth inside it, so paths
// stay medial) and, at a high cost, through unclaimed non-fat voxels (gaps in the enhancement).
struct Paths {
  std::vector<float> dist;    // path cost
  std::vector<float> length;  // mm along the cheapest path
  std::vector<int64_t> pred;
};

Paths geodesic(const Grid& g, const std::vector<int>& depth, const std::vector<float>& smooth,
               const std::vector<char>& other_organ, double stop_hu, size_t source) {
  const size_t n = depth.size();
  Paths p{std::vector<float>(n, std::numeric_limits<float>::infinity()), std::vector<float>(n, 0.0f),
          std::vector<int64_t>(n, -1)};
  using Item = std::pair<float, size_t>;
  std::priority_queue<Item, std::vector<Item>, std::greater<Item>> heap;
  p.dist[source] = 0;
  heap.push({0.0f, source});
  while (!heap.empty()) {
    const auto [c, id] = heap.top();
    heap.pop();
    if (c > p.dist[id]) continue;
    for_each_face_neighbour(g.d, id, [&, c = c, id = id](size_t q, int axis) {
      double w;
      if (depth[q] > 0) {
        const double r = 4.0 / depth[q];
        w = g.sp[axis] * (1.0 + r * r);
      } else if (!other_organ[q] && smooth[q] >= stop_hu) {
        w = g.sp[axis] * 40.0;
      } else {
        return;
      }
      const float nc = static_cast<float>(c + w);
      if (nc < p.dist[q]) {
        p.dist[q] = nc;
        p.length[q] = p.length[id] + static_cast<float>(g.sp[axis]);
        p.pred[q] = static_cast<int64_t>(id);
        heap.push({nc, q});
      }
    });
  }
  return p;
}

struct Section {
  Vec3 c;
  double r = 0;
  double inliers = 0;  // share of rays whose end lies within 20 % of the fitted circle
};

struct Circle {
  double cx = 0, cy = 0, r = 0;
  double inliers = 0;  // share of all rays
  bool ok = false;
};

// Robust circle fit to ray ends len[k] * (cs[k], sn[k]) in a section's plane. Rays that leak into
// bone, muscle or a branch end too far out: start from the shorter 60 % of the rays, then keep the
// ends within 20 % of the circle (four rounds of a Kasa fit).
Circle fit_circle(const std::vector<double>& len, const std::vector<double>& cs, const std::vector<double>& sn,
                  double max_len) {
  const int rays = static_cast<int>(len.size());
  std::vector<double> sorted = len;
  const int q = static_cast<int>(0.6 * (rays - 1));
  std::nth_element(sorted.begin(), sorted.begin() + q, sorted.end());
  std::vector<char> use(rays);
  for (int k = 0; k < rays; ++k) use[k] = len[k] <= sorted[q] && len[k] < max_len;
  Circle c;
  for (int it = 0; it < 4; ++it) {
    // Kasa fit: x^2 + y^2 + D x + E y + F = 0, normal equations solved with partial pivoting.
    double m[3][4] = {};
    int in = 0;
    for (int k = 0; k < rays; ++k) {
      if (!use[k]) continue;
      const double x = len[k] * cs[k], y = len[k] * sn[k];
      const double row[3] = {x, y, 1}, rhs = -(x * x + y * y);
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) m[i][j] += row[i] * row[j];
        m[i][3] += row[i] * rhs;
      }
      ++in;
    }
    if (in < 5) return Circle{};
    for (int col = 0; col < 3; ++col) {
      int piv = col;
      for (int i = col + 1; i < 3; ++i)
        if (std::abs(m[i][col]) > std::abs(m[piv][col])) piv = i;
      std::swap(m[col], m[piv]);
      if (std::abs(m[col][col]) < 1e-12) return Circle{};
      for (int i = 0; i < 3; ++i) {
        if (i == col) continue;
        const double f = m[i][col] / m[col][col];
        for (int j = col; j < 4; ++j) m[i][j] -= f * m[col][j];
      }
    }
    const double D = m[0][3] / m[0][0], E = m[1][3] / m[1][1], F = m[2][3] / m[2][2];
    c.cx = -D / 2, c.cy = -E / 2;
    const double rr = c.cx * c.cx + c.cy * c.cy - F;
    if (rr <= 0) return Circle{};
    c.r = std::sqrt(rr);
    for (int k = 0; k < rays; ++k) {
      const double x = len[k] * cs[k], y = len[k] * sn[k];
      use[k] = std::abs(std::hypot(x - c.cx, y - c.cy) - c.r) <= std::max(0.2 * c.r, 1.5) && len[k] < max_len;
    }
  }
  int in = 0;
  for (char u : use) in += u;
  c.inliers = static_cast<double>(in) / rays;
  // The point the rays started from must lie inside the fitted circle.
  c.ok = std::hypot(c.cx, c.cy) <= c.r;
  return c;
}

// The rays of one section: directions in the plane normal to t.
struct Rays {
  Vec3 u, v;
  std::vector<double> cs, sn;
  std::vector<Vec3> dir;
  Rays(const Vec3& t, int n) : cs(n), sn(n), dir(n) {
    const Vec3 a = std::abs(t[0]) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
    u = unit(cross(t, a)), v = cross(t, u);
    for (int k = 0; k < n; ++k) {
      const double th = 2 * M_PI * k / n;
      cs[k] = std::cos(th), sn[k] = std::sin(th);
      dir[k] = cs[k] * u + sn[k] * v;
    }
  }
};

enum class Stop { go_on, here, after_wall };

// Ray lengths from c: each ray walks in steps of a quarter voxel until `stop(id, value, peak)`
// says so (at once, or after wall_mm more unless it stops at once before), or the grid's edge, or
// max_len. `peak` is the ray's own state (starts at -inf).
template <class F>
std::vector<double> cast(const Grid& g, const std::vector<float>& smooth, const Rays& rays, const Vec3& c,
                         double max_len, double wall_mm, F stop) {
  const double ds = 0.25 * std::min({g.sp[0], g.sp[1], g.sp[2]});
  std::vector<double> len(rays.dir.size());
  for (size_t k = 0; k < rays.dir.size(); ++k) {
    double l = 0, peak = -std::numeric_limits<double>::infinity(), end = max_len;
    while (l < end) {
      const Vec3 p = c + (l + ds) * rays.dir[k];
      if (!g.inside(p)) break;
      const Stop s = stop(g.nearest(p), g.sample(smooth, p), peak);
      if (s == Stop::here) break;
      if (s == Stop::after_wall && end == max_len) end = std::min(max_len, l + wall_mm);
      l += ds;
    }
    len[k] = std::min(l, end);
  }
  return len;
}

// Where every ray ends: at fat/air, at bright voxels not `ours` (bone, another vessel), at another
// organ or a background click.
bool leaves_vessel(const std::vector<char>& other_organ, const std::vector<char>& ours, const TubeOptions& o, size_t id,
                   double v) {
  return other_organ[id] || v < o.stop_hu || (v > o.bright_hu && !ours[id]);
}

// Fits a circle in the plane through c0 normal to t: rays stop at fat/air, at bright voxels not
// `ours`, at another organ or at the grid's edge; a robust circle fit to their ends gives the
// radius and the new centre, from which the rays are cast again (three rounds).
Section fat_section(const Grid& g, const std::vector<float>& smooth, const std::vector<char>& other_organ,
                    const std::vector<char>& ours, const Vec3& c0, const Rays& rays, const TubeOptions& o) {
  Vec3 c = c0;
  Section s{c, 0, 0};
  for (int round = 0; round < 3; ++round) {
    if (!g.inside(c) || smooth[g.nearest(c)] < o.stop_hu) return Section{c, 0, 0};
    const auto len = cast(g, smooth, rays, c, o.max_radius_mm, o.wall_mm, [&](size_t id, double v, double&) {
      return leaves_vessel(other_organ, ours, o, id, v) ? Stop::here : Stop::go_on;
    });
    const Circle f = fit_circle(len, rays.cs, rays.sn, o.max_radius_mm);
    if (!f.ok) return Section{c, 0, 0};
    s = Section{c, f.r, f.inliers};
    const Vec3 next = c + f.cx * rays.u + f.cy * rays.v;
    if (norm(next - c0) > 1.5 * f.r) break;
    c = next;
    s.c = c;
  }
  return s;
}

Section fit_section(const Grid& g, const std::vector<float>& smooth, const std::vector<char>& other_organ,
                    const std::vector<char>& ours, const Vec3& c0, const Vec3& t, const TubeOptions& o) {
  const Rays rays(t, o.rays);
  const Section fat = fat_section(g, smooth, other_organ, ours, c0, rays, o);
  if (fat.r <= 0 || o.lumen_min_hu <= 0) return fat;
  // From the fat circle's centre, rays that cross contrast-filled lumen end wall_mm past its
  // edge: where soft tissue rather than fat lies beyond the wall (the crura, the root's sinus),
  // the rays to fat run on through it. In a crescent of contrast beside unenhanced blood, rays
  // through the crescent end at the wall anyway and the others never see contrast.
  const auto len = cast(g, smooth, rays, fat.c, o.max_radius_mm, o.wall_mm, [&](size_t id, double v, double& peak) {
    if (leaves_vessel(other_organ, ours, o, id, v)) return Stop::here;
    peak = std::max(peak, v);
    return peak >= o.lumen_min_hu && v < std::min(o.lumen_edge_hu, o.tissue_hu + o.edge_fraction * (peak - o.tissue_hu))
               ? Stop::after_wall
               : Stop::go_on;
  });
  const Circle f = fit_circle(len, rays.cs, rays.sn, o.max_radius_mm);
  if (!f.ok) return fat;
  return Section{fat.c + f.cx * rays.u + f.cy * rays.v, f.r, f.inliers};
}

}  // namespace

std::vector<char> vessel_tube(const std::array<int, 3>& dims, const double spacing[3], const std::vector<float>& smooth,
                              const std::vector<int16_t>& owner, int self, const std::vector<char>& other_organ,
                              const std::vector<size_t>& seeds, const TubeOptions& o, TubeReport* report) {
  const Grid g{dims, {spacing[0], spacing[1], spacing[2]}};
  const size_t n = owner.size();
  if (seeds.size() < 2) return {};
  // Depth (6-neighbour steps) of every voxel of the region, for medial paths.
  // The region and a one-voxel rim (partial volume), `ours`: bright voxels outside it are another
  // structure (bone, another vessel), where a ray stops.
  std::vector<int> depth(n, 0);
  std::vector<char> ours(n, 0);
  std::vector<size_t> queue;
  for (size_t id = 0; id < n; ++id) {
    if (owner[id] != self) continue;
    ours[id] = 1;
    bool edge = false;
    for_each_face_neighbour(dims, id, [&](size_t q, int) {
      ours[q] = 1;
      edge = edge || owner[q] != self;
    });
    if (edge) depth[id] = 1, queue.push_back(id);
  }
  for (size_t h = 0; h < queue.size(); ++h) {
    const size_t id = queue[h];
    for_each_face_neighbour(dims, id, [&](size_t q, int) {
      if (owner[q] == self && depth[q] == 0) depth[q] = depth[id] + 1, queue.push_back(q);
    });
  }
  for (size_t id = 0; id < n; ++id)
    if (owner[id] == self && depth[id] == 0) depth[id] = 1;  // region voxels on the grid's edge only

  // The ends of the centreline: the two seeds farthest apart along the cheapest path between
  // them (its length, not its cost, which a seed in unenhanced blood inflates), found by a double
  // sweep (exact on a tree-like vessel).
  auto farthest = [&](const Paths& p) {
    size_t best = seeds[0];
    for (size_t s : seeds)
      if (std::isfinite(p.dist[s]) && p.length[s] > p.length[best]) best = s;
    return best;
  };
  const size_t a = farthest(geodesic(g, depth, smooth, other_organ, o.stop_hu, seeds[0]));
  const Paths pa = geodesic(g, depth, smooth, other_organ, o.stop_hu, a);
  const size_t b = farthest(pa);
  if (b == a || !std::isfinite(pa.dist[b])) return {};
  std::vector<Vec3> path;
  for (int64_t id = static_cast<int64_t>(b); id >= 0; id = pa.pred[static_cast<size_t>(id)]) path.push_back(g.mm(id));

  // Resample every step_mm of arc length.
  std::vector<Vec3> pts{path.front()};
  double carry = 0;
  for (size_t i = 1; i < path.size(); ++i) {
    const Vec3 e = path[i] - path[i - 1];
    const double l = norm(e);
    double at = o.step_mm - carry;
    while (at <= l) {
      pts.push_back(path[i - 1] + (at / l) * e);
      at += o.step_mm;
    }
    carry = l - (at - o.step_mm);
  }
  if (norm(path.back() - pts.back()) > 0.5 * o.step_mm) pts.push_back(path.back());
  auto smooth_points = [](std::vector<Vec3>& p, int half) {
    std::vector<Vec3> out(p.size());
    for (size_t i = 0; i < p.size(); ++i) {
      Vec3 s{0, 0, 0};
      int cnt = 0;
      for (int k = -half; k <= half; ++k) {
        const long j = static_cast<long>(i) + k;
        if (j < 0 || j >= static_cast<long>(p.size())) continue;
        s = s + p[static_cast<size_t>(j)], ++cnt;
      }
      out[i] = (1.0 / cnt) * s;
    }
    p.swap(out);
  };
  // The voxel path wanders inside a thin crescent of contrast; tangents come from a path smoothed
  // over +-5 samples, and the fit is repeated from the smoothed fitted centres.
  smooth_points(pts, 5);
  // The last samples at each end see a one-sided window, and the path there wanders to a seed
  // that may lie anywhere in the lumen: their tangents can lie across the vessel. They are
  // dropped; the end extension below walks the vessel on from the clean part.
  if (pts.size() >= 8 * static_cast<size_t>(o.end_trim))
    pts = std::vector<Vec3>(pts.begin() + o.end_trim, pts.end() - o.end_trim);
  if (pts.size() < 3) return {};
  auto tangent = [](const std::vector<Vec3>& p, size_t i) {
    const size_t lo = i > 1 ? i - 2 : 0, hi = std::min(i + 2, p.size() - 1);
    return unit(p[hi] - p[lo]);
  };
  std::vector<Section> sec(pts.size());
  for (int pass = 0; pass < 3; ++pass) {
    for (size_t i = 0; i < pts.size(); ++i)
      sec[i] = fit_section(g, smooth, other_organ, ours, pts[i], tangent(pts, i), o);
    for (size_t i = 0; i < pts.size(); ++i)
      if (sec[i].r > 0) pts[i] = sec[i].c;
    smooth_points(pts, 3);
  }

  // Extend both ends along the vessel while the cross-section stays round, of a similar radius,
  // inside the grid and out of other organs.
  auto median_radius = [](const std::vector<Section>& s, size_t from, size_t to) {
    std::vector<double> r;
    for (size_t i = from; i < to; ++i)
      if (s[i].r > 0) r.push_back(s[i].r);
    if (r.empty()) return 0.0;
    std::nth_element(r.begin(), r.begin() + r.size() / 2, r.end());
    return r[r.size() / 2];
  };
  for (int end = 0; end < 2; ++end) {
    if (end == 1) std::reverse(sec.begin(), sec.end());
    // sec.back() is the end being extended; the vessel may bend, but not turn by more than
    // max_turn_deg from its direction at the end of the centreline (else the sections walk off
    // sideways into whatever soft tissue meets the vessel there).
    const size_t m0 = sec.size();
    const Vec3 t0 = unit(sec[m0 - 1].c - sec[std::max<size_t>(m0, 4) - 4].c);
    for (int step = 0; step < 200; ++step) {
      const size_t m = sec.size();
      const Vec3 t = unit(sec[m - 1].c - sec[std::max<size_t>(m, 4) - 4].c);
      if (dot(t, t0) < std::cos(o.max_turn_deg * M_PI / 180)) break;
      const double r_ref = median_radius(sec, m > 8 ? m - 8 : 0, m);
      const Vec3 next = sec[m - 1].c + o.step_mm * t;
      if (!g.inside(next)) {
        // The vessel leaves the image: one more section so the tube reaches the edge.
        sec.push_back(Section{next, sec[m - 1].r, 1});
        break;
      }
      if (other_organ[g.nearest(next)]) break;
      Section s = fit_section(g, smooth, other_organ, ours, next, t, o);
      if (s.r <= 0 || s.inliers < 0.5 || s.r < 0.6 * r_ref || s.r > 1.4 * r_ref) break;
      // Keep going on along the vessel: the re-centred point must move forward and not jump
      // sideways by more than a quarter radius (a branch or a chamber, not the vessel).
      const Vec3 e = s.c - sec[m - 1].c;
      const double ahead = dot(e, t);
      if (ahead <= 0 || norm(e - ahead * t) > 0.25 * r_ref) break;
      sec.push_back(s);
    }
  }
  // Drop sections that failed (centre in fat), then smooth radii (median of 9, less the wall) and
  // centres.
  std::vector<Section> good;
  for (const auto& s : sec)
    if (s.r > 0) good.push_back(s);
  if (good.size() < 3) return {};
  std::vector<double> rad(good.size());
  for (size_t i = 0; i < good.size(); ++i) {
    std::vector<double> w;
    for (long k = -4; k <= 4; ++k) {
      const long j = static_cast<long>(i) + k;
      if (j >= 0 && j < static_cast<long>(good.size())) w.push_back(good[static_cast<size_t>(j)].r);
    }
    std::nth_element(w.begin(), w.begin() + w.size() / 2, w.end());
    rad[i] = std::max(w[w.size() / 2] - o.wall_mm, 0.5 * w[w.size() / 2]);
  }
  std::vector<Vec3> centre(good.size());
  for (size_t i = 0; i < good.size(); ++i) centre[i] = good[i].c;
  smooth_points(centre, 1);

  // Rasterise the capsules between consecutive sections (flat at the two ends).
  std::vector<char> tube(n, 0);
  for (size_t s = 0; s + 1 < centre.size(); ++s) {
    const Vec3 c0 = centre[s], c1 = centre[s + 1], e = c1 - c0;
    const double r0 = rad[s], r1 = rad[s + 1], ee = std::max(dot(e, e), 1e-12), rm = std::max(r0, r1) + o.wall_mm;
    int lo[3], hi[3];
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::max(0, static_cast<int>(std::floor((std::min(c0[a], c1[a]) - rm) / g.sp[a])));
      hi[a] = std::min(dims[a] - 1, static_cast<int>(std::ceil((std::max(c0[a], c1[a]) + rm) / g.sp[a])));
    }
    for (int k = lo[2]; k <= hi[2]; ++k)
      for (int j = lo[1]; j <= hi[1]; ++j)
        for (int i = lo[0]; i <= hi[0]; ++i) {
          const Vec3 p{i * g.sp[0], j * g.sp[1], k * g.sp[2]};
          double tau = dot(p - c0, e) / ee;
          if ((s == 0 && tau < 0) || (s + 2 == centre.size() && tau > 1)) continue;
          tau = std::clamp(tau, 0.0, 1.0);
          const Vec3 q = c0 + tau * e;
          const double r = r0 + tau * (r1 - r0);
          const size_t id = g.index(i, j, k);
          const double q2 = dot(p - q, p - q);
          if (other_organ[id] || q2 > (r + o.wall_mm) * (r + o.wall_mm)) continue;
          if (q2 <= r * r)
            tube[id] = kTubeInside;
          else if (tube[id] == 0)
            tube[id] = kTubeWall;
        }
  }
  // Beyond the last sections, the grown region continues the vessel where no round section was
  // found (a crossing of the diaphragm, the image's edge): its voxels within the end radius of
  // the end's axis and up to four radii further are kept.
  for (int end = 0; end < 2; ++end) {
    const size_t m = centre.size();
    const Vec3 c = end == 0 ? centre[0] : centre[m - 1];
    const Vec3 t = end == 0 ? unit(centre[0] - centre[std::min<size_t>(3, m - 1)])
                            : unit(centre[m - 1] - centre[m > 4 ? m - 4 : 0]);
    const double r = (end == 0 ? rad[0] : rad[m - 1]) + g.sp[0];
    const double reach = 4 * r;
    int lo[3], hi[3];
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::max(0, static_cast<int>(std::floor((std::min(c[a], c[a] + reach * t[a]) - r) / g.sp[a])));
      hi[a] = std::min(dims[a] - 1, static_cast<int>(std::ceil((std::max(c[a], c[a] + reach * t[a]) + r) / g.sp[a])));
    }
    for (int k = lo[2]; k <= hi[2]; ++k)
      for (int j = lo[1]; j <= hi[1]; ++j)
        for (int i = lo[0]; i <= hi[0]; ++i) {
          const size_t id = g.index(i, j, k);
          if (owner[id] != self) continue;
          const Vec3 p = Vec3{i * g.sp[0], j * g.sp[1], k * g.sp[2]} - c;
          const double along = dot(p, t);
          if (along <= 0 || along > reach) continue;
          const Vec3 radial = p - along * t;
          if (dot(radial, radial) <= r * r) tube[id] = kTubeInside;
        }
  }
  if (report) {
    report->sections = good.size();
    std::vector<double> r = rad;
    std::nth_element(r.begin(), r.begin() + r.size() / 2, r.end());
    report->median_radius_mm = r[r.size() / 2];
    double len = 0;
    for (size_t i = 1; i < centre.size(); ++i) len += norm(centre[i] - centre[i - 1]);
    report->length_mm = len;
  }
  return tube;
}

}  // namespace softatlas::pipeline
