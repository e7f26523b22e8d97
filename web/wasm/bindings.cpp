// The physics core's C interface for WebAssembly (web/): the page builds a sim::SceneDesc from the
// exported scene.json through these calls, then compiles and steps it with the very same
// sim::compile() and sim::step() as the native programs. One scene at a time (a page shows one
// atlas). Arrays cross the boundary as pointers into the wasm heap (HEAPF64 / HEAP32 in JS).
//
//   sa_reset(); sa_settings(...); sa_add_organ(...) per organ; sa_add_connection(...) per link;
//   sa_compile() == 0 or sa_error(); then sa_step(n), sa_positions(organ), sa_grab(...), ...
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <exception>
#include <memory>
#include <string>
#include <vector>

#include "softatlas/sim/sim.hpp"

namespace sim = softatlas::sim;

namespace {

struct Session {
  sim::SceneDesc desc;
  std::unique_ptr<sim::Model> model;
  std::unique_ptr<sim::State> state;
  std::unique_ptr<sim::Work> work;
  std::string error;
  std::vector<double> positions;  // organ_positions() output, read by JS
  std::array<double, 3> reaction{0, 0, 0};
  std::vector<int32_t> grabbed;
  int last_status = 0;
};

Session& session() {
  static Session s;
  return s;
}

bool compiled() { return session().model != nullptr; }

// The material's numeric fields in the order sa_add_organ() reads them; the page fills the array
// by these names from scene.json, so the order lives here only.
struct Field {
  const char* name;
  double sim::Material::*member;
};
const Field kFields[] = {
    {"young_modulus_pa", &sim::Material::young_modulus_pa},
    {"thickness_m", &sim::Material::thickness_m},
    {"total_mass_kg", &sim::Material::total_mass_kg},
    {"density_kg_m3", &sim::Material::density_kg_m3},
    {"stiffness", &sim::Material::stiffness},
    {"damping", &sim::Material::damping},
    {"damping_scale", &sim::Material::damping_scale},
    {"vertex_mass_kg", &sim::Material::vertex_mass_kg},
    {"elastica_a", &sim::Material::elastica_a},
    {"elastica_b", &sim::Material::elastica_b},
    {"curvature_unit_m", &sim::Material::curvature_unit_m},
    {"elastica_cap", &sim::Material::elastica_cap},
    {"tau_s", &sim::Material::tau_s},
    {"tau_c", &sim::Material::tau_c},
    {"flexion_stiffness", &sim::Material::flexion_stiffness},
    {"volume_stiffness", &sim::Material::volume_stiffness},
};
constexpr int kFieldCount = static_cast<int>(sizeof(kFields) / sizeof(kFields[0]));

}  // namespace

extern "C" {

// Comma-separated names of the material fields sa_add_organ() expects, in order.
const char* sa_material_fields() {
  static std::string names;
  if (names.empty())
    for (int i = 0; i < kFieldCount; ++i) names += (i ? "," : "") + std::string(kFields[i].name);
  return names.c_str();
}

const char* sa_error() { return session().error.c_str(); }

void sa_reset() {
  Session& s = session();
  s.model.reset();
  s.state.reset();
  s.work.reset();
  s.desc = sim::SceneDesc{};
  s.error.clear();
  s.grabbed.clear();
}

// Scene settings; integrator is "verlet" | "semi-implicit" | "implicit". Returns 0, or -1 with
// sa_error() set.
int sa_settings(const char* integrator, double dt_s, int gravity, double gx, double gy, double gz, int cg_iterations,
                double cg_tolerance, int guard, double max_tool_force_N, int max_substeps, int allow_sleep,
                double sleep_speed_m_s, int sleep_steps) {
  Session& s = session();
  if (!sim::parse_integrator(integrator, s.desc.integrator)) {
    s.error = std::string("scene.json: settings.integrator: unknown '") + integrator +
              "' (expected verlet, semi-implicit or implicit)";
    return -1;
  }
  s.desc.dt_s = dt_s;
  s.desc.gravity = gravity != 0;
  s.desc.gravity_m_s2 = {gx, gy, gz};
  s.desc.cg_iterations = cg_iterations;
  s.desc.cg_tolerance = cg_tolerance;
  s.desc.guard = guard != 0;
  s.desc.max_tool_force_N = max_tool_force_N;
  s.desc.max_substeps = max_substeps;
  s.desc.allow_sleep = allow_sleep != 0;
  s.desc.sleep_speed_m_s = sleep_speed_m_s;
  s.desc.sleep_steps = sleep_steps;
  s.desc.threads = 1;  // no worker threads in the page (the build has no pthreads)
  return 0;
}

// One organ: vertices #V*3 in metres, faces #F*3, fixed local vertex indices, the material (model
// name, elastica p, and kFieldCount numbers in sa_material_fields() order). Returns the organ's
// index in the scene, or -1 with sa_error() set.
int sa_add_organ(const char* name, const double* vertices, int nvert, const int32_t* faces, int nface,
                 const int32_t* fixed, int nfixed, const char* model, int elastica_p, const double* material,
                 int shown) {
  Session& s = session();
  sim::OrganDesc o;
  o.name = name;
  o.vertices.assign(vertices, vertices + 3 * static_cast<size_t>(std::max(nvert, 0)));
  o.faces.assign(faces, faces + 3 * static_cast<size_t>(std::max(nface, 0)));
  o.fixed.assign(fixed, fixed + std::max(nfixed, 0));
  if (!sim::parse_model_kind(model, o.material.model)) {
    s.error = std::string("scene.json: organs.") + name + ".material.model: unknown '" + model +
              "' (expected tmsm, cmsm, nmsm or flexion)";
    return -1;
  }
  o.material.elastica_p = elastica_p;
  for (int i = 0; i < kFieldCount; ++i) o.material.*(kFields[i].member) = material[i];
  o.shown = shown != 0;
  s.desc.organs.push_back(std::move(o));
  return static_cast<int>(s.desc.organs.size()) - 1;
}

void sa_add_connection(int organ_a, int vertex_a, int organ_b, int vertex_b, double rest_length_m, double stiffness) {
  sim::ConnectionDesc c;
  c.organ_a = organ_a, c.vertex_a = vertex_a, c.organ_b = organ_b, c.vertex_b = vertex_b;
  c.rest_length_m = rest_length_m;
  c.stiffness = stiffness;
  session().desc.connections.push_back(c);
}

// compile() + make_state() + make_work(). 0 on success, -1 with sa_error() set (InputError text).
int sa_compile() {
  Session& s = session();
  try {
    s.model = std::make_unique<sim::Model>(sim::compile(s.desc));
    s.state = std::make_unique<sim::State>(sim::make_state(*s.model));
    s.work = std::make_unique<sim::Work>(sim::make_work(*s.model));
  } catch (const std::exception& e) {
    s.model.reset();
    s.error = e.what();
    return -1;
  }
  s.desc.organs.clear();  // the model keeps what it needs
  return 0;
}

double sa_dt() { return compiled() ? session().model->dt_s : 0.0; }
double sa_time() { return compiled() ? session().state->time_s : 0.0; }
int sa_organ_count() { return compiled() ? static_cast<int>(session().model->organs.size()) : 0; }
const char* sa_organ_name(int organ) {
  return compiled() && organ >= 0 && organ < sa_organ_count()
             ? session().model->organs[static_cast<size_t>(organ)].name.c_str()
             : "";
}
int sa_find_organ(const char* name) { return compiled() ? sim::find_organ(*session().model, name) : -1; }
const char* sa_explain() {
  static std::string text;
  text = compiled() ? sim::explain(*session().model) : "";
  return text.c_str();
}

// n steps; returns the status of the worst one (StepStatus as int) and keeps the tool reaction.
int sa_step(int n) {
  if (!compiled()) return -1;
  Session& s = session();
  int worst = 0;
  for (int i = 0; i < n; ++i) worst = std::max(worst, static_cast<int>(sim::step(*s.model, *s.state, *s.work).status));
  s.reaction = sim::tool_reaction(*s.state);
  s.last_status = worst;
  return worst;
}

// Current positions of one organ, #V*3 in the source mesh's vertex order (the glb's order);
// returns a pointer into the heap, valid until the next call, and the count through *count.
const double* sa_positions(int organ, int* count) {
  Session& s = session();
  *count = 0;
  if (!compiled() || organ < 0 || organ >= sa_organ_count()) return nullptr;
  sim::organ_positions(*s.model, *s.state, organ, s.positions);
  *count = static_cast<int>(s.positions.size() / 3);
  return s.positions.data();
}

// Grasps the organ's free vertices within radius_m of (x, y, z) (the deformed surface; metres,
// the organ set's frame); the nearest free vertex when none is that close. Returns the number
// of vertices held (0: nothing to hold, e.g. the organ is not simulated).
int sa_grab(int organ, double x, double y, double z, double radius_m) {
  Session& s = session();
  if (!compiled() || organ < 0 || organ >= sa_organ_count()) return 0;
  const sim::OrganRange& r = s.model->organs[static_cast<size_t>(organ)];
  s.grabbed.clear();
  int32_t nearest = -1;
  double best = INFINITY;
  for (int32_t v = r.vert_begin; v < r.vert_end; ++v) {
    if (s.model->vert_inv_mass[static_cast<size_t>(v)] == 0.0) continue;
    const double dx = s.state->x[v] - x, dy = s.state->y[v] - y, dz = s.state->z[v] - z;
    const double d2 = dx * dx + dy * dy + dz * dz;
    if (d2 < radius_m * radius_m) s.grabbed.push_back(v);
    if (d2 < best) best = d2, nearest = v;
  }
  if (s.grabbed.empty() && nearest >= 0) s.grabbed.push_back(nearest);
  if (s.grabbed.empty()) return 0;
  sim::wake(*s.model, *s.state, organ);
  sim::attach(*s.model, *s.state, s.grabbed, {0, 0, 0}, 1);
  return static_cast<int>(s.grabbed.size());
}

// Moves the held patch to anchor + offset (metres).
void sa_move(double ox, double oy, double oz) {
  if (compiled() && !session().grabbed.empty()) sim::move_attachment(*session().state, {ox, oy, oz});
}

void sa_release() {
  Session& s = session();
  if (!compiled()) return;
  sim::release(*s.state);
  s.grabbed.clear();
  s.reaction = {0, 0, 0};
}

// The tool reaction of the last sa_step() (N), component c = 0, 1, 2.
double sa_reaction(int c) { return c >= 0 && c < 3 ? session().reaction[static_cast<size_t>(c)] : 0.0; }

// 1 if the organ is awake (moved in the last step; sleeping organs keep their positions).
int sa_organ_awake(int organ) {
  Session& s = session();
  if (!compiled() || organ < 0 || organ >= sa_organ_count()) return 0;
  return s.state->organ_awake[static_cast<size_t>(organ)] != 0;
}

// Largest displacement of one organ's vertices from the rest shape (m).
double sa_max_displacement(int organ) {
  Session& s = session();
  if (!compiled() || organ < 0 || organ >= sa_organ_count()) return 0.0;
  const sim::OrganRange& r = s.model->organs[static_cast<size_t>(organ)];
  double worst = 0.0;
  for (int32_t v = r.vert_begin; v < r.vert_end; ++v) {
    const double dx = s.state->x[v] - s.model->vert_rest_x[v], dy = s.state->y[v] - s.model->vert_rest_y[v],
                 dz = s.state->z[v] - s.model->vert_rest_z[v];
    worst = std::max(worst, dx * dx + dy * dy + dz * dz);
  }
  return std::sqrt(worst);
}

}  // extern "C"
