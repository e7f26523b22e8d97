// Native side of tests/web/wasm_match.mjs: the exported scene.json (the SceneDesc that
// io::scene_from_organ_set() built, written with round-trip doubles) read back into a
// sim::SceneDesc and compiled natively, the pull protocol below, and the positions after it as
// JSON on stdout. The node script replays the same protocol in WebAssembly and compares.
//
// Protocol: grasp the free vertices of ORGAN within 10 mm of its most anterior vertex (rest shape)
// as the page's sa_grab() does, attach, move the patch by (0, +20 mm, 0) (anterior), step
// PULL steps, release, step FREE steps.
//
//   web_native_steps SCENE_JSON ORGAN PULL FREE
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>
#include <vector>

#include <fstream>
#include <nlohmann/json.hpp>

#include "softatlas/sim/sim.hpp"

namespace sim = softatlas::sim;
using json = nlohmann::json;

// scene.json (pipeline/src/export_web.cpp) -> SceneDesc.
sim::SceneDesc read_scene(const char* path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(std::string("cannot read ") + path);
  const json j = json::parse(in);
  const json& s = j.at("settings");
  sim::SceneDesc d;
  if (!sim::parse_integrator(s.at("integrator").get<std::string>(), d.integrator))
    throw std::runtime_error("integrator");
  d.dt_s = s.at("dt_s");
  d.gravity = s.at("gravity");
  d.gravity_m_s2 = s.at("gravity_m_s2");
  d.cg_iterations = s.at("cg_iterations");
  d.cg_tolerance = s.at("cg_tolerance");
  d.guard = s.at("guard");
  d.max_tool_force_N = s.at("max_tool_force_N");
  d.max_substeps = s.at("max_substeps");
  d.allow_sleep = s.at("allow_sleep");
  d.sleep_speed_m_s = s.at("sleep_speed_m_s");
  d.sleep_steps = s.at("sleep_steps");
  for (const json& o : j.at("organs")) {
    sim::OrganDesc od;
    od.name = o.at("name");
    od.vertices = o.at("vertices").get<std::vector<double>>();
    od.faces = o.at("faces").get<std::vector<int32_t>>();
    od.fixed = o.at("fixed").get<std::vector<int32_t>>();
    od.shown = o.at("shown");
    const json& m = o.at("material");
    if (!sim::parse_model_kind(m.at("model").get<std::string>(), od.material.model)) throw std::runtime_error("model");
    od.material.elastica_p = m.at("elastica_p");
    sim::Material& t = od.material;
    for (auto [name, field] : {std::pair<const char*, double*>{"young_modulus_pa", &t.young_modulus_pa},
                               {"thickness_m", &t.thickness_m},
                               {"total_mass_kg", &t.total_mass_kg},
                               {"density_kg_m3", &t.density_kg_m3},
                               {"stiffness", &t.stiffness},
                               {"damping", &t.damping},
                               {"damping_scale", &t.damping_scale},
                               {"vertex_mass_kg", &t.vertex_mass_kg},
                               {"elastica_a", &t.elastica_a},
                               {"elastica_b", &t.elastica_b},
                               {"curvature_unit_m", &t.curvature_unit_m},
                               {"elastica_cap", &t.elastica_cap},
                               {"tau_s", &t.tau_s},
                               {"tau_c", &t.tau_c},
                               {"flexion_stiffness", &t.flexion_stiffness},
                               {"volume_stiffness", &t.volume_stiffness}})
      *field = m.at(name).get<double>();
    d.organs.push_back(std::move(od));
  }
  for (const json& c : j.at("connections")) {
    sim::ConnectionDesc cd;
    cd.organ_a = c.at("organ_a"), cd.vertex_a = c.at("vertex_a");
    cd.organ_b = c.at("organ_b"), cd.vertex_b = c.at("vertex_b");
    cd.rest_length_m = c.at("rest_length_m"), cd.stiffness = c.at("stiffness");
    d.connections.push_back(cd);
  }
  return d;
}

int main(int argc, char** argv) {
  if (argc != 5) {
    std::fprintf(stderr, "usage: web_native_steps SET ORGAN PULL FREE\n");
    return 2;
  }
  try {
    const sim::SceneDesc desc = read_scene(argv[1]);
    const sim::Model model = sim::compile(desc);
    sim::State state = sim::make_state(model);
    sim::Work work = sim::make_work(model);
    const int organ = sim::find_organ(model, argv[2]);
    if (organ < 0) throw std::runtime_error(std::string("no organ ") + argv[2]);
    const sim::OrganRange& r = model.organs[static_cast<size_t>(organ)];
    int32_t front = r.vert_begin;
    for (int32_t v = r.vert_begin; v < r.vert_end; ++v)
      if (state.y[v] > state.y[front]) front = v;
    const double px = state.x[front], py = state.y[front], pz = state.z[front], radius = 0.010;
    std::vector<int32_t> verts;
    for (int32_t v = r.vert_begin; v < r.vert_end; ++v) {
      if (model.vert_inv_mass[static_cast<size_t>(v)] == 0.0) continue;
      const double dx = state.x[v] - px, dy = state.y[v] - py, dz = state.z[v] - pz;
      if (dx * dx + dy * dy + dz * dz < radius * radius) verts.push_back(v);
    }
    sim::wake(model, state, organ);
    sim::attach(model, state, verts, {0, 0, 0}, 1);
    sim::move_attachment(state, {0, 0.020, 0});
    const int pull = std::atoi(argv[3]), free_steps = std::atoi(argv[4]);
    for (int i = 0; i < pull; ++i) sim::step(model, state, work);
    const std::array<double, 3> reaction = sim::tool_reaction(state);
    sim::release(state);
    for (int i = 0; i < free_steps; ++i) sim::step(model, state, work);
    std::printf(
        "{\"point\": [%.17g, %.17g, %.17g], \"grabbed\": %zu, \"reaction\": [%.17g, %.17g, %.17g], \"organs\": {", px,
        py, pz, verts.size(), reaction[0], reaction[1], reaction[2]);
    std::vector<double> pos;
    for (size_t o = 0; o < model.organs.size(); ++o) {
      sim::organ_positions(model, state, static_cast<int32_t>(o), pos);
      std::printf("%s\"%s\": [", o ? ", " : "", model.organs[o].name.c_str());
      for (size_t k = 0; k < pos.size(); ++k) std::printf("%s%.17g", k ? "," : "", pos[k]);
      std::printf("]");
    }
    std::printf("}}\n");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "web_native_steps: %s\n", e.what());
    return 1;
  }
  return 0;
}
