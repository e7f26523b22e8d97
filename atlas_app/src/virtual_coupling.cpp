#include "softatlas/app/virtual_coupling.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>

namespace softatlas::app {
namespace {

double dot3(const Vec3d& a, const Vec3d& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

// Symmetric part of a 3x3 matrix with negative eigenvalues set to zero: the proxy's system
// (k_c + b_c / T) I + K must stay positive definite, and a tissue that feels like a negative
// spring would feed energy into the hand.
void project_psd(double K[9]) {
  Eigen::Matrix3d A;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) A(r, c) = 0.5 * (K[3 * r + c] + K[3 * c + r]);
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(A);
  const Eigen::Vector3d l = es.eigenvalues().cwiseMax(0.0);
  const Eigen::Matrix3d P = es.eigenvectors() * l.asDiagonal() * es.eigenvectors().transpose();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) K[3 * r + c] = std::isfinite(P(r, c)) ? P(r, c) : 0.0;
}

}  // namespace

// ---- sizing ------------------------------------------------------------------------------------

CouplingParams size_coupling(double device_max_stiffness_N_m, double rate_hz, double device_period_s, double margin,
                             double damping_fraction) {
  CouplingParams c;
  c.period_s = 1.0 / rate_hz;
  // Colgate & Schenkel 1997 eq 9, b > K T / 2 + |B|: the device's physical damping implied by
  // its rating, a damper that takes a fraction of it, and the stiffness left with a margin.
  const double b = device_max_stiffness_N_m * device_period_s / 2.0;
  c.damping_N_s_m = damping_fraction * b;
  c.stiffness_N_m = margin * 2.0 * (b - c.damping_N_s_m) / c.period_s;
  return c;
}

bool passive(const CouplingParams& c, double device_max_stiffness_N_m, double device_period_s) {
  const double b = device_max_stiffness_N_m * device_period_s / 2.0;
  return b > c.stiffness_N_m * c.period_s / 2.0 + std::abs(c.damping_N_s_m);
}

// ---- haptic side -------------------------------------------------------------------------------

HapticCoupling::HapticCoupling(const CouplingParams& params, bool probe) : params_(params), probe_(probe) {}

HapticCoupling::Affine HapticCoupling::affine(const LocalModel& m) {
  // R(p) = R0 - K (p - p0) = (R0 + K p0) - K p
  Affine a;
  for (int r = 0; r < 3; ++r) {
    a.c[r] = m.reaction0_N[r];
    for (int k = 0; k < 3; ++k) {
      a.K[3 * r + k] = m.K_N_m[3 * r + k];
      a.c[r] += m.K_N_m[3 * r + k] * m.p0_m[k];
    }
  }
  return a;
}

HapticCoupling::Affine HapticCoupling::blended(double t_s) const {
  const double w = std::clamp((t_s - t_update_) / blend_s_, 0.0, 1.0);
  Affine a;
  for (int i = 0; i < 3; ++i) a.c[i] = from_.c[i] + w * (to_.c[i] - from_.c[i]);
  for (int i = 0; i < 9; ++i) a.K[i] = from_.K[i] + w * (to_.K[i] - from_.K[i]);
  return a;
}

void HapticCoupling::update(const LocalModel& m, double t_s) {
  latest_ = m;
  // The blend lasts one physics period (measured between updates), so the model in force moves
  // from the old linearisation to the new one while the next one is being computed.
  if (last_update_wall_ >= 0) {
    const double dt = t_s - last_update_wall_;
    if (dt > 0) blend_s_ = std::clamp(0.8 * blend_s_ + 0.2 * dt, 1e-3, 0.05);
  }
  last_update_wall_ = t_s;
  const bool usable = m.valid && (!probe_ || (contact_ && m.contact_id == contact_id_));
  if (!usable) {
    if (!probe_) have_model_ = false;  // a probe in contact keeps its touch model
    return;
  }
  const Affine next = affine(m);
  if (have_model_) {
    from_ = blended(t_s);
  } else {
    from_ = next;
  }
  to_ = next;
  t_update_ = t_s;
  have_model_ = true;
  stiff_ = m.has_stiffness;
}

Vec3d HapticCoupling::solve_proxy(const Affine& a, const Vec3d& x, const Vec3d& v) const {
  // (k_c + b_c / T) I + K) p = k_c x + b_c (v + p_prev / T) + c   (massless proxy, see header)
  const double kc = params_.stiffness_N_m, bc = params_.damping_N_s_m, T = params_.period_s;
  Eigen::Matrix3d A;
  Eigen::Vector3d rhs;
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) A(r, k) = a.K[3 * r + k] + (r == k ? kc + bc / T : 0.0);
    rhs[r] = kc * x[r] + bc * (v[r] + proxy_[r] / T) + a.c[r];
  }
  const Eigen::Vector3d p = A.ldlt().solve(rhs);
  return {p[0], p[1], p[2]};
}

Vec3d HapticCoupling::tick(ToolCommand& cmd, double t_s, bool& from_model) {
  from_model = false;
  const Vec3d x = cmd.offset_m;
  const double T = params_.period_s;
  Vec3d v{0, 0, 0};
  if (have_last_)
    for (int k = 0; k < 3; ++k) v[k] = (x[k] - last_device_[k]) / T;
  last_device_ = x;
  have_last_ = true;
  auto free_proxy = [&]() {
    proxy_ = x;
    cmd.proxy_m = x;
    cmd.contact = false;
    cmd.contact_id = contact_id_;
    return Vec3d{0, 0, 0};
  };
  if (!cmd.engaged || cmd.force_mode) {
    contact_ = false;
    if (!probe_) have_model_ = false;
    return free_proxy();
  }
  if (probe_ && !contact_) {
    // Touch: the tip went below the plane of the nearest surface. The proxy starts on the plane
    // (the god-object's constrained point closest to the tip), with the patch's stiffness.
    if (!latest_.surface) return free_proxy();
    Vec3d d{x[0] - latest_.surface_m[0], x[1] - latest_.surface_m[1], x[2] - latest_.surface_m[2]};
    const double depth = -dot3(d, latest_.normal);
    if (depth <= 0) return free_proxy();
    contact_ = true;
    ++contact_id_;
    // proxy_ keeps last tick's (free) position, the tip's: the damper sees the proxy arrive at
    // the device's speed instead of a jump onto the plane.
    Vec3d on_plane;
    for (int k = 0; k < 3; ++k) on_plane[k] = x[k] + depth * latest_.normal[k];
    LocalModel touch;
    touch.valid = true;
    touch.has_stiffness = true;
    touch.p0_m = on_plane;
    std::copy(latest_.K_N_m, latest_.K_N_m + 9, touch.K_N_m);
    touch_normal_ = latest_.normal;
    touch_point_ = on_plane;
    from_ = to_ = affine(touch);
    t_update_ = t_s;
    have_model_ = true;
    stiff_ = true;
  }
  if (!have_model_) return free_proxy();
  const Affine a = blended(t_s);
  const Vec3d prev = proxy_;
  const Vec3d p = solve_proxy(a, x, v);
  Vec3d f;
  for (int k = 0; k < 3; ++k)
    f[k] = -(params_.stiffness_N_m * (x[k] - p[k]) + params_.damping_N_s_m * (v[k] - (p[k] - prev[k]) / T));
  const Vec3d gap{x[0] - p[0], x[1] - p[1], x[2] - p[2]};
  if (probe_ && dot3(gap, touch_normal_) >= 0.0) {
    // God-object rule: the contact lasts while the tip is below the proxy's surface, however
    // deep; it ends when the tip is back above it (the coupling spring would pull the tissue).
    contact_ = false;
    return free_proxy();
  }
  proxy_ = p;
  cmd.proxy_m = p;
  cmd.contact = true;
  cmd.contact_id = contact_id_;
  cmd.contact_m = touch_point_;
  from_model = stiff_;
  return f;
}

// ---- physics side ------------------------------------------------------------------------------

CouplingPhysics::CouplingPhysics(const sim::Model& m) {
  scratch_.assign(static_cast<size_t>(m.nvert), 0);
  vert_face_begin_.assign(static_cast<size_t>(m.nvert) + 1, 0);
  for (int32_t i = 0; i < 3 * m.nface; ++i) ++vert_face_begin_[static_cast<size_t>(m.face_vert[i]) + 1];
  for (int32_t v = 0; v < m.nvert; ++v) vert_face_begin_[v + 1] += vert_face_begin_[v];
  vert_faces_.assign(static_cast<size_t>(3 * m.nface), 0);
  std::vector<int32_t> fill(vert_face_begin_.begin(), vert_face_begin_.end() - 1);
  for (int32_t f = 0; f < m.nface; ++f)
    for (int c = 0; c < 3; ++c) vert_faces_[static_cast<size_t>(fill[m.face_vert[3 * f + c]]++)] = f;
}

void CouplingPhysics::grasp(const sim::Model& m, sim::State& s, const std::vector<int32_t>& verts) {
  mode_ = Mode::grasp;
  home_ = {0, 0, 0};
  proxy_ = {0, 0, 0};
  contact_point_ = {0, 0, 0};
  sim::attach(m, s, verts, {0, 0, 0}, 1);
  held_ = s.tool.verts;
  attached_ = !held_.empty();
}

void CouplingPhysics::probe(const Vec3d& home_m, double patch_radius_m) {
  mode_ = Mode::probe;
  home_ = home_m;
  radius_m_ = patch_radius_m;
  attached_ = false;
  held_.clear();
}

void CouplingPhysics::release(sim::State& s) {
  sim::release(s);
  mode_ = Mode::none;
  attached_ = false;
  held_.clear();
}

void CouplingPhysics::apply(const sim::Model& m, sim::State& s, const ToolCommand& cmd) {
  tip_ = cmd.offset_m;
  if (mode_ == Mode::grasp) {
    if (attached_) {
      proxy_ = cmd.engaged ? cmd.proxy_m : cmd.offset_m;
      sim::move_attachment(s, proxy_);
    }
    return;
  }
  if (mode_ != Mode::probe) return;
  if (cmd.contact && cmd.contact_id != contact_id_) {
    // A new touch: hold the patch under the contact point where it is now.
    contact_id_ = cmd.contact_id;
    contact_point_ = cmd.contact_m;
    Vec3d point, normal;
    if (patch_near(m, s, contact_point_, point, normal)) {
      sim::attach(m, s, patch_scratch_, {0, 0, 0}, 1);
      held_ = s.tool.verts;
      attached_ = !held_.empty();
    }
  } else if (!cmd.contact && attached_) {
    sim::release(s);
    attached_ = false;
    held_.clear();
  }
  if (attached_) {
    proxy_ = cmd.proxy_m;
    sim::move_attachment(s,
                         {proxy_[0] - contact_point_[0], proxy_[1] - contact_point_[1], proxy_[2] - contact_point_[2]});
  }
}

LocalModel CouplingPhysics::local_model(const sim::Model& m, const sim::State& s, const sim::Work& w) {
  LocalModel out;
  out.serial = ++serial_;
  out.physics_time_s = s.time_s;
  out.contact_id = contact_id_;
  if (attached_) {
    // R(p) = R0 + B v0 - (K + B / dt) (p - p0): this step's damping force -B v0 (held vertices
    // moved at v0 = (p0 - p0_prev) / dt) is replaced by the next step's, -B (p - p0) / dt. A
    // solid's step stiffness K_s (inertia M / h^2, elasticity, Rayleigh) gets no such term: its
    // inertial share would predict K_s v0 dt, and when the physics runs slower than real time
    // the proxy moves over more wall time than dt, the prediction overshoots, and the loop rings
    // at the physics rate (bench haptic on a solid atlas at 0.25x: 8 N swings without it 0.01 N).
    double B[9];
    step_response(m, s, w, held_, scratch_, out.K_N_m, B);
    const Vec3d R0 = sim::tool_reaction(s);
    Vec3d v0;
    for (int k = 0; k < 3; ++k) v0[k] = have_prev_ ? (proxy_[k] - prev_proxy_[k]) / m.dt_s : 0.0;
    out.valid = true;
    out.has_stiffness = true;
    out.p0_m = proxy_;
    for (int r = 0; r < 3; ++r) {
      out.reaction0_N[r] = R0[r];
      for (int k = 0; k < 3; ++k) out.reaction0_N[r] += B[3 * r + k] * v0[k];
    }
    prev_proxy_ = proxy_;
    have_prev_ = true;
  } else {
    have_prev_ = false;
  }
  if (mode_ == Mode::probe && !attached_) {
    // Free probe: the plane of the surface nearest to the tip, and the patch's stiffness there.
    Vec3d point, normal;
    if (patch_near(m, s, tip_, point, normal)) {
      double B[9];
      step_response(m, s, w, patch_scratch_, scratch_, out.K_N_m, B);
      out.surface = true;
      out.surface_m = {point[0] - home_[0], point[1] - home_[1], point[2] - home_[2]};
      out.normal = normal;
    }
  }
  return out;
}

void CouplingPhysics::held_response(const sim::Model& m, const sim::State& s, const std::vector<int32_t>& verts,
                                    std::vector<uint8_t>& held, double K[9], double B[9]) {
  std::fill(K, K + 9, 0.0);
  std::fill(B, B + 9, 0.0);
  if (held.size() != static_cast<size_t>(m.nvert)) held.assign(static_cast<size_t>(m.nvert), 0);
  for (int32_t v : verts) held[static_cast<size_t>(v)] = 1;
  auto add = [&](int32_t a, int32_t b, double k, double d, double l0) {
    if (held[static_cast<size_t>(a)] == held[static_cast<size_t>(b)]) return;  // both held or both free
    const double e[3] = {s.x[b] - s.x[a], s.y[b] - s.y[a], s.z[b] - s.z[a]};
    const double l = std::sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
    if (!(l > 0)) return;
    const double u[3] = {e[0] / l, e[1] / l, e[2] / l};
    const double kt = k * std::max(0.0, 1.0 - l0 / l);  // tension's transverse stiffness
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        K[3 * r + c] += (k - kt) * u[r] * u[c] + (r == c ? kt : 0.0);
        B[3 * r + c] += d * u[r] * u[c];  // eq 10 damping acts along the spring
      }
  };
  for (int32_t i = 0; i < m.nspring; ++i)
    add(m.spring_a[i], m.spring_b[i], m.spring_k[i], m.spring_d[i], m.spring_length0[i]);
  for (int32_t i = 0; i < m.nconn; ++i) add(m.conn_a[i], m.conn_b[i], m.conn_k[i], m.conn_d[i], m.conn_rest[i]);
  for (int32_t v : verts) held[static_cast<size_t>(v)] = 0;
}

void CouplingPhysics::step_response(const sim::Model& m, const sim::State& s, const sim::Work& w,
                                    const std::vector<int32_t>& verts, std::vector<uint8_t>& held, double K_step[9],
                                    double B[9]) {
  // The next step moves the held vertices from p0 to p in dt: besides the springs (K) their
  // dampers answer with B (p - p0) / dt, so one step's reaction is linear in p with K + B / dt.
  double K[9];
  held_response(m, s, verts, held, K, B);
  const double Ks = m.solids.empty() ? 0.0 : sim::solid_hold_stiffness(m, w, verts);  // isotropic
  for (int i = 0; i < 9; ++i) K_step[i] = K[i] + B[i] / m.dt_s + (i % 4 == 0 ? Ks : 0.0);
  project_psd(K_step);
}

void CouplingPhysics::nearest_surface(const sim::Model& m, const sim::State& s, const Vec3d& tip, Vec3d& point,
                                      Vec3d& normal, int32_t& vertex) const {
  vertex = -1;
  double best = std::numeric_limits<double>::infinity();
  for (size_t o = 0; o < m.organs.size(); ++o) {
    const sim::OrganRange& r = m.organs[o];
    for (int32_t v = r.vert_begin; v < r.vert_end; ++v) {
      if (vert_face_begin_[v + 1] == vert_face_begin_[v] || m.vert_inv_mass[v] <= 0) continue;
      const double dx = s.x[v] - tip[0], dy = s.y[v] - tip[1], dz = s.z[v] - tip[2];
      const double d2 = dx * dx + dy * dy + dz * dz;
      if (d2 < best) best = d2, vertex = v;
    }
  }
  if (vertex < 0) return;
  // Area-weighted normal of the faces around the vertex (faces wind outward: compile() keeps
  // the organ set's orientation, organ_volume > 0).
  double n[3] = {0, 0, 0};
  for (int32_t k = vert_face_begin_[vertex]; k < vert_face_begin_[vertex + 1]; ++k) {
    const int32_t f = vert_faces_[static_cast<size_t>(k)];
    const int32_t a = m.face_vert[3 * f], b = m.face_vert[3 * f + 1], c = m.face_vert[3 * f + 2];
    const double e1[3] = {s.x[b] - s.x[a], s.y[b] - s.y[a], s.z[b] - s.z[a]};
    const double e2[3] = {s.x[c] - s.x[a], s.y[c] - s.y[a], s.z[c] - s.z[a]};
    n[0] += e1[1] * e2[2] - e1[2] * e2[1];
    n[1] += e1[2] * e2[0] - e1[0] * e2[2];
    n[2] += e1[0] * e2[1] - e1[1] * e2[0];
  }
  const double sign = sim::organ_volume(m, s, m.vert_organ[vertex]) < 0 ? -1.0 : 1.0;
  const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  normal = len > 0 ? Vec3d{sign * n[0] / len, sign * n[1] / len, sign * n[2] / len} : Vec3d{0, 0, 1};
  point = {s.x[vertex], s.y[vertex], s.z[vertex]};
}

bool CouplingPhysics::patch_near(const sim::Model& m, const sim::State& s, const Vec3d& tool_point, Vec3d& point,
                                 Vec3d& normal) {
  const Vec3d world{home_[0] + tool_point[0], home_[1] + tool_point[1], home_[2] + tool_point[2]};
  int32_t vertex = -1;
  nearest_surface(m, s, world, point, normal, vertex);
  if (vertex >= 0) patch(m, s, vertex, patch_scratch_);
  return vertex >= 0;
}

void CouplingPhysics::patch(const sim::Model& m, const sim::State& s, int32_t vertex, std::vector<int32_t>& out) const {
  // The vertex's ring (a coarse mesh has edges longer than the radius) and every vertex of the
  // same organ within radius_m_ of it (deformed positions), found by walking faces outward from
  // it, so the patch is one connected piece of that surface.
  out.clear();
  out.push_back(vertex);
  const double r2 = radius_m_ * radius_m_;
  for (size_t q = 0; q < out.size(); ++q) {
    const int32_t v = out[q];
    for (int32_t k = vert_face_begin_[v]; k < vert_face_begin_[v + 1]; ++k) {
      const int32_t f = vert_faces_[static_cast<size_t>(k)];
      for (int c = 0; c < 3; ++c) {
        const int32_t w = m.face_vert[3 * f + c];
        if (std::find(out.begin(), out.end(), w) != out.end()) continue;
        const double dx = s.x[w] - s.x[vertex], dy = s.y[w] - s.y[vertex], dz = s.z[w] - s.z[vertex];
        if (q == 0 || dx * dx + dy * dy + dz * dz <= r2) out.push_back(w);
      }
    }
  }
}

}  // namespace softatlas::app
