#include "softatlas/evidence/runner.hpp"

#include <algorithm>
#include <cmath>
#include <random>

#include "softatlas/sim/error.hpp"
#include "softatlas/sim/sim.hpp"
#include "softatlas/sim/tmm.hpp"

namespace softatlas::evidence {

double paper_b(int faces) {
  // Paper 000: b = 0.5 at 1000 faces (Table II); Table III: 0.3 / 0.2 / 0.15 / 0.15 / 0.15 at
  // 2000 / 4000 / 6000 / 8000 / 10000 faces.
  if (faces <= 1000) return 0.5;
  if (faces <= 2000) return 0.3;
  if (faces <= 4000) return 0.2;
  return 0.15;
}

ModelSpec paper_spec(const std::string& model, const std::string& integrator, int faces) {
  ModelSpec s;
  s.model = model;
  s.integrator = integrator;
  if (model == "cmsm") {
    s.tau_s = 0.01;
    s.tau_c = 0.01;
  } else if (model == "nmsm" || model == "nmsm_p2") {
    s.elastica_a = 1.0;
    s.elastica_b = paper_b(faces);
    s.elastica_p = model == "nmsm_p2" ? 2 : 1;
  } else if (model == "flexion") {
    // Paper 003 gives k_f = 0.32 in unstated units on its own mesh; we scale to the edge
    // springs: a dihedral torque k_f theta of the order of k l^2 theta (docs/benchmark-method.md).
    s.flexion_stiffness = 1e-4;
    s.volume_stiffness = 0.5;
  }
  if (model == "tmm" || model == "fem" || model == "solid") s.integrator = "implicit";
  // The solid (volumetric) model and the FEM are materials, not membranes: nearly incompressible
  // as the reference (organs: nu = 0.49, sim/model.hpp).
  if (model == "solid" || model == "fem") s.poisson_ratio = 0.49;
  return s;
}

namespace {

// x (#N*3) += amplitude in a random direction per point, for the points with free[i] != 0; the
// same draw as sim::perturb for the core's models.
void perturb_points(std::vector<double>& x, const std::vector<uint8_t>& free, double amplitude, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  for (size_t i = 0; i < free.size(); ++i) {
    if (!free[i]) continue;
    double d[3] = {gauss(rng), gauss(rng), gauss(rng)};
    const double n = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    for (int c = 0; c < 3; ++c) x[3 * i + c] += n > 0 ? amplitude * d[c] / n : 0.0;
  }
}

// ---- mass-spring (the core) --------------------------------------------------------------------
class MassSpring final : public Simulation {
 public:
  MassSpring(const TriMesh& surface, const std::vector<int32_t>& fixed, const ModelSpec& spec) {
    sim::SceneDesc scene;
    sim::OrganDesc organ;
    organ.name = "organ";
    organ.vertices = surface.V;
    organ.faces = surface.F;
    organ.fixed = fixed;
    sim::Material& m = organ.material;
    const std::string& name = spec.model;
    if (name == "tmsm")
      m.model = sim::ModelKind::tmsm;
    else if (name == "cmsm")
      m.model = sim::ModelKind::cmsm;
    else if (name == "nmsm" || name == "nmsm_p2")
      m.model = sim::ModelKind::nmsm;
    else if (name == "flexion")
      m.model = sim::ModelKind::flexion;
    else if (name == "solid")
      m.model = sim::ModelKind::solid;
    else
      throw InputError("model", "unknown mass-spring model '" + name + "'");
    m.young_modulus_pa = spec.young_modulus_pa;
    m.thickness_m = spec.thickness_m;
    m.total_mass_kg = spec.total_mass_kg;
    m.density_kg_m3 = spec.density_kg_m3;
    m.stiffness = spec.stiffness;
    m.damping = spec.damping;
    m.damping_scale = spec.damping_scale;
    m.vertex_mass_kg = spec.vertex_mass_kg;
    m.elastica_a = spec.elastica_a;
    m.elastica_b = m.model == sim::ModelKind::nmsm ? spec.elastica_b : 0.0;
    m.elastica_p = spec.elastica_p;
    m.curvature_unit_m = spec.curvature_unit_m;
    m.tau_s = spec.tau_s;
    m.tau_c = spec.tau_c;
    m.compensation_iterations = spec.compensation_iterations;
    m.flexion_stiffness = spec.flexion_stiffness;
    m.volume_stiffness = spec.volume_stiffness;
    if (m.model == sim::ModelKind::solid) m.poisson_ratio = spec.poisson_ratio;
    scene.organs.push_back(organ);
    if (!sim::parse_integrator(spec.integrator, scene.integrator))
      throw InputError("integrator", "expected verlet, semi_implicit or implicit, got '" + spec.integrator + "'");
    scene.dt_s = spec.dt_s;
    scene.guard = spec.guard;
    scene.cg_iterations = spec.cg_iterations;
    scene.max_tool_force_N = spec.max_tool_force_N;
    scene.max_substeps = spec.max_substeps;
    scene.allow_sleep = false;  // measure every step
    model_ = sim::compile(scene);
    state_ = sim::make_state(model_);
    work_ = sim::make_work(model_);
    global_.assign(surface.nvert(), -1);
    for (int32_t g = 0; g < model_.nvert; ++g) global_[model_.vert_source[g]] = g;
  }
  void pull(const std::vector<int32_t>& verts, const std::array<double, 3>& f) override {
    sim::pull_force(model_, state_, map(verts), f);
  }
  void attach(const std::vector<int32_t>& verts, const std::array<double, 3>& o, int it) override {
    sim::attach(model_, state_, map(verts), o, it);
  }
  void release() override {
    sim::release(state_);
    sim::wake(model_, state_, 0);
  }
  void perturb(double amplitude_m, uint32_t seed) override { sim::perturb(model_, state_, amplitude_m, seed); }
  StepOut step() override {
    const sim::StepReport r = sim::step(model_, state_, work_);
    StepOut o;
    o.guard_acted = r.status != sim::StepStatus::ok || r.tool_clamped;
    o.accel_sum = r.accel_sum;
    o.finite = std::isfinite(r.accel_sum);
    for (int32_t i = 0; i < model_.nvert && o.finite; i += 1)
      o.finite = std::isfinite(state_.x[i]) && std::isfinite(state_.y[i]) && std::isfinite(state_.z[i]);
    return o;
  }
  void positions(std::vector<double>& out) const override { sim::organ_positions(model_, state_, 0, out); }
  double volume() const override { return sim::total_volume(model_, state_); }
  std::array<double, 3> reaction() override { return sim::tool_reaction(state_); }
  double energy() const override { return sim::total_energy(model_, state_); }
  double stable_dt() const override { return model_.stable_dt_s; }
  std::string plan() const override { return sim::explain(model_); }

 private:
  std::vector<int32_t> map(const std::vector<int32_t>& verts) const {
    std::vector<int32_t> g;
    for (int32_t v : verts)
      if (v >= 0 && v < static_cast<int32_t>(global_.size()) && global_[v] >= 0) g.push_back(global_[v]);
    return g;
  }
  sim::Model model_;
  sim::State state_;
  sim::Work work_;
  std::vector<int32_t> global_;
};

// ---- tensor-mass (paper 002) -------------------------------------------------------------------
class TensorMass final : public Simulation {
 public:
  TensorMass(const TriMesh& surface, const std::vector<int32_t>& fixed, const ModelSpec& spec) : spec_(spec) {
    sim::tmm::Params p;
    p.young_modulus_pa = spec.young_modulus_pa;
    p.poisson_ratio = spec.poisson_ratio;
    p.thickness_m = spec.thickness_m;
    p.total_mass_kg = spec.total_mass_kg;
    p.density_kg_m3 = spec.density_kg_m3;
    p.rayleigh_mass = spec.rayleigh_mass;
    p.rayleigh_stiffness = spec.rayleigh_stiffness;
    p.cg_iterations = spec.cg_iterations;
    if (!(spec.dt_s > 0)) throw InputError("dt_s", "expected a positive time step");
    model_ = sim::tmm::compile(surface.V, surface.F, fixed, p);
    free_.assign(surface.nvert(), 1);
    for (int32_t v : fixed)
      if (v >= 0 && v < surface.nvert()) free_[v] = 0;
    state_ = sim::tmm::make_state(model_);
    work_ = sim::tmm::make_work(model_);
    good_ = state_;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int32_t i = 0; i < surface.nvert(); ++i)
      for (int c = 0; c < 3; ++c)
        lo[c] = std::min(lo[c], surface.V[3 * i + c]), hi[c] = std::max(hi[c], surface.V[3 * i + c]);
    size_ = std::sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                      (hi[2] - lo[2]) * (hi[2] - lo[2]));
  }
  void pull(const std::vector<int32_t>& verts, const std::array<double, 3>& f) override {
    std::array<double, 3> force = f;
    clamped_ = false;
    if (spec_.guard) {  // same rule as the core's guard: clamp tool forces
      const double n = std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
      if (n > spec_.max_tool_force_N) {
        for (double& c : force) c *= spec_.max_tool_force_N / n;
        clamped_ = true;
      }
    }
    sim::tmm::pull_force(state_, verts, force);
  }
  void attach(const std::vector<int32_t>& verts, const std::array<double, 3>& o, int it) override {
    sim::tmm::attach(state_, verts, o, it);
  }
  void release() override { sim::tmm::release(state_); }
  void perturb(double amplitude_m, uint32_t seed) override {
    perturb_points(state_.x, free_, amplitude_m, seed);
    good_.x = state_.x;
  }
  StepOut step() override {
    const sim::tmm::StepInfo info = sim::tmm::step(model_, state_, work_, spec_.dt_s);
    StepOut o;
    o.finite = info.finite;
    o.accel_sum = info.accel_sum;
    o.guard_acted = clamped_;
    if (spec_.guard) {
      // The guard's last rule for the tensor-mass model: restore the last good state on
      // non-finite values (implicit Euler of a linear model is otherwise unconditionally stable).
      // Same runaway rule as the core's guard: a vertex moving more than a quarter of the
      // organ's size in one step.
      double vmax2 = 0.0;
      for (double v : state_.v) vmax2 = std::max(vmax2, v * v);
      const bool runaway = std::sqrt(vmax2) * spec_.dt_s > 0.25 * size_;
      if (!info.finite || runaway) {
        const sim::tmm::Tool tool = state_.tool;
        state_ = good_;
        state_.tool = tool;
        for (double& v : state_.v) v = 0.0;
        o.finite = true;
        o.guard_acted = true;
      } else if (++since_good_ >= 10) {
        good_.x = state_.x;
        good_.v = state_.v;
        good_.time_s = state_.time_s;
        since_good_ = 0;
      }
    }
    return o;
  }
  void positions(std::vector<double>& out) const override { out = state_.x; }
  double volume() const override { return sim::tmm::volume(model_, state_.x); }
  std::array<double, 3> reaction() override { return sim::tmm::tool_reaction(model_, state_, work_); }
  double energy() const override {
    sim::tmm::Work w = work_;
    return sim::tmm::energy(model_, state_, w);
  }

 private:
  ModelSpec spec_;
  sim::tmm::Model model_;
  sim::tmm::State state_, good_;
  sim::tmm::Work work_;
  std::vector<uint8_t> free_;
  int since_good_ = 0;
  bool clamped_ = false;
  double size_ = 1.0;
};

// ---- FEM dynamics --------------------------------------------------------------------------------
class FemDynamics final : public Simulation {
 public:
  FemDynamics(const sim::fem::TetMesh& mesh, const std::vector<int32_t>& fixed, const ModelSpec& spec,
              TriMesh& boundary, std::vector<int32_t>& boundary_nodes)
      : spec_(spec) {
    sim::fem::Material mat;
    mat.young_modulus_pa = spec.young_modulus_pa;
    mat.poisson_ratio = spec.poisson_ratio;
    mat.density_kg_m3 = spec.density_kg_m3;
    mat.rayleigh_mass = spec.rayleigh_mass;
    mat.rayleigh_stiffness = spec.rayleigh_stiffness;
    mat.elasticity = sim::fem::Elasticity::corotational;
    model_ = sim::fem::compile(mesh, mat);
    const std::vector<int32_t> faces = sim::fem::boundary_faces(mesh);
    std::vector<int32_t> local(mesh.nnode(), -1);
    boundary = TriMesh{};
    boundary_nodes.clear();
    for (int32_t n : faces)
      if (local[n] < 0) {
        local[n] = static_cast<int32_t>(boundary_nodes.size());
        boundary_nodes.push_back(n);
        boundary.V.insert(boundary.V.end(), {mesh.nodes[3 * n], mesh.nodes[3 * n + 1], mesh.nodes[3 * n + 2]});
      }
    for (int32_t n : faces) boundary.F.push_back(local[n]);
    nodes_ = boundary_nodes;
    faces_ = boundary.F;
    load_ = sim::fem::make_load(model_);
    sim::fem::fix_nodes(load_, fixed, {0, 0, 0});
    base_ = load_;
    state_ = sim::fem::make_state(model_);
  }
  void pull(const std::vector<int32_t>& verts, const std::array<double, 3>& f) override {
    load_ = base_;
    tool_ = to_nodes(verts);
    sim::fem::add_force(load_, tool_, f);
    attach_steps_ = 0;
  }
  void attach(const std::vector<int32_t>& verts, const std::array<double, 3>& o, int it) override {
    load_ = base_;
    tool_ = to_nodes(verts);
    offset_ = o;
    attach_steps_ = std::max(1, it);
    progress_ = 0;
    anchor_.clear();
    for (int32_t n : tool_)
      for (int c = 0; c < 3; ++c) anchor_.push_back(state_.x[3 * n + c] - model_.rest[3 * n + c]);
  }
  void release() override {
    load_ = base_;
    tool_.clear();
    attach_steps_ = 0;
  }
  void perturb(double amplitude_m, uint32_t seed) override {
    std::vector<uint8_t> free(model_.nnode);
    for (int32_t n = 0; n < model_.nnode; ++n) free[n] = !base_.dof_fixed[3 * n];
    perturb_points(state_.x, free, amplitude_m, seed);
  }
  StepOut step() override {
    if (attach_steps_ > 0) {
      progress_ = std::min(progress_ + 1, attach_steps_);
      const double lam = static_cast<double>(progress_) / attach_steps_;
      for (size_t k = 0; k < tool_.size(); ++k)
        for (int c = 0; c < 3; ++c) {
          load_.dof_fixed[3 * tool_[k] + c] = 1;
          load_.dof_disp[3 * tool_[k] + c] = anchor_[3 * k + c] + lam * offset_[c];
        }
    }
    const std::vector<double> x0 = state_.x;
    sim::fem::step_implicit(model_, load_, state_, spec_.dt_s);
    StepOut o;
    for (size_t k = 0; k < state_.x.size(); ++k) {
      o.finite = o.finite && std::isfinite(state_.x[k]);
      if (k % 3 == 0 && k + 2 < state_.x.size()) {
        double a2 = 0;
        for (int c = 0; c < 3; ++c) {
          const double a = (state_.x[k + c] - x0[k + c]) / (spec_.dt_s * spec_.dt_s);
          a2 += a * a;
        }
        o.accel_sum += std::sqrt(a2);
      }
    }
    return o;
  }
  void positions(std::vector<double>& out) const override {
    out.resize(3 * nodes_.size());
    for (size_t i = 0; i < nodes_.size(); ++i)
      for (int c = 0; c < 3; ++c) out[3 * i + c] = state_.x[3 * nodes_[i] + c];
  }
  double volume() const override {
    double v = 0.0;
    for (int32_t t = 0; t < model_.ntet; ++t) {
      const int32_t* n = &model_.tets[4 * t];
      double d[3][3];
      for (int a = 0; a < 3; ++a)
        for (int c = 0; c < 3; ++c) d[a][c] = state_.x[3 * n[a + 1] + c] - state_.x[3 * n[0] + c];
      v += (d[0][0] * (d[1][1] * d[2][2] - d[1][2] * d[2][1]) - d[0][1] * (d[1][0] * d[2][2] - d[1][2] * d[2][0]) +
            d[0][2] * (d[1][0] * d[2][1] - d[1][1] * d[2][0])) /
           6.0;
    }
    return v;
  }
  std::array<double, 3> reaction() override { return sim::fem::reaction_force(model_, state_.x, tool_); }
  double energy() const override { return sim::fem::energy(model_, state_.x, state_.v); }

 private:
  std::vector<int32_t> to_nodes(const std::vector<int32_t>& verts) const {
    std::vector<int32_t> out;
    for (int32_t v : verts) out.push_back(nodes_.at(v));
    return out;
  }
  ModelSpec spec_;
  sim::fem::Model model_;
  sim::fem::Load load_, base_;
  sim::fem::State state_;
  std::vector<int32_t> nodes_, faces_, tool_;
  std::array<double, 3> offset_{0, 0, 0};
  std::vector<double> anchor_;
  int attach_steps_ = 0, progress_ = 0;
};

}  // namespace

std::unique_ptr<Simulation> make_surface_simulation(const TriMesh& surface, const std::vector<int32_t>& fixed,
                                                    const ModelSpec& spec) {
  if (spec.model == "tmm") return std::make_unique<TensorMass>(surface, fixed, spec);
  return std::make_unique<MassSpring>(surface, fixed, spec);
}

std::unique_ptr<Simulation> make_fem_simulation(const sim::fem::TetMesh& mesh, const std::vector<int32_t>& fixed,
                                                const ModelSpec& spec, TriMesh& boundary,
                                                std::vector<int32_t>& boundary_nodes) {
  return std::make_unique<FemDynamics>(mesh, fixed, spec, boundary, boundary_nodes);
}

}  // namespace softatlas::evidence
