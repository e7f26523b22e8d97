// Multirate haptics: a local model of the touched tissue, evaluated every haptic tick, coupled to
// the device through a virtual coupling (spring-damper) sized for passivity.
//
//   physics thread (~100-300 Hz)                       haptic loop (1 kHz)
//   sim::step, then LocalModel  --SeqLock-->  HapticCoupling::tick: blend the models, solve the
//   (reaction R0 at proxy p0,                 proxy (massless, between the coupling and the
//    stiffness K of the held region)          model), force on the device = R(proxy)
//   attach target = proxy       <--SeqLock--  ToolCommand with proxy_m
//
// The tissue near the tool is linear between two physics steps (Cavusoglu & Tendick 2000,
// "Multirate simulation for high fidelity haptic interaction with deformable objects"; Mark et
// al. 1996's intermediate representation):
//   R(p) = R0 - K (p - p0)                         force of the tissue on the tool (N)
// with K the linearised answer of one physics step to moving the held vertices from p0 to p
// (springs plus dampers: K_springs + B / dt, CouplingPhysics::step_response).
// The device holds the proxy through the coupling (Adams & Hannaford 1999, "Stable haptic
// interaction with virtual environments"); the proxy is massless, so at every tick
//   k_c (x_d - p) + b_c (v_d - v_p) + R(p) = 0,    v_p = (p - p_prev) / T
// and the device gets F = -(k_c (x_d - p) + b_c (v_d - v_p)) = R(p). The hand feels the coupling
// and the tissue in series: never stiffer than k_c, whatever the tissue's K, so the coupling
// alone decides stability. Sizing (Colgate & Schenkel 1997, "Passivity of a class of
// sampled-data systems", eq 9): a virtual spring K and damper B sampled at period T are passive
// on a device with physical damping b when
//   b > K T / 2 + |B|
// A device's rated maximum stiffness K_dev is the stiffness it renders stably at its servo
// period T_dev, so its physical damping is at least b = K_dev T_dev / 2; the coupling takes a
// damper b_c = damping_fraction * b and the stiffness k_c = margin * 2 (b - b_c) / T.
//
// Pressing (god-object / proxy, Zilles & Salisbury 1995): the physics publishes the plane of the
// organ surface nearest to the probe tip; the tick puts the proxy on the plane when the tip goes
// below it, and from then on the patch under the proxy is held at the proxy (full stick), so
// the proxy stays on the deformed surface, outside the organ, while the tip goes deeper (the tip
// cannot pop through: the contact lasts while the tip is below the proxy's tangent plane at the
// touch, and ends when it is back above it, where the coupling would pull the tissue).
#pragma once

#include <cstdint>
#include <vector>

#include "softatlas/app/tool_command.hpp"
#include "softatlas/sim/sim.hpp"

namespace softatlas::app {

// What the physics publishes after each step. Positions are in the tool frame: offsets (m) from
// the tool's home (the grasp point of a grasp; the probe's home point of a probe).
struct LocalModel {
  uint64_t serial = 0;                            // increases with every published model
  bool valid = false;                             // a grasp or a contact the physics has set up
  bool has_stiffness = false;                     // K from the tissue (false: a held reaction, ToolFeedback)
  Vec3d p0_m{0, 0, 0};                            // proxy position the physics used this step
  Vec3d reaction0_N{0, 0, 0};                     // R0: force of the tissue on the tool at p0
  double K_N_m[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};  // row-major, symmetric positive semi-definite
  double physics_time_s = 0.0;
  // Probe only: the surface nearest to the tip (the plane through surface_m with outward unit
  // normal), with the stiffness of the patch there (used from touch until the physics has
  // attached that patch), and which contact the model describes (0: none yet).
  bool surface = false;
  Vec3d surface_m{0, 0, 0};
  Vec3d normal{0, 0, 1};
  uint32_t contact_id = 0;
};

struct CouplingParams {
  double stiffness_N_m = 400.0;  // k_c
  double damping_N_s_m = 0.1;    // b_c
  double period_s = 1e-3;        // T, the haptic tick
};

// The coupling for a device of rated stiffness `device_max_stiffness_N_m` (at its servo period
// `device_period_s`) ticked at `rate_hz`: k_c = margin 2 (b - b_c) / T with b = K_dev T_dev / 2
// and b_c = damping_fraction b (see above). margin 0.5 keeps half of Colgate's bound in reserve.
CouplingParams size_coupling(double device_max_stiffness_N_m, double rate_hz, double device_period_s = 1e-3,
                             double margin = 0.5, double damping_fraction = 0.2);
// Colgate's criterion with the device damping implied by the rating: b > k_c T / 2 + b_c.
bool passive(const CouplingParams& c, double device_max_stiffness_N_m, double device_period_s = 1e-3);

// The haptic side: runs inside the 1 kHz tick, never allocates, never waits.
class HapticCoupling {
 public:
  HapticCoupling() = default;
  explicit HapticCoupling(const CouplingParams& params, bool probe = false);

  // A model from the physics (call when its serial changes). The tick blends from the model in
  // force at `t_s` to the new one over the observed physics period, so an update never makes the
  // force jump.
  void update(const LocalModel& model, double t_s);
  // One tick: `cmd` comes from the device (offset_m = device position in the tool frame,
  // engaged = button); fills cmd.proxy_m and cmd.contact, returns the force on the device (N,
  // before the shaper). `from_model` tells whether the force came from a tissue model.
  Vec3d tick(ToolCommand& cmd, double t_s, bool& from_model);

  const Vec3d& proxy() const { return proxy_; }
  bool in_contact() const { return contact_; }
  double blend_period_s() const { return blend_s_; }
  const CouplingParams& params() const { return params_; }

 private:
  struct Affine {  // R(p) = c - K p
    double c[3] = {0, 0, 0};
    double K[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
  };
  static Affine affine(const LocalModel& m);
  Affine blended(double t_s) const;
  Vec3d solve_proxy(const Affine& a, const Vec3d& x, const Vec3d& v) const;

  CouplingParams params_;
  bool probe_ = false;
  Affine from_, to_;
  bool have_model_ = false, stiff_ = false;
  double t_update_ = 0.0, blend_s_ = 4e-3, last_update_wall_ = -1.0;
  Vec3d proxy_{0, 0, 0}, last_device_{0, 0, 0};
  bool have_last_ = false;
  bool contact_ = false;
  uint32_t contact_id_ = 0;
  Vec3d touch_point_{0, 0, 0}, touch_normal_{0, 0, 1};  // probe: where the contact began
  LocalModel latest_;
};

// The physics side: turns the coupling's proxy into the attachment and the state after a step
// into a LocalModel. Allocates only in grasp() / when a probe contact starts.
class CouplingPhysics {
 public:
  explicit CouplingPhysics(const sim::Model& model);

  // Grasp: hold `verts` where they are (the tool frame's origin is the grasp point).
  void grasp(const sim::Model& model, sim::State& state, const std::vector<int32_t>& verts);
  // Probe: a tip whose tool frame has its origin at `home_m` (world, m); touches organs' surfaces.
  void probe(const Vec3d& home_m, double patch_radius_m = 6e-3);
  void release(sim::State& state);
  bool active() const { return mode_ != Mode::none; }

  // Before sim::step: the proxy of the last tick becomes the attachment's target; a probe contact
  // that begins attaches the patch under the contact point, one that ends releases it.
  void apply(const sim::Model& model, sim::State& state, const ToolCommand& cmd);
  // After sim::step: the model to publish (`work`: the step's, for the solid organs' factor).
  LocalModel local_model(const sim::Model& model, const sim::State& state, const sim::Work& work);

  // Stiffness K (N/m) and damping B (N s/m), row-major 3x3, of moving `verts` together while
  // the rest of the mesh stays: the Hooke linearisation of every edge and connection spring
  // with one end held, k u u^T + k max(0, 1 - l0 / l) (I - u u^T), and its damper d u u^T.
  static void held_response(const sim::Model& model, const sim::State& state, const std::vector<int32_t>& verts,
                            std::vector<uint8_t>& held_scratch, double K[9], double B[9]);
  // One physics step's answer to moving the held vertices: K + B / dt of the surface models'
  // springs plus, on solid organs, the implicit step's own stiffness (sim::solid_hold_stiffness:
  // inertia, elasticity and Rayleigh damping of the lattice), projected onto the PSD cone; B of
  // the springs on its own.
  static void step_response(const sim::Model& model, const sim::State& state, const sim::Work& work,
                            const std::vector<int32_t>& verts, std::vector<uint8_t>& held_scratch, double K_step[9],
                            double B[9]);
  const std::vector<int32_t>& held() const { return held_; }

 private:
  enum class Mode { none, grasp, probe };
  void nearest_surface(const sim::Model& model, const sim::State& state, const Vec3d& tip_world, Vec3d& point,
                       Vec3d& normal, int32_t& vertex) const;
  void patch(const sim::Model& model, const sim::State& state, int32_t vertex, std::vector<int32_t>& out) const;
  // The surface point nearest to `tool_point` (tool frame) and its patch into patch_scratch_.
  bool patch_near(const sim::Model& model, const sim::State& state, const Vec3d& tool_point, Vec3d& point,
                  Vec3d& normal);

  Mode mode_ = Mode::none;
  Vec3d home_{0, 0, 0};
  double radius_m_ = 6e-3;
  std::vector<int32_t> held_;
  std::vector<uint8_t> scratch_;
  std::vector<int32_t> vert_face_begin_, vert_faces_;  // CSR vertex -> faces (normals)
  std::vector<int32_t> patch_scratch_;
  Vec3d proxy_{0, 0, 0}, contact_point_{0, 0, 0};
  Vec3d prev_proxy_{0, 0, 0};  // proxy of the previous step (the held vertices' velocity)
  bool have_prev_ = false;
  uint32_t contact_id_ = 0;
  bool attached_ = false;
  uint64_t serial_ = 0;
  Vec3d tip_{0, 0, 0};
};

}  // namespace softatlas::app
