// Native side of tests/web/wasm_match.mjs: the organ set through the native path
// (io::read_organ_set + io::scene_from_organ_set + sim::compile), the pull protocol below, and the
// positions after it as JSON (round-trip doubles) on stdout. The node script replays the same
// protocol on the exported scene.json in WebAssembly and compares.
//
// Protocol: grasp the free vertices of ORGAN within 10 mm of its most anterior vertex (rest shape)
// as the page's sa_grab() does, attach, move the patch by (0, +20 mm, 0) (anterior), step
// PULL steps, release, step FREE steps.
//
//   web_native_steps SET ORGAN PULL FREE
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>
#include <vector>

#include "softatlas/io/organ_set.hpp"
#include "softatlas/io/scene.hpp"
#include "softatlas/sim/sim.hpp"

namespace sim = softatlas::sim;
namespace io = softatlas::io;

int main(int argc, char** argv) {
  if (argc != 5) {
    std::fprintf(stderr, "usage: web_native_steps SET ORGAN PULL FREE\n");
    return 2;
  }
  try {
    const sim::SceneDesc desc = io::scene_from_organ_set(io::read_organ_set(argv[1]), io::SceneOptions{});
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
    std::printf("{\"point\": [%.17g, %.17g, %.17g], \"grabbed\": %zu, \"reaction\": [%.17g, %.17g, %.17g], \"organs\": {",
                px, py, pz, verts.size(), reaction[0], reaction[1], reaction[2]);
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
