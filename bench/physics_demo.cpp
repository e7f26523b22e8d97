// `softatlas sim demo`: pulls the shipped liver (data/meshes/liver_1000.obj, the paper 000
// Table II setting: one top face moved by [0, 20, 20] mm in 30 iterations of 1 ms, then held for
// a second so that the organ follows) with every model, and
// prints the feedback force and the volume change per model; writes results.json and an SVG of
// the rest and deformed shapes (side view).
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <chrono>
#include <sstream>

#include "softatlas/bench/cli.hpp"
#include "softatlas/io/cli.hpp"
#include "softatlas/io/output_folder.hpp"
#include "softatlas/io/cli_number.hpp"
#include "softatlas/sim/error.hpp"
#include "softatlas/bench/cli.hpp"
#include "softatlas/io/mesh_io.hpp"
#include "softatlas/sim/sim.hpp"

namespace softatlas::bench {
namespace fs = std::filesystem;

namespace {

struct DemoRun {
  std::string model;
  std::array<double, 3> feedback_mN{0, 0, 0};
  double volume_change_pct = 0.0;
  double max_displacement_mm = 0.0;
  double ms_per_step = 0.0;
  std::vector<double> deformed;  // #V*3, mm
};

// Side view (y right, z up) of the mesh edges: rest in grey, each model in its colour.
std::string svg_picture(const io::TriMesh& rest, const std::vector<DemoRun>& runs, const std::vector<int32_t>& face) {
  double lo[2] = {1e300, 1e300}, hi[2] = {-1e300, -1e300};
  auto grow = [&](const std::vector<double>& V) {
    for (size_t i = 0; i < V.size() / 3; ++i)
      for (int c = 0; c < 2; ++c) lo[c] = std::min(lo[c], V[3 * i + 1 + c]), hi[c] = std::max(hi[c], V[3 * i + 1 + c]);
  };
  grow(rest.vertices);
  for (const DemoRun& r : runs) grow(r.deformed);
  const double W = 360, H = 300, pad = 20;
  const double sc = std::min((W - 2 * pad) / (hi[0] - lo[0]), (H - 2 * pad - 30) / (hi[1] - lo[1]));
  const char* colours[] = {"#1f77b4", "#ff7f0e", "#d62728", "#9467bd", "#2ca02c", "#8c564b"};
  std::ostringstream os;
  os << "<svg xmlns='http://www.w3.org/2000/svg' width='" << W * runs.size() << "' height='" << H
     << "' font-family='sans-serif' font-size='13'>\n<rect width='100%' height='100%' fill='white'/>\n";
  for (size_t k = 0; k < runs.size(); ++k) {
    const double ox = k * W;
    auto px = [&](const std::vector<double>& V, int32_t v, double& x, double& y) {
      x = ox + pad + (V[3 * v + 1] - lo[0]) * sc;
      y = H - pad - (V[3 * v + 2] - lo[1]) * sc;
    };
    auto edges = [&](const std::vector<double>& V, const char* colour, double width) {
      os << "<path fill='none' stroke='" << colour << "' stroke-width='" << width << "' d='";
      for (size_t f = 0; f < rest.faces.size(); f += 3)
        for (int e = 0; e < 3; ++e) {
          const int32_t a = rest.faces[f + e], b = rest.faces[f + (e + 1) % 3];
          if (a > b) continue;
          double x0, y0, x1, y1;
          px(V, a, x0, y0), px(V, b, x1, y1);
          os << "M" << x0 << ' ' << y0 << 'L' << x1 << ' ' << y1;
        }
      os << "'/>\n";
    };
    edges(rest.vertices, "#bbbbbb", 0.5);
    edges(runs[k].deformed, colours[k % (sizeof colours / sizeof colours[0])], 0.6);
    for (int32_t v : face) {
      double x, y;
      px(runs[k].deformed, v, x, y);
      os << "<circle cx='" << x << "' cy='" << y << "' r='3' fill='black'/>\n";
    }
    char title[200];
    std::snprintf(
        title, sizeof title, "%s: feedback %.0f mN, volume %+.2f %%", runs[k].model.c_str(),
        std::sqrt(runs[k].feedback_mN[0] * runs[k].feedback_mN[0] + runs[k].feedback_mN[1] * runs[k].feedback_mN[1] +
                  runs[k].feedback_mN[2] * runs[k].feedback_mN[2]),
        runs[k].volume_change_pct);
    os << "<text x='" << ox + pad << "' y='20'>" << title << "</text>\n";
    os << "<text x='" << ox + pad << "' y='" << H - 4 << "' fill='#777'>side view (y right, z up); grey: rest</text>\n";
  }
  os << "</svg>\n";
  return os.str();
}

}  // namespace

namespace {
struct DemoArgs {
  std::string mesh_path = std::string(SOFTATLAS_DATA_DIR) + "/meshes/liver_1000.obj";
  std::string out = "out/physics";
  double pull_mm = 20.0;
  int hold_steps = 300;
};

int physics_demo(const DemoArgs& a) {
  const auto& [mesh_path, out, pull_mm, hold_steps] = a;
  io::check_writable(out);  // before the runs, not after them
  const io::TriMesh mesh = io::read_mesh(mesh_path);
  // top face (highest centroid) and the 20 lowest vertices held, as in the paper's setting
  size_t top = 0;
  double best = -1e300;
  for (size_t f = 0; f < mesh.face_count(); ++f) {
    double z = 0;
    for (int c = 0; c < 3; ++c) z += mesh.vertices[3 * mesh.faces[3 * f + c] + 2];
    if (z > best) best = z, top = f;
  }
  const std::vector<int32_t> face{mesh.faces[3 * top], mesh.faces[3 * top + 1], mesh.faces[3 * top + 2]};
  std::vector<int32_t> order(mesh.vertex_count());
  for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int32_t>(i);
  std::sort(order.begin(), order.end(),
            [&](int32_t a, int32_t b) { return mesh.vertices[3 * a + 2] < mesh.vertices[3 * b + 2]; });
  order.resize(20);

  std::vector<DemoRun> runs;
  std::printf("%-8s %28s %14s %12s %10s\n", "model", "feedback force (mN)", "volume (%)", "max disp", "ms/step");
  struct Variant {
    sim::ModelKind kind;
    double volume;
    const char* label;
  };
  const Variant variants[] = {{sim::ModelKind::tmsm, 0.0, "tmsm"},       {sim::ModelKind::cmsm, 0.0, "cmsm"},
                              {sim::ModelKind::nmsm, 0.0, "nmsm"},       {sim::ModelKind::nmsm, 0.5, "nmsm+vol"},
                              {sim::ModelKind::flexion, 0.5, "flexion"}, {sim::ModelKind::solid, 0.0, "solid"}};
  for (const Variant& var : variants) {
    const sim::ModelKind kind = var.kind;
    sim::SceneDesc scene;
    sim::OrganDesc d;
    d.name = "liver";
    for (double x : mesh.vertices) d.vertices.push_back(1e-3 * x);
    d.faces = mesh.faces;
    d.fixed = order;
    d.material.model = kind;
    d.material.young_modulus_pa = 4000.0;  // liver-like, a few kPa
    d.material.elastica_b = 0.5;           // Table II, 1000 faces
    d.material.tau_s = kind == sim::ModelKind::cmsm ? 0.0 : -1.0;
    d.material.flexion_stiffness = kind == sim::ModelKind::flexion ? 1e-4 : 0.0;
    d.material.volume_stiffness = var.volume;
    scene.organs.push_back(d);
    scene.integrator = sim::Integrator::verlet;
    scene.dt_s = 1e-3;
    scene.allow_sleep = false;
    const sim::Model m = sim::compile(scene);
    sim::State s = sim::make_state(m);
    sim::Work w = sim::make_work(m);
    const double v0 = sim::total_volume(m, s);
    std::vector<int32_t> picked;
    for (int32_t v : face) picked.push_back(sim::global_vertex(m, 0, v));
    sim::attach(m, s, picked, {0, 1e-3 * pull_mm, 1e-3 * pull_mm}, 30);
    const auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < 30 + hold_steps; ++i) sim::step(m, s, w);
    const auto t1 = std::chrono::steady_clock::now();
    DemoRun r;
    r.model = var.label;
    const auto react = sim::tool_reaction(s);
    for (int c = 0; c < 3; ++c) r.feedback_mN[c] = -1e3 * react[c];
    r.volume_change_pct = 100.0 * (sim::total_volume(m, s) - v0) / v0;
    r.max_displacement_mm = 1e3 * sim::max_displacement(m, s);
    r.ms_per_step = std::chrono::duration<double, std::milli>(t1 - t0).count() / (30.0 + hold_steps);
    sim::organ_positions(m, s, 0, r.deformed);
    for (double& x : r.deformed) x *= 1e3;
    std::printf("%-8s [%8.1f %8.1f %8.1f] %14.3f %10.2f mm %10.4f\n", r.model.c_str(), r.feedback_mN[0],
                r.feedback_mN[1], r.feedback_mN[2], r.volume_change_pct, r.max_displacement_mm, r.ms_per_step);
    runs.push_back(std::move(r));
  }
  // Both files or none (a full disk, a read-only folder): one InputError naming the folder.
  io::StagedFolder staged(out);
  nlohmann::json j;
  j["mesh"] = mesh_path;
  j["pull_mm"] = {0.0, pull_mm, pull_mm};
  j["iterations"] = 30;
  j["hold_steps"] = hold_steps;
  for (const DemoRun& r : runs)
    j["runs"].push_back({{"model", r.model},
                         {"feedback_force_mN", r.feedback_mN},
                         {"volume_change_pct", r.volume_change_pct},
                         {"max_displacement_mm", r.max_displacement_mm},
                         {"ms_per_step", r.ms_per_step}});
  staged.write_and_commit([&](const std::string& dir) {
    io::write_file_atomic((fs::path(dir) / "deformation.svg").string(), svg_picture(mesh, runs, face));
    io::write_file_atomic((fs::path(dir) / "results.json").string(), j.dump(2) + "\n");
  });
  std::printf("physics demo: %s/results.json, %s/deformation.svg\n", out.c_str(), out.c_str());
  return 0;
}

}  // namespace

void add_sim_demo(CLI::App& sim, cli::Status* status) {
  CLI::App* app = sim.add_subcommand("demo", "pull the shipped liver with every model");
  auto a = std::make_shared<DemoArgs>();
  app->add_option("--mesh", a->mesh_path, "surface mesh in mm");
  app->add_option("--out", a->out, "output folder");
  app->add_option("--pull-mm", a->pull_mm, "pull of the top face along [0, 1, 1] (mm)")
      ->check(io::finite_in(-200, 200));
  app->add_option("--hold-steps", a->hold_steps, "steps (1 ms) the face is held after the 30 iterations (at most 20 s)")
      ->check(CLI::Range(0, 20000));
  cli::on_run(app, status, [a] { return physics_demo(*a); });
}

}  // namespace softatlas::bench
