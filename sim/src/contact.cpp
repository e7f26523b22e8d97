// Contact between organs: detection in a spatial hash grid of face centroids, position
// projection of penetrating vertices (sim/contact.hpp has the method and its exemptions).
#include "softatlas/sim/contact.hpp"

#include <algorithm>
#include <cmath>

#include "engine.hpp"

namespace softatlas::sim {

namespace {

constexpr int kContactSweeps = 3;    // Gauss-Seidel sweeps over the step's contacts per round
constexpr int kContactRounds = 3;    // rounds of sweeps and lattice transfer per step
constexpr double kLetGoDepth = 2.0;  // detection radius in depths (deeper vertices are let go)
// Two organs whose surfaces overlap deeper than this at rest get no contact between them: a vessel
// inside the liver, a vein in its groove (contact between them inverted the vein, 21 mm residual
// and -292 % volume in bench restore on the CT abdomen set); a voxel or two of overlap is normal.
constexpr double kJoinedDepth_m = 2e-3;
// Speed at which a tool hold that contact stopped at another organ's surface returns toward the
// device when contact lets it (follow_contact).
constexpr double kHoldReturn_m_s = 0.1;

struct Positions {
  const double* x;
  const double* y;
  const double* z;
};

// Closest point of triangle abc to p as barycentric weights (Ericson, Real-Time Collision
// Detection, 5.1.5).
void closest_on_triangle(const double p[3], const double a[3], const double b[3], const double c[3], double w[3]) {
  double ab[3], ac[3], ap[3];
  for (int k = 0; k < 3; ++k) ab[k] = b[k] - a[k], ac[k] = c[k] - a[k], ap[k] = p[k] - a[k];
  auto dot = [](const double* u, const double* v) { return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]; };
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) {
    w[0] = 1, w[1] = w[2] = 0;
    return;
  }
  double bp[3], cp[3];
  for (int k = 0; k < 3; ++k) bp[k] = p[k] - b[k], cp[k] = p[k] - c[k];
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) {
    w[1] = 1, w[0] = w[2] = 0;
    return;
  }
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double t = d1 / (d1 - d3);
    w[0] = 1 - t, w[1] = t, w[2] = 0;
    return;
  }
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) {
    w[2] = 1, w[0] = w[1] = 0;
    return;
  }
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double t = d2 / (d2 - d6);
    w[0] = 1 - t, w[2] = t, w[1] = 0;
    return;
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    w[1] = 1 - t, w[2] = t, w[0] = 0;
    return;
  }
  const double den = 1.0 / (va + vb + vc);
  w[1] = vb * den, w[2] = vc * den, w[0] = 1 - w[1] - w[2];
}

int32_t bucket_of(int64_t ix, int64_t iy, int64_t iz, int32_t table) {
  const uint64_t h = static_cast<uint64_t>(ix) * 73856093u ^ static_cast<uint64_t>(iy) * 19349663u ^
                     static_cast<uint64_t>(iz) * 83492791u;
  return static_cast<int32_t>(h & static_cast<uint64_t>(table - 1));
}

int64_t cell_index(double v, double cell) { return static_cast<int64_t>(std::floor(v / cell)); }

void load(const Positions& P, int32_t v, double p[3]) { p[0] = P.x[v], p[1] = P.y[v], p[2] = P.z[v]; }

// Bounding boxes of every organ; pairs whose boxes, grown by `grow`, overlap. With `step_rules`
// pairs need one awake and one non-rigid organ (a pair of sleeping or of rigid organs cannot move).
int32_t find_pairs(const Model& m, const State* s, const Positions& P, double grow, ContactWork& cw) {
  const size_t no = m.organs.size();
  for (size_t o = 0; o < no; ++o) {
    double* b = &cw.box[6 * o];
    b[0] = b[1] = b[2] = INFINITY, b[3] = b[4] = b[5] = -INFINITY;
    for (int32_t v = m.organs[o].vert_begin; v < m.organs[o].vert_end; ++v) {
      const double p[3] = {P.x[v], P.y[v], P.z[v]};
      for (int k = 0; k < 3; ++k) b[k] = std::min(b[k], p[k]), b[3 + k] = std::max(b[3 + k], p[k]);
    }
  }
  std::fill(cw.organ_paired.begin(), cw.organ_paired.end(), uint8_t{0});
  std::fill(cw.pair.begin(), cw.pair.end(), uint8_t{0});
  int32_t pairs = 0;
  for (size_t a = 0; a < no; ++a)
    for (size_t b = a + 1; b < no; ++b) {
      const double* A = &cw.box[6 * a];
      const double* B = &cw.box[6 * b];
      bool overlap = true;
      for (int k = 0; k < 3; ++k) overlap = overlap && A[k] - grow <= B[3 + k] && B[k] - grow <= A[3 + k];
      if (!overlap) continue;
      if (!m.contact.joined.empty() && m.contact.joined[a * no + b]) continue;
      if (s) {
        const bool ra = m.organs[a].model == ModelKind::rigid, rb = m.organs[b].model == ModelKind::rigid;
        if (ra && rb) continue;
        if (!s->organ_awake[a] && !s->organ_awake[b]) continue;
      }
      cw.pair[a * no + b] = cw.pair[b * no + a] = 1;
      cw.organ_paired[a] = cw.organ_paired[b] = 1;
      ++pairs;
    }
  return pairs;
}

// The faces of the paired organs into the hash grid (counting sort by bucket).
void build_grid(const Model& m, const Positions& P, ContactWork& cw) {
  const int32_t T = m.contact.table_size;
  std::fill(cw.bucket_start.begin(), cw.bucket_start.end(), 0);
  double rmax = 0.0;
  cw.nbig = 0;
  for (size_t o = 0; o < m.organs.size(); ++o) {
    const OrganRange& r = m.organs[o];
    for (int32_t f = r.face_begin; f < r.face_end; ++f) {
      cw.face_bucket[f] = -1;
      if (!cw.organ_paired[o]) continue;
      double c[3] = {0, 0, 0}, q[3][3];
      for (int i = 0; i < 3; ++i) {
        load(P, m.face_vert[3 * f + i], q[i]);
        for (int k = 0; k < 3; ++k) c[k] += q[i][k] / 3.0;
      }
      double* sph = &cw.face_sphere[4 * static_cast<size_t>(f)];
      sph[0] = c[0], sph[1] = c[1], sph[2] = c[2], sph[3] = 0.0;
      for (int i = 0; i < 3; ++i)
        sph[3] = std::max(sph[3], std::sqrt((q[i][0] - c[0]) * (q[i][0] - c[0]) + (q[i][1] - c[1]) * (q[i][1] - c[1]) +
                                            (q[i][2] - c[2]) * (q[i][2] - c[2])));
      if (sph[3] > m.contact.cell_m) {  // a face stretched past a cell: scanned by every query
        cw.face_bucket[f] = -2;
        cw.big_face[cw.nbig++] = f;
        continue;
      }
      rmax = std::max(rmax, sph[3]);
      const int32_t bk = bucket_of(cell_index(c[0], m.contact.cell_m), cell_index(c[1], m.contact.cell_m),
                                   cell_index(c[2], m.contact.cell_m), T);
      cw.face_bucket[f] = bk;
      ++cw.bucket_start[bk + 1];
    }
  }
  for (int32_t i = 0; i < T; ++i) cw.bucket_start[i + 1] += cw.bucket_start[i];
  // fill: bucket_start[b] is advanced while filling, then shifted back
  for (int32_t f = 0; f < m.nface; ++f)
    if (cw.face_bucket[f] >= 0) cw.bucket_face[cw.bucket_start[cw.face_bucket[f]]++] = f;
  for (int32_t i = T; i > 0; --i) cw.bucket_start[i] = cw.bucket_start[i - 1];
  cw.bucket_start[0] = 0;
  cw.face_radius = rmax;
}

struct Nearest {
  int32_t face = -1;
  double dist2 = INFINITY;
  double bary[3] = {0, 0, 0};
  double normal[3] = {0, 0, 0};  // unit outward normal of the face
  double signed_dist = 0.0;      // along the normal: < 0 behind the face (inside its organ)
};

// Nearest face, within `radius` of p, of an organ paired with `self`.
Nearest nearest_face(const Model& m, const Positions& P, const ContactWork& cw, const double p[3], int32_t self,
                     double radius) {
  Nearest best;
  const double cell = m.contact.cell_m;
  const double reach = radius + cw.face_radius;  // a face's centroid is within this of p
  const int64_t lo[3] = {cell_index(p[0] - reach, cell), cell_index(p[1] - reach, cell),
                         cell_index(p[2] - reach, cell)};
  const int64_t hi[3] = {cell_index(p[0] + reach, cell), cell_index(p[1] + reach, cell),
                         cell_index(p[2] + reach, cell)};
  const size_t no = m.organs.size();
  const int32_t T = m.contact.table_size;
  const int64_t cells = (hi[0] - lo[0] + 1) * (hi[1] - lo[1] + 1) * (hi[2] - lo[2] + 1);
  // A search wider than the table visits buckets more than once: scan every face then.
  const bool all = cells > T;
  auto visit = [&](int32_t f) {
    const int32_t o = m.vert_organ[m.face_vert[3 * f]];
    if (o == self || !cw.pair[static_cast<size_t>(self) * no + o]) return;
    // the face's bounding sphere first: most faces of the scanned cells are farther than that
    const double* sph = &cw.face_sphere[4 * static_cast<size_t>(f)];
    const double cx = p[0] - sph[0], cy = p[1] - sph[1], cz = p[2] - sph[2];
    const double lim = std::min(radius, std::sqrt(best.dist2)) + sph[3];
    if (cx * cx + cy * cy + cz * cz > lim * lim) return;
    double a[3], b[3], c[3], w[3];
    load(P, m.face_vert[3 * f], a), load(P, m.face_vert[3 * f + 1], b), load(P, m.face_vert[3 * f + 2], c);
    closest_on_triangle(p, a, b, c, w);
    double d[3], d2 = 0;
    for (int k = 0; k < 3; ++k) d[k] = p[k] - (w[0] * a[k] + w[1] * b[k] + w[2] * c[k]), d2 += d[k] * d[k];
    if (d2 > radius * radius) return;
    // Faces that share the closest point (an edge or a corner) tie: the one whose plane faces p
    // most squarely decides the side (a point outside a saddle corner is behind some of them).
    const double tie = 1e-12 * (best.dist2 + 1e-12);
    if (d2 > best.dist2 + tie) return;
    double e1[3], e2[3];
    for (int k = 0; k < 3; ++k) e1[k] = b[k] - a[k], e2[k] = c[k] - a[k];
    double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (!(len > 0)) return;  // a collapsed face has no side
    const double sg = m.contact.organ_sign[o] / len;
    const double sd = (d[0] * n[0] + d[1] * n[1] + d[2] * n[2]) * sg;
    if (d2 >= best.dist2 - tie && best.face >= 0) {  // a tie: keep the squarer face
      const double dn = std::sqrt(d2);
      if (!(dn > 0) || std::abs(sd) <= std::abs(best.signed_dist)) return;
    }
    best.face = f, best.dist2 = d2;
    for (int k = 0; k < 3; ++k) best.bary[k] = w[k], best.normal[k] = n[k] * sg;
    best.signed_dist = sd;
  };
  for (int32_t i = 0; i < cw.nbig; ++i) visit(cw.big_face[i]);
  if (all) {
    for (int32_t f = 0; f < m.nface; ++f)
      if (cw.face_bucket[f] >= 0) visit(f);
    return best;
  }
  for (int64_t ix = lo[0]; ix <= hi[0]; ++ix)
    for (int64_t iy = lo[1]; iy <= hi[1]; ++iy)
      for (int64_t iz = lo[2]; iz <= hi[2]; ++iz) {
        const int32_t bk = bucket_of(ix, iy, iz, T);
        for (int32_t i = cw.bucket_start[bk]; i < cw.bucket_start[bk + 1]; ++i) visit(cw.bucket_face[i]);
      }
  return best;
}

bool in_partner_box(const Model& m, const ContactWork& cw, int32_t self, const double p[3], double grow) {
  const size_t no = m.organs.size();
  for (size_t o = 0; o < no; ++o) {
    if (!cw.pair[static_cast<size_t>(self) * no + o]) continue;
    const double* b = &cw.box[6 * o];
    if (p[0] >= b[0] - grow && p[0] <= b[3] + grow && p[1] >= b[1] - grow && p[1] <= b[4] + grow &&
        p[2] >= b[2] - grow && p[2] <= b[5] + grow)
      return true;
  }
  return false;
}

// Crossings of the ray p + t dir, 0 < t <= t_max, with organ o's faces (Moller-Trumbore).
int crossings(const Model& m, const Positions& P, const double p[3], const double dir[3], double t_max, int32_t o) {
  int hits = 0;
  for (int32_t f = m.organs[o].face_begin; f < m.organs[o].face_end; ++f) {
    double a[3], b[3], c[3];
    load(P, m.face_vert[3 * f], a), load(P, m.face_vert[3 * f + 1], b), load(P, m.face_vert[3 * f + 2], c);
    double e1[3], e2[3], t[3];
    for (int k = 0; k < 3; ++k) e1[k] = b[k] - a[k], e2[k] = c[k] - a[k], t[k] = p[k] - a[k];
    const double h[3] = {dir[1] * e2[2] - dir[2] * e2[1], dir[2] * e2[0] - dir[0] * e2[2],
                         dir[0] * e2[1] - dir[1] * e2[0]};
    const double det = e1[0] * h[0] + e1[1] * h[1] + e1[2] * h[2];
    if (std::abs(det) < 1e-30) continue;
    const double u = (t[0] * h[0] + t[1] * h[1] + t[2] * h[2]) / det;
    if (u < 0 || u > 1) continue;
    const double q[3] = {t[1] * e1[2] - t[2] * e1[1], t[2] * e1[0] - t[0] * e1[2], t[0] * e1[1] - t[1] * e1[0]};
    const double v = (dir[0] * q[0] + dir[1] * q[1] + dir[2] * q[2]) / det;
    if (v < 0 || u + v > 1) continue;
    const double tt = (e2[0] * q[0] + e2[1] * q[1] + e2[2] * q[2]) / det;
    if (tt > 0 && tt <= t_max) ++hits;
  }
  return hits;
}

// Ray parity: whether p is inside organ o's closed surface (a skewed ray, so that it meets no edge
// of a regular mesh exactly). For the measurement and the rest exemptions, where the nearest
// face's side can be wrong far from the surface (a point in a curved organ's concavity).
bool inside_by_parity(const Model& m, const Positions& P, const double p[3], int32_t o) {
  const double dir[3] = {1.0, 0.0013717, 0.0021523};
  return crossings(m, P, p, dir, INFINITY, o) % 2 == 1;
}

// Whether the straight way from vertex v (of organ `self`) back to its rest position crosses a
// partner organ: then v is on the far side of it (pushed through). The rest position as compiled:
// the organs of an atlas are anchored (the organ's mean displacement added to it put the way home
// of a sphere pushed as a whole inside its neighbour).
bool way_home_blocked(const Model& m, const Positions& P, const ContactWork& cw, int32_t v, int32_t self) {
  double p[3];
  load(P, v, p);
  const double home[3] = {m.vert_rest_x[v], m.vert_rest_y[v], m.vert_rest_z[v]};
  const double dir[3] = {home[0] - p[0], home[1] - p[1], home[2] - p[2]};
  const size_t no = m.organs.size();
  for (size_t o = 0; o < no; ++o) {
    if (!cw.pair[static_cast<size_t>(self) * no + o]) continue;
    const double* b = &cw.box[6 * o];
    bool overlap = true;  // the segment's box against the partner's
    for (int k = 0; k < 3; ++k)
      overlap = overlap && std::min(p[k], home[k]) <= b[3 + k] && std::max(p[k], home[k]) >= b[k];
    if (overlap && crossings(m, P, p, dir, 1.0, static_cast<int32_t>(o)) > 0) return true;
  }
  return false;
}

bool held_now(const State& s, int32_t v) {
  return s.tool.mode == ToolMode::attach && std::binary_search(s.tool.verts.begin(), s.tool.verts.end(), v);
}

// Nearest partner face at any distance (the search radius doubles from the contact depth up to the
// model's size): whether p lies inside a partner organ, and how deep.
Nearest nearest_any(const Model& m, const Positions& P, const ContactWork& cw, const double p[3], int32_t self) {
  Nearest n;
  for (double r = m.contact.depth_m; n.face < 0 && r < 4.0 * m.size_m + m.contact.depth_m; r *= 2.0)
    n = nearest_face(m, P, cw, p, self, r);
  return n;
}

}  // namespace

void compile_contact(bool on, Model& m) {
  ContactModel& c = m.contact;
  c = ContactModel{};
  if (!on || m.organs.size() < 2 || m.nface == 0) return;
  c.on = true;
  const size_t no = m.organs.size();
  c.organ_sign.assign(no, 1);
  for (size_t o = 0; o < no; ++o) c.organ_sign[o] = m.organs[o].rest_volume_m3 < 0 ? -1 : 1;
  c.vert_movable.assign(m.nvert, 0);
  for (int32_t v = 0; v < m.nvert; ++v)
    c.vert_movable[v] = m.vert_inv_mass[v] > 0 && m.organs[m.vert_organ[v]].model != ModelKind::rigid;
  int32_t T = 1024;
  while (T < 2 * m.nface) T *= 2;
  c.table_size = T;
  // Cell: the contact depth plus the typical face's reach, so that a query scans 3^3 cells.
  std::vector<double> reach;
  reach.reserve(m.nface);
  for (int32_t f = 0; f < m.nface; ++f) {
    const int32_t a = m.face_vert[3 * f], b = m.face_vert[3 * f + 1];
    const double dx = m.vert_rest_x[b] - m.vert_rest_x[a], dy = m.vert_rest_y[b] - m.vert_rest_y[a],
                 dz = m.vert_rest_z[b] - m.vert_rest_z[a];
    reach.push_back(std::sqrt(dx * dx + dy * dy + dz * dz));
  }
  std::nth_element(reach.begin(), reach.begin() + reach.size() / 2, reach.end());
  c.cell_m = c.depth_m + reach[reach.size() / 2];
  // Vertices inside another organ at rest.
  c.rest_inside.assign(m.nvert, 0);
  c.joined.assign(no * no, 0);
  ContactWork cw = make_contact_work(m);
  const Positions P{m.vert_rest_x.data(), m.vert_rest_y.data(), m.vert_rest_z.data()};
  if (find_pairs(m, nullptr, P, c.depth_m, cw) == 0) return;
  build_grid(m, P, cw);
  for (size_t o = 0; o < no; ++o) {
    if (!cw.organ_paired[o]) continue;
    for (int32_t v = m.organs[o].vert_begin; v < m.organs[o].vert_end; ++v) {
      double p[3];
      load(P, v, p);
      if (!in_partner_box(m, cw, static_cast<int32_t>(o), p, c.depth_m)) continue;
      const Nearest n = nearest_any(m, P, cw, p, static_cast<int32_t>(o));
      if (n.face < 0 || n.signed_dist >= 0) continue;
      const int32_t other = m.vert_organ[m.face_vert[3 * n.face]];
      if (!inside_by_parity(m, P, p, other)) continue;
      c.rest_inside[v] = 1;
      // organs that overlap deeply at rest (a vessel running inside the liver) are one body here
      if (-n.signed_dist > kJoinedDepth_m) c.joined[o * no + other] = c.joined[other * no + o] = 1;
    }
  }
}

ContactWork make_contact_work(const Model& m) {
  ContactWork cw;
  if (!m.contact.on) return cw;
  const size_t no = m.organs.size();
  cw.box.assign(6 * no, 0.0);
  cw.organ_paired.assign(no, 0);
  cw.pair.assign(no * no, 0);
  cw.bucket_start.assign(static_cast<size_t>(m.contact.table_size) + 1, 0);
  cw.bucket_face.assign(m.nface, 0);
  cw.face_bucket.assign(m.nface, -1);
  cw.face_sphere.assign(4 * static_cast<size_t>(m.nface), 0.0);
  cw.big_face.assign(m.nface, 0);
  cw.c_vert.assign(m.nvert, 0), cw.c_face.assign(m.nvert, 0);
  cw.c_bary.assign(3 * static_cast<size_t>(m.nvert), 0.0), cw.c_normal.assign(3 * static_cast<size_t>(m.nvert), 0.0);
  cw.saved.assign(3 * static_cast<size_t>(m.nvert), 0.0);
  cw.weight = m.contact.vert_movable;
  cw.touched.assign(m.nvert, 0);
  cw.held_before.assign(3 * static_cast<size_t>(m.nvert), 0.0);
  cw.clear.assign(m.nvert, 0.0), cw.moved.assign(m.nvert, 0.0);
  cw.last_x.resize(3 * static_cast<size_t>(m.nvert));
  for (int32_t v = 0; v < m.nvert; ++v)
    cw.last_x[3 * v] = m.vert_rest_x[v], cw.last_x[3 * v + 1] = m.vert_rest_y[v],
                  cw.last_x[3 * v + 2] = m.vert_rest_z[v];
  cw.organ_moved.assign(no, 0.0);
  cw.pair_before.assign(no * no, 0);
  size_t nodes = 0;
  for (const SolidBody& b : m.solids) nodes = std::max(nodes, static_cast<size_t>(b.node_begin + b.nnode));
  cw.node_acc.assign(4 * nodes, 0.0);
  cw.node_stop.assign(nodes, 0);
  return cw;
}

namespace {

// The tool's held vertices as a proxy that contact stops at another organ's surface (the god
// object of haptic rendering, Zilles and Salisbury 1995): the mean of what contact did to the
// held vertices this step stays in their targets (ToolState::contact_shift, one vector: the held
// patch moves as one, like a probe's tip), and the shift returns toward the device at
// kHoldReturn_m_s when contact does not push. Without it the hold drives the vertices back into
// the organ every step, the lattice carries the vertices around them in, deeper than contact
// projects: the pushed pancreas ended 11.7 mm inside the kidney. One shift per held vertex made
// targets that the lattice could not meet: a kidney vertex jumped 5 mm in one step.
void follow_contact(const Model& m, State& s, const ContactWork& cw, bool projected) {
  ToolState& t = s.tool;
  if (t.mode != ToolMode::attach || t.verts.empty()) return;
  double d[3] = {0, 0, 0};
  if (projected)
    for (int32_t v : t.verts) {
      d[0] += s.x[v] - cw.held_before[3 * v], d[1] += s.y[v] - cw.held_before[3 * v + 1];
      d[2] += s.z[v] - cw.held_before[3 * v + 2];
    }
  double* c = t.contact_shift.data();
  if (d[0] != 0 || d[1] != 0 || d[2] != 0) {
    for (int k = 0; k < 3; ++k) c[k] += d[k] / static_cast<double>(t.verts.size());
    return;
  }
  const double back = kHoldReturn_m_s * m.dt_s;
  const double len = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
  const double keep = len > back ? 1.0 - back / len : 0.0;
  for (int k = 0; k < 3; ++k) c[k] *= keep;
}

// Inelastic contact: a velocity (a spring organ's vertex, a lattice node) whose position the
// projection moved by d loses its component against d (into what it touched), by at most |d| / h;
// nothing is added away from it. A spring organ's vertices land where the projection puts them:
// the penetrating vertex and the face's corners both stop. A solid organ's lattice smooths what
// its surface was given (the surface follows the nodes, a residual is left): only the nodes that
// carry penetrating vertices stop; those moved for a face's corners move in position only, their
// velocity left to the organ's elasticity. Measured on the CT abdomen set (`bench contact`): the
// displacement added as velocity d / h (the earlier rule) pumped energy into organs squeezed
// between the tool and a bone or vessel (the back muscle 26 mm from rest under a 2 mm push, the
// splenic vein 14 mm inside the spleen); stopping the face corners' nodes too ratcheted: a
// vertebra corner behind the back muscle's face pushed the face in every step while its elastic
// recovery was cancelled every step (30 mm from rest). Positions only everywhere (no stop) let a
// free sphere pushed into another keep its momentum: 11 mm inside (Contact.PushedSphere...).
void stop_approach(double& vx, double& vy, double& vz, const double d[3], double h) {
  const double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  if (!(len > 0)) return;
  const double u[3] = {d[0] / len, d[1] / len, d[2] / len};
  const double vn = vx * u[0] + vy * u[1] + vz * u[2];
  if (vn >= 0) return;
  const double dv = std::min(-vn, len / h);
  vx += dv * u[0], vy += dv * u[1], vz += dv * u[2];
}

// One round of the projection over the step's contacts; returns how many were violated.
int project_round(const Model& m, State& s, Work& w, int32_t nc) {
  ContactWork& cw = w.contact;
  const size_t no = m.organs.size();
  int violated = 0;
  std::copy(s.x.begin(), s.x.end(), cw.saved.begin());
  std::copy(s.y.begin(), s.y.end(), cw.saved.begin() + m.nvert);
  std::copy(s.z.begin(), s.z.end(), cw.saved.begin() + 2 * static_cast<size_t>(m.nvert));
  double* X[3] = {s.x.data(), s.y.data(), s.z.data()};
  for (int sweep = 0; sweep < kContactSweeps; ++sweep)
    for (int32_t i = 0; i < nc; ++i) {
      const int32_t v = cw.c_vert[i];
      const int32_t* fv = &m.face_vert[3 * cw.c_face[i]];
      const double* b = &cw.c_bary[3 * i];
      const double* n = &cw.c_normal[3 * i];
      double C = 0;
      for (int k = 0; k < 3; ++k) C += n[k] * (X[k][v] - b[0] * X[k][fv[0]] - b[1] * X[k][fv[1]] - b[2] * X[k][fv[2]]);
      if (C >= 0) continue;
      if (sweep == 0) ++violated;
      double wv = cw.weight[v], wf[3] = {1.0 * cw.weight[fv[0]], 1.0 * cw.weight[fv[1]], 1.0 * cw.weight[fv[2]]};
      double den = wv + b[0] * b[0] * wf[0] + b[1] * b[1] * wf[1] + b[2] * b[2] * wf[2];
      if (!(den > 0)) {  // held against a fixed or rigid vertex: the hold gives way
        const std::vector<uint8_t>& mv = m.contact.vert_movable;
        wv = mv[v], wf[0] = mv[fv[0]], wf[1] = mv[fv[1]], wf[2] = mv[fv[2]];
        den = wv + b[0] * b[0] * wf[0] + b[1] * b[1] * wf[1] + b[2] * b[2] * wf[2];
      }
      if (!(den > 0)) continue;
      const double lambda = -C / den;
      for (int k = 0; k < 3; ++k) {
        X[k][v] += wv * lambda * n[k];
        for (int j = 0; j < 3; ++j) X[k][fv[j]] -= wf[j] * b[j] * lambda * n[k];
      }
      cw.touched[v] |= 2, cw.touched[fv[0]] |= 1, cw.touched[fv[1]] |= 1, cw.touched[fv[2]] |= 1;
    }
  // What moved stops moving into what it touched (stop_approach); solid organs' lattices take
  // their surface's displacement.
  std::fill(cw.node_acc.begin(), cw.node_acc.end(), 0.0);
  std::fill(w.organ_flag.begin(), w.organ_flag.end(), uint8_t{0});
  for (int32_t v = 0; v < m.nvert; ++v) {
    if (!cw.touched[v]) continue;
    const bool pen = (cw.touched[v] & 2) != 0;  // a penetrating vertex (else only a face's corner)
    cw.touched[v] = 0;
    double d[3];
    for (int k = 0; k < 3; ++k) d[k] = X[k][v] - cw.saved[k * static_cast<size_t>(m.nvert) + v];
    if (d[0] == 0 && d[1] == 0 && d[2] == 0) continue;
    const int32_t o = m.vert_organ[v];
    w.organ_flag[o] = 1;
    const int32_t si = m.organ_solid[o];
    if (si < 0) {
      stop_approach(s.vx[v], s.vy[v], s.vz[v], d, m.dt_s);  // vertex and face corners alike
      continue;
    }
    const SolidBody& body = m.solids[si];
    const int32_t lv = v - m.organs[o].vert_begin;
    const int32_t t = body.embed_tet[lv];
    if (t < 0) continue;
    for (int i = 0; i < 4; ++i) {
      const double wi = body.embed_w[4 * lv + i];
      double* acc = &cw.node_acc[4 * static_cast<size_t>(body.node_begin + body.tets[4 * t + i])];
      for (int k = 0; k < 3; ++k) acc[k] += wi * d[k];
      acc[3] += wi;
      if (pen) cw.node_stop[body.node_begin + body.tets[4 * t + i]] = 1;
    }
  }
  for (size_t o = 0; o < no; ++o) {
    if (!w.organ_flag[o]) continue;
    if (!s.organ_awake[o]) s.organ_awake[o] = 1, s.organ_still_steps[o] = 0;  // pushed: awake
    const int32_t si = m.organ_solid[o];
    if (si < 0) continue;
    const SolidBody& body = m.solids[si];
    for (int32_t i = 0; i < body.nnode; ++i) {
      const size_t g = static_cast<size_t>(body.node_begin + i);
      const double* acc = &cw.node_acc[4 * g];
      if (!(acc[3] > 0)) continue;
      const double d[3] = {acc[0] / acc[3], acc[1] / acc[3], acc[2] / acc[3]};
      for (int k = 0; k < 3; ++k) s.solid_x[3 * g + k] += d[k];
      if (cw.node_stop[g]) stop_approach(s.solid_v[3 * g], s.solid_v[3 * g + 1], s.solid_v[3 * g + 2], d, m.dt_s);
      cw.node_stop[g] = 0;
    }
    solid_restore_volume(m, body, w.solid[si], s, cw.node_acc.data());
    solid_surface_update(m, body, s);
  }
  return violated;
}

}  // namespace

int contact_pass(const Model& m, State& s, Work& w) {
  if (!m.contact.on) return 0;
  ContactWork& cw = w.contact;
  const ContactModel& c = m.contact;
  const Positions P{s.x.data(), s.y.data(), s.z.data()};
  if (find_pairs(m, &s, P, c.depth_m, cw) == 0) {
    follow_contact(m, s, cw, false);
    return 0;
  }
  build_grid(m, P, cw);
  if (s.tool.mode == ToolMode::attach)
    for (int32_t v : s.tool.verts) {
      cw.held_before[3 * v] = s.x[v], cw.held_before[3 * v + 1] = s.y[v], cw.held_before[3 * v + 2] = s.z[v];
    }
  // What moved since the last detection: each vertex (into cw.moved), and each organ's most.
  // A vertex whose last distance to its partners' faces (cw.clear) still exceeds what it and
  // they moved since cannot touch them: it is not looked up (conservative advancement).
  const size_t no = m.organs.size();
  if (!std::equal(cw.pair.begin(), cw.pair.end(), cw.pair_before.begin())) {  // new partners
    std::fill(cw.clear.begin(), cw.clear.end(), 0.0);
    std::copy(cw.pair.begin(), cw.pair.end(), cw.pair_before.begin());
  }
  for (size_t o = 0; o < no; ++o) {
    cw.organ_moved[o] = 0.0;
    if (!cw.organ_paired[o]) continue;
    double most = 0.0;
    for (int32_t v = m.organs[o].vert_begin; v < m.organs[o].vert_end; ++v) {
      double* q = &cw.last_x[3 * static_cast<size_t>(v)];
      const double dx = s.x[v] - q[0], dy = s.y[v] - q[1], dz = s.z[v] - q[2];
      cw.moved[v] = std::sqrt(dx * dx + dy * dy + dz * dz);
      most = std::max(most, cw.moved[v]);
      q[0] = s.x[v], q[1] = s.y[v], q[2] = s.z[v];
    }
    cw.organ_moved[o] = most;
  }
  // Detection: each vertex of a paired organ against its partners' faces.
  int32_t nc = 0;
  for (size_t o = 0; o < no; ++o) {
    if (!cw.organ_paired[o]) continue;
    double partners_moved = 0.0;
    for (size_t b = 0; b < no; ++b)
      if (cw.pair[o * no + b]) partners_moved = std::max(partners_moved, cw.organ_moved[b]);
    for (int32_t v = m.organs[o].vert_begin; v < m.organs[o].vert_end; ++v) {
      if (c.rest_inside[v]) continue;
      cw.clear[v] -= cw.moved[v] + partners_moved;
      if (cw.clear[v] > 0 && !s.contact_let_go[v]) continue;
      cw.clear[v] = 0.0;
      double p[3];
      load(P, v, p);
      if (!in_partner_box(m, cw, static_cast<int32_t>(o), p, c.depth_m)) {
        // clear of every partner box; one let go stays so while it is beyond a partner
        if (s.contact_let_go[v]) s.contact_let_go[v] = way_home_blocked(m, P, cw, v, static_cast<int32_t>(o));
        continue;
      }
      // faces within twice the depth: a vertex between depth_m and 2 depth_m inside is let go
      const double radius = kLetGoDepth * c.depth_m;
      const Nearest n = nearest_face(m, P, cw, p, static_cast<int32_t>(o), radius);
      // a vertex behind a face is looked up again next step whatever moved (projection can leave
      // a residual: skipping it kept the pancreas 9 mm inside the kidney)
      cw.clear[v] = n.face < 0 ? radius : n.signed_dist >= 0 ? std::sqrt(n.dist2) : 0.0;
      if (n.face < 0) continue;  // far outside, or deeper: unchanged
      const bool held = held_now(s, v);
      if (n.signed_dist >= 0) {  // outside, near a face
        // A vertex let go stays let go while it is on a partner's far side (its straight way home
        // crosses the partner): projecting it there trapped a sphere on its neighbour's far side,
        // 29 mm from rest, when it was cleared on the first step outside.
        if (s.contact_let_go[v]) s.contact_let_go[v] = way_home_blocked(m, P, cw, v, static_cast<int32_t>(o));
        continue;
      }
      // Let go: pushed in deeper than contact holds in a step (the nearest face may be on the
      // partner's far side); the organ's elasticity brings it back. Never a held vertex: the hold
      // stops at the partner instead (follow_contact).
      if (s.contact_let_go[v] && !held) continue;
      if (-n.signed_dist > c.depth_m * 0.999 && !held) {
        s.contact_let_go[v] = 1;
        continue;
      }
      s.contact_let_go[v] = 0;
      cw.c_vert[nc] = v, cw.c_face[nc] = n.face;
      for (int k = 0; k < 3; ++k) cw.c_bary[3 * nc + k] = n.bary[k], cw.c_normal[3 * nc + k] = n.normal[k];
      ++nc;
    }
  }
  if (nc == 0) {
    follow_contact(m, s, cw, false);
    return 0;
  }
  // Tool-held vertices do not move for contact in the first rounds: the organ they press moves
  // instead (a held vertex gives way when what it presses cannot move, see project_round). In the
  // last round they share what is left, so that a hold against an organ that resists (anchored,
  // smoothed by its lattice) does not end the step inside it.
  const bool attached = s.tool.mode == ToolMode::attach;
  if (attached)
    for (int32_t v : s.tool.verts) cw.weight[v] = 0;
  // Rounds: Gauss-Seidel sweeps on the surface positions, then the solid organs' lattices take
  // their surface's displacement (which smooths it: the next round projects what is left).
  for (int round = 0; round < kContactRounds; ++round) {
    if (attached && round == kContactRounds - 1)
      for (int32_t v : s.tool.verts) cw.weight[v] = c.vert_movable[v];
    if (project_round(m, s, w, nc) == 0) break;
  }
  follow_contact(m, s, cw, true);
  if (attached)
    for (int32_t v : s.tool.verts) cw.weight[v] = c.vert_movable[v];
  return nc;
}

double max_penetration(const Model& m, const State& s, int32_t* vertex, int32_t* into_organ) {
  if (vertex) *vertex = -1;
  if (into_organ) *into_organ = -1;
  if (!m.contact.on) return 0.0;  // nothing to measure against (one organ, or contact off)
  ContactWork cw = make_contact_work(m);
  const Positions P{s.x.data(), s.y.data(), s.z.data()};
  if (find_pairs(m, nullptr, P, m.contact.depth_m, cw) == 0) return 0.0;
  build_grid(m, P, cw);
  double deepest = 0.0;
  for (size_t o = 0; o < m.organs.size(); ++o) {
    if (!cw.organ_paired[o]) continue;
    for (int32_t v = m.organs[o].vert_begin; v < m.organs[o].vert_end; ++v) {
      if (m.contact.rest_inside[v]) continue;
      double p[3];
      load(P, v, p);
      if (!in_partner_box(m, cw, static_cast<int32_t>(o), p, 0.0)) continue;
      const Nearest n = nearest_any(m, P, cw, p, static_cast<int32_t>(o));
      if (n.face >= 0 && -n.signed_dist > deepest && inside_by_parity(m, P, p, m.vert_organ[m.face_vert[3 * n.face]])) {
        deepest = -n.signed_dist;
        if (vertex) *vertex = v;
        if (into_organ) *into_organ = m.vert_organ[m.face_vert[3 * n.face]];
      }
    }
  }
  return deepest;
}

}  // namespace softatlas::sim
