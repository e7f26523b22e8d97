// `softatlas bench sim`: the core's step on real meshes, in the scenario of shared/bench-ref
// (each mesh a body with its 10 lowest vertices fixed, gravity, dt = 1e-4, k = 30, d = 0.1,
// lumped masses 1000 kg/m^3 x 1 mm x area / 3, elastica a = 1, b = 0.1). Prints one JSON object.
// `softatlas sim SET|MESH... --explain`: the compiled plan of a scene.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numeric>

#include "softatlas/io/cli.hpp"
#include "softatlas/io/cli_number.hpp"
#include "softatlas/bench/cli.hpp"
#include "softatlas/io/mesh_io.hpp"
#include "softatlas/io/organ_set.hpp"
#include "softatlas/io/scene.hpp"
#include "softatlas/sim/sim.hpp"

namespace softatlas::bench {
namespace {

using nlohmann::json;

sim::OrganDesc body_from_mesh(const std::string& path, size_t index) {
  io::TriMesh mesh = io::read_mesh(path);
  sim::OrganDesc d;
  d.name = std::filesystem::path(path).stem().string() + "#" + std::to_string(index);
  d.vertices = mesh.vertices;
  d.faces = mesh.faces;
  return d;
}

// The bench-ref scenario on one body (see shared/bench-ref/springref.cpp).
void bench_ref_scenario(sim::OrganDesc& d, sim::ModelKind model) {
  const size_t nv = d.vertices.size() / 3;
  std::vector<char> used(nv, 0);
  for (int32_t v : d.faces) used[v] = 1;
  std::vector<int32_t> ids;
  for (size_t v = 0; v < nv; ++v)
    if (used[v]) ids.push_back(static_cast<int32_t>(v));
  const size_t n = std::min<size_t>(10, ids.size());
  std::partial_sort(ids.begin(), ids.begin() + static_cast<long>(n), ids.end(), [&](int32_t a, int32_t b) {
    return d.vertices[3 * a + 2] < d.vertices[3 * b + 2] || (d.vertices[3 * a + 2] == d.vertices[3 * b + 2] && a < b);
  });
  d.fixed.assign(ids.begin(), ids.begin() + static_cast<long>(n));
  sim::Material& m = d.material;
  m.model = model;
  m.stiffness = 30.0;
  m.damping = 0.1;
  m.elastica_a = 1.0;
  m.elastica_b = 0.1;
  m.elastica_p = 1;
  m.elastica_literal = true;  // bench-ref runs the paper's form (curvature of the deformed shape)
  // bench-ref reads eq 2 literally (kappa = H / 3, no length unit): 1.5 H L / 2 * b with L = 1/3
  // gives the same b kappa / 2 per vertex, so both run the same force law.
  m.curvature_unit_m = 1.0 / 3.0;
  m.tau_s = model == sim::ModelKind::cmsm ? 0.01 : -1.0;
  m.tau_c = model == sim::ModelKind::cmsm ? 0.01 : -1.0;
  // lumped masses: density 1000 x thickness 1e-3 x area, spread by eq 8
  std::vector<double> x(nv), y(nv), z(nv);
  for (size_t v = 0; v < nv; ++v) x[v] = d.vertices[3 * v], y[v] = d.vertices[3 * v + 1], z[v] = d.vertices[3 * v + 2];
  const double area = sim::surface_area(x.data(), y.data(), z.data(), d.faces.data(), 0, d.faces.size() / 3);
  m.total_mass_kg = 1000.0 * 1e-3 * area;
}

struct BenchSimArgs {
  std::vector<std::string> meshes;
  std::string model_name = "tmsm", integrator_name = "semi-implicit";
  int steps = 2000, repeat = 5, cg_iterations = 25, threads = 1, warmup = 200;
  bool json_out = false, no_gravity = false, no_guard = false;
  double dt = 1e-4;
};

int bench_sim(const BenchSimArgs& a) {
  const auto& [meshes, model_name, integrator_name, steps, repeat, cg_iterations, threads, warmup, json_out, no_gravity,
               no_guard, dt] = a;

  sim::ModelKind model;
  if (!sim::parse_model_kind(model_name, model))
    throw InputError("--model", "unknown model '" + model_name + "' (expected tmsm, cmsm, nmsm or flexion)");
  sim::Integrator integrator;
  if (!sim::parse_integrator(integrator_name, integrator))
    throw InputError("--integrator",
                     "unknown integrator '" + integrator_name + "' (expected verlet, semi-implicit or implicit)");
  sim::SceneDesc scene;
  for (size_t i = 0; i < meshes.size(); ++i) {
    sim::OrganDesc d = body_from_mesh(meshes[i], i);
    bench_ref_scenario(d, model);
    scene.organs.push_back(std::move(d));
  }
  scene.integrator = integrator;
  scene.dt_s = dt;
  scene.gravity = !no_gravity;
  scene.guard = !no_guard;
  scene.cg_iterations = cg_iterations;
  scene.cg_tolerance = 0.0;   // always run the requested iterations: the cost is what we time
  scene.allow_sleep = false;  // same work every step as bench-ref
  // bench-ref has no contact (and the meshes of --mesh come from different sources, placed as
  // they are): contact on by default made TMSM 5.9x bench-ref here (1.1x without).
  scene.contact = false;
  scene.threads = threads;
  const sim::Model m = sim::compile(scene);
  sim::State s = sim::make_state(m);
  sim::Work w = sim::make_work(m);

  int64_t guard_steps = 0, cg_done = 0, cg_steps = 0;
  auto one_step = [&] {
    const sim::StepReport rep = sim::step(m, s, w);
    guard_steps += rep.status != sim::StepStatus::ok;
    if (rep.cg_iterations > 0) cg_done += rep.cg_iterations, ++cg_steps;
  };
  for (int k = 0; k < warmup; ++k) one_step();
  std::vector<double> us(repeat);
  for (int r = 0; r < repeat; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    for (int k = 0; k < steps; ++k) one_step();
    const auto t1 = std::chrono::steady_clock::now();
    us[r] = std::chrono::duration<double, std::micro>(t1 - t0).count() / steps;
  }
  std::vector<double> sorted = us;
  std::sort(sorted.begin(), sorted.end());
  const size_t h = sorted.size() / 2;
  const double median = sorted.size() % 2 ? sorted[h] : 0.5 * (sorted[h - 1] + sorted[h]);
  double checksum = 0.0;
  bool finite = true;
  for (int32_t v = 0; v < m.nvert; ++v) {
    checksum += s.x[v] + s.y[v] + s.z[v];
    finite = finite && std::isfinite(s.x[v]) && std::isfinite(s.y[v]) && std::isfinite(s.z[v]);
  }
  json j;
  j["model"] = sim::to_string(model);
  j["integrator"] = sim::to_string(integrator);
  j["effective_integrator"] = sim::to_string(m.effective_integrator);
  j["bodies"] = meshes.size();
  j["vertices"] = m.nvert;
  j["faces"] = m.nface;
  j["springs"] = m.nspring;
  j["threads"] = threads;
  j["cg_iterations"] = integrator == sim::Integrator::implicit ? cg_iterations : 0;
  // iterations the CG did per implicit step (cg_tolerance 0 here: all of them, restarts included)
  j["cg_iterations_mean"] = cg_steps ? static_cast<double>(cg_done) / cg_steps : 0.0;
  j["gravity"] = !no_gravity;
  j["dt_s"] = dt;
  j["warmup_steps"] = warmup;
  j["steps"] = steps;
  j["repeat"] = repeat;
  j["us_per_step_median"] = median;
  j["us_per_step_min"] = sorted.front();
  j["us_per_step_runs"] = us;
  j["ns_per_spring"] = median * 1e3 / std::max<int32_t>(1, m.nspring);
  j["stable_dt_s"] = m.stable_dt_s;
  j["substeps"] = m.substeps;
  j["guard_steps"] = guard_steps;
  j["max_displacement"] = finite ? json(sim::max_displacement(m, s)) : json(nullptr);
  j["checksum"] = finite ? json(checksum) : json(nullptr);
  j["finite"] = finite;
  if (json_out) {
    std::printf("%s\n", j.dump().c_str());
  } else {
    std::printf("%s %s: %d vertices, %d springs, %.3f us/step (%.3f ns/spring), finite: %s\n",
                j["model"].get<std::string>().c_str(), j["integrator"].get<std::string>().c_str(), m.nvert, m.nspring,
                median, j["ns_per_spring"].get<double>(), finite ? "yes" : "no");
  }
  return finite ? 0 : 3;
}

struct SimArgs {
  std::vector<std::string> inputs, shown;
  std::string model_name, integrator_name = "semi-implicit";
  double dt = 0.0;  // the models' own (sim::recommended_dt_s)
  bool explain_flag = false, gravity = false, no_guard = false;
};

int sim_explain(const SimArgs& a) {
  const auto& [inputs, shown, model_name, integrator_name, dt, explain_flag, gravity, no_guard] = a;
  (void)explain_flag;
  io::SceneOptions opt;
  if (!sim::parse_integrator(integrator_name, opt.integrator))
    throw InputError("--integrator", "unknown integrator '" + integrator_name + "'");
  opt.dt_s = dt;
  opt.gravity = gravity;
  opt.guard = !no_guard;
  opt.shown = shown;
  opt.model_override = model_name;
  sim::SceneDesc scene;
  if (inputs.size() == 1 && std::filesystem::is_directory(inputs[0])) {
    scene = io::scene_from_organ_set(io::read_organ_set(inputs[0]), opt);
  } else {
    for (size_t i = 0; i < inputs.size(); ++i) {
      sim::OrganDesc d = body_from_mesh(inputs[i], i);
      if (!model_name.empty() && !sim::parse_model_kind(model_name, d.material.model))
        throw InputError("--model", "unknown model '" + model_name + "'");
      d.material.curvature_unit_m = 1.0;
      scene.organs.push_back(std::move(d));
    }
    scene.integrator = opt.integrator;
    scene.dt_s = dt;
    scene.gravity = gravity;
    scene.guard = !no_guard;
  }
  const sim::Model m = sim::compile(scene);
  std::fputs(sim::explain(m).c_str(), stdout);
  return 0;
}

void add_bench_sim(CLI::App& bench, cli::Status* status) {
  CLI::App* app = bench.add_subcommand("sim", "time the physics step on real meshes (bench-ref scenario)");
  auto a = std::make_shared<BenchSimArgs>();
  app->add_option("--mesh", a->meshes, "mesh files (OBJ, PLY, STL, OFF, glTF); each is one body")->required();
  app->add_option("--model", a->model_name, "tmsm | cmsm | nmsm | flexion");
  app->add_option("--integrator", a->integrator_name, "verlet | semi-implicit | implicit");
  app->add_option("--cg-iterations", a->cg_iterations, "CG iterations per implicit step")->check(CLI::Range(1, 100000));
  app->add_option("--steps", a->steps, "timed steps per repeat")->check(CLI::Range(1, 1000000));
  app->add_option("--repeat", a->repeat, "timed repeats (the median is reported)")->check(CLI::Range(1, 1000));
  app->add_option("--warmup", a->warmup, "untimed steps first")->check(CLI::Range(0, 1000000));
  app->add_option("--threads", a->threads, "worker threads (the core steps organs in parallel)")
      ->check(CLI::Range(1, 64));
  app->add_option("--dt", a->dt, "time step (s)")->check(io::finite_in(1e-7, 0.1));
  app->add_flag("--json", a->json_out, "print one JSON object");
  app->add_flag("--no-gravity", a->no_gravity, "rest shape stays put (checks force-free rest)");
  app->add_flag("--no-guard", a->no_guard, "turn the stability guard off");
  cli::on_run(app, status, [a] { return bench_sim(*a); });
}

// `sim SET|MESH... --explain`, and `sim demo` (physics_demo.cpp) below it.
CLI::App* add_sim(CLI::App& root, cli::Status* status) {
  CLI::App* app = root.add_subcommand("sim", "compile a scene and print its plan (SET|MESH... --explain), or sim demo");
  app->require_subcommand(0, 1);
  auto a = std::make_shared<SimArgs>();
  app->add_option("inputs", a->inputs, "an organ-set folder, or mesh files");
  app->add_flag("--explain", a->explain_flag, "print the compiled plan");
  app->add_option("--show", a->shown, "organs to show (default: all)")->delimiter(',');
  app->add_option("--model", a->model_name, "override every organ's model: solid | nmsm | tmsm | cmsm | flexion");
  app->add_option("--integrator", a->integrator_name, "verlet | semi-implicit | implicit");
  app->add_option("--dt", a->dt, "time step (s; default: the models' own, 8 ms all solid, else 1 ms)")
      ->check(io::finite_in(1e-7, 0.1));
  app->add_flag("--gravity", a->gravity, "gravity on");
  app->add_flag("--no-guard", a->no_guard, "turn the stability guard off");
  app->callback([app, a, status] {
    if (!app->get_subcommands().empty()) return;  // `sim demo` ran
    if (a->inputs.empty()) throw CLI::RequiredError("inputs (an organ-set folder, or mesh files)");
    status->rc = sim_explain(*a);
  });
  return app;
}

}  // namespace

void add_commands(CLI::App& root, cli::Status* status) {
  add_sim_demo(*add_sim(root, status), status);
  CLI::App* bench = cli::group(root, "bench", "benchmarks (JSON on stdout)");
  add_bench_sim(*bench, status);
  add_bench_restore(*bench, status);
  add_bench_contact(*bench, status);
}

int cli_main(const std::vector<std::string>& args) { return cli::run_only(add_commands, args); }

}  // namespace softatlas::bench
