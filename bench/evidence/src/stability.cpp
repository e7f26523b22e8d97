// `softatlas bench stability`: where each model and integrator stays stable, with and without the
// guard, over stiffness, time step, load size and mesh quality (issue 7).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>

#include "softatlas/evidence/evidence.hpp"
#include "softatlas/evidence/svg.hpp"
#include "softatlas/sim/error.hpp"

namespace softatlas::evidence {

using nlohmann::json;

namespace {

// First neighbour and 1-ring of every vertex.
std::vector<std::vector<int32_t>> rings(const TriMesh& m) {
  std::vector<std::set<int32_t>> r(m.nvert());
  for (int32_t f = 0; f < m.nface(); ++f)
    for (int k = 0; k < 3; ++k) {
      r[m.F[3 * f + k]].insert(m.F[3 * f + (k + 1) % 3]);
      r[m.F[3 * f + k]].insert(m.F[3 * f + (k + 2) % 3]);
    }
  std::vector<std::vector<int32_t>> out(m.nvert());
  for (int32_t i = 0; i < m.nvert(); ++i) out[i].assign(r[i].begin(), r[i].end());
  return out;
}

}  // namespace

// Degraded copies of a good mesh (same topology): slivers (vertices slid 90% of the way to a
// neighbour), near-zero edges (vertices within 1e-6 of an edge length of a neighbour), and flipped
// triangles (vertices pushed past a neighbour so the triangles between fold over).
TriMesh degrade(const TriMesh& good, const std::string& kind) {
  TriMesh m = good;
  if (kind == "good") return m;
  const auto ring = rings(good);
  for (int32_t i = 0; i < m.nvert(); ++i) {
    const int32_t j = ring[i].front();
    double* p = &m.V[3 * i];
    const double* q = &good.V[3 * j];
    if (kind == "sliver" && i % 5 == 1) {
      for (int c = 0; c < 3; ++c) p[c] = good.V[3 * i + c] + 0.9 * (q[c] - good.V[3 * i + c]);
    } else if (kind == "short_edge" && i % 7 == 1) {
      for (int c = 0; c < 3; ++c) p[c] = q[c] + 1e-6 * (good.V[3 * i + c] - q[c]);
    } else if (kind == "flipped" && i % 11 == 1) {
      // Past its neighbour: the triangles on that side fold over (their normals flip).
      for (int c = 0; c < 3; ++c) p[c] = good.V[3 * i + c] + 1.6 * (q[c] - good.V[3 * i + c]);
    }
  }
  return m;
}

json run_stability(const Options& opt) {
  const auto t_start = std::chrono::steady_clock::now();
  const bool full = opt.grid == Grid::full, tiny = opt.grid == Grid::tiny;
  const std::vector<double> stiffness = full   ? std::vector<double>{1, 10, 100, 1e3, 1e4, 1e5, 1e6}
                                        : tiny ? std::vector<double>{1, 1e6}
                                               : std::vector<double>{1, 100, 1e4, 1e6};
  const std::vector<double> dts = full   ? std::vector<double>{1e-5, 1e-4, 1e-3, 1e-2, 1e-1}
                                  : tiny ? std::vector<double>{1e-4, 1e-2}
                                         : std::vector<double>{1e-4, 1e-3, 1e-2, 1e-1};
  struct Load {
    std::string name;
    bool attach;
    std::array<double, 3> value;
    double perturb_m = 0.0;  // > 0: no load, rest plus this random perturbation (self-excitation)
  };
  const Load unloaded{"rest_perturbed", false, {0, 0, 0}, 1e-6};
  const std::vector<Load> loads =
      full ? std::vector<Load>{{"force_1N", false, {0, 1, 0}},
                               {"force_10N", false, {0, 10, 0}},
                               {"pull_10mm", true, {0, 0.01, 0}},
                               {"pull_100mm", true, {0, 0.1, 0}},
                               unloaded}
           : std::vector<Load>{{"force_10N", false, {0, 10, 0}}, {"pull_100mm", true, {0, 0.1, 0}}, unloaded};
  const std::vector<std::string> meshes = full || !tiny
                                              ? std::vector<std::string>{"good", "sliver", "short_edge", "flipped"}
                                              : std::vector<std::string>{"good", "flipped"};
  std::vector<std::pair<std::string, std::string>> combos;
  const std::vector<std::string> models =
      full ? std::vector<std::string>{"tmsm", "cmsm", "nmsm", "flexion"} : std::vector<std::string>{"tmsm", "nmsm"};
  const std::vector<std::string> integ = tiny ? std::vector<std::string>{"semi_implicit", "implicit"}
                                              : std::vector<std::string>{"verlet", "semi_implicit", "implicit"};
  for (const auto& m : models)
    for (const auto& i : integ) combos.push_back({m, i});
  combos.push_back({"tmm", "implicit"});
  if (!tiny) combos.push_back({"solid", "implicit"});  // the atlas default (its own solver)
  const int64_t steps = full ? 200 : 100;
  const TriMesh sphere = icosphere(2, 0.05);
  std::vector<int32_t> fixed;
  for (int32_t i = 0; i < sphere.nvert(); ++i)
    if (sphere.V[3 * i + 1] < -0.04) fixed.push_back(i);
  const std::vector<int32_t> tool = region(sphere.V, {0, 0.05, 0}, 0.012);
  const double diameter = 0.1;

  json cells = json::array();
  json rejected = json::array();
  std::fprintf(stderr, "stability: %zu stiffness x %zu dt x %zu loads x %zu meshes x %zu model/integrator x 2 guard\n",
               stiffness.size(), dts.size(), loads.size(), meshes.size(), combos.size());
  for (const std::string& mesh_kind : meshes) {
    const TriMesh mesh = degrade(sphere, mesh_kind);
    for (const auto& [model, integrator] : combos)
      for (bool guard : {false, true})
        for (double k : stiffness)
          for (double dt : dts)
            for (const Load& load : loads) {
              ModelSpec spec = paper_spec(model, integrator, 320);
              spec.dt_s = dt;
              spec.guard = guard;
              spec.elastica_b = model == "nmsm" ? 0.3 : 0.0;
              if (model == "tmm") {
                // Same order of stiffness: a membrane's K ~ E t for unit-aspect triangles.
                spec.young_modulus_pa = k / spec.thickness_m;
              } else if (model == "solid") {
                // A solid's K ~ E h with h its cell size (about a fifth of the sphere: 20 mm).
                spec.young_modulus_pa = k / 0.02;
              } else {
                spec.stiffness = k;
              }
              if (model == "flexion") spec.flexion_stiffness = 1e-4 * k;
              json cell = {{"model", model},    {"integrator", integrator}, {"stiffness", k}, {"dt", dt},
                           {"load", load.name}, {"mesh", mesh_kind},        {"guard", guard}};
              std::unique_ptr<Simulation> sim;
              try {
                sim = make_surface_simulation(mesh, fixed, spec);
              } catch (const InputError& e) {
                cell["reason"] = e.what();
                rejected.push_back(cell);
                continue;
              }
              double e_start = 0.0;
              if (load.perturb_m > 0) {
                sim->perturb(load.perturb_m, 1);
                e_start = sim->energy();
              } else if (load.attach) {
                sim->attach(tool, load.value, 30);
              } else {
                sim->pull(tool, load.value);
              }
              int64_t guard_actions = 0;
              bool finite = true;
              double e_late = 0.0, e_end = 0.0;
              int64_t it = 0;
              for (; it < steps; ++it) {
                const StepOut r = sim->step();
                guard_actions += r.guard_acted ? 1 : 0;
                if (!r.finite) {
                  finite = false;
                  break;
                }
                if (it + 1 == 3 * steps / 4) e_late = sim->energy();
              }
              std::vector<double> x;
              sim->positions(x);
              double maxd = 0.0;
              for (size_t q = 0; q < x.size() / 3; ++q) {
                double d2 = 0;
                for (int c = 0; c < 3; ++c)
                  d2 += (x[3 * q + c] - mesh.V[3 * q + c]) * (x[3 * q + c] - mesh.V[3 * q + c]);
                if (!std::isfinite(d2)) finite = false;
                maxd = std::max(maxd, std::sqrt(d2));
              }
              e_end = finite ? sim->energy() : NAN;
              if (!std::isfinite(e_end)) finite = false;
              // Over the last quarter of the run: a load started from rest legitimately raises the energy
              // (polynomially in t: a factor below 2 over that quarter); an instability multiplies it.
              const double drift = finite ? (e_end - e_late) / std::max(std::abs(e_late), 1e-12) : NAN;
              // Unloaded from a perturbed rest no work is done on the model: its energy may only
              // fall, and nothing may move far beyond the perturbation (self-excitation: the
              // NMSM drift of issue 13 moved vertices by millimetres).
              const bool self_excited =
                  load.perturb_m > 0 && finite && (e_end > 1.1 * e_start + 1e-15 || maxd > 100.0 * load.perturb_m);
              std::string outcome;
              if (!finite)
                outcome = "non-finite";
              else if (drift > 10.0 || maxd > 1e3 * diameter || self_excited)
                outcome = "diverged";  // numerical runaway
              else if (guard_actions > 0)
                outcome = "guarded";
              else
                outcome = "stable";
              cell["outcome"] = outcome;
              cell["energy_drift"] = std::isfinite(drift) ? json(drift) : json(nullptr);
              cell["guard_actions"] = guard_actions;
              cell["steps"] = it;
              cell["max_displacement_m"] = std::isfinite(maxd) ? json(maxd) : json(nullptr);
              if (sim->stable_dt() > 0) cell["stable_dt_s"] = sim->stable_dt();
              cells.push_back(cell);
            }
    std::fprintf(stderr, "  mesh %s done (%zu cells)\n", mesh_kind.c_str(), cells.size());
  }
  // Summary counts.
  std::map<std::string, int> off, on;
  for (const auto& c : cells) (c["guard"].get<bool>() ? on : off)[c["outcome"].get<std::string>()] += 1;
  json summary = {{"guard_off", off}, {"guard_on", on}, {"cells", cells.size()}, {"rejected_meshes", rejected.size()}};
  double worst_drift_on = -INFINITY;
  for (const auto& c : cells)
    if (c["guard"].get<bool>() && c["energy_drift"].is_number())
      worst_drift_on = std::max(worst_drift_on, c["energy_drift"].get<double>());
  summary["max_energy_drift_guard_on"] = worst_drift_on;
  // Heat maps: stiffness x dt per model/integrator, worst outcome over loads and meshes.
  const std::vector<std::string> order = {"stable", "guarded", "diverged", "non-finite"};
  svg::Legend legend{order, {"#59a14f", "#edc948", "#f28e2b", "#e15759"}};
  auto rank = [&](const std::string& o) {
    return static_cast<int>(std::find(order.begin(), order.end(), o) - order.begin());
  };
  std::vector<std::string> xl, yl;
  for (double k : stiffness) {
    char b[32];
    std::snprintf(b, sizeof b, "%g", k);
    xl.push_back(b);
  }
  for (double dt : dts) {
    char b[32];
    std::snprintf(b, sizeof b, "%g", dt);
    yl.push_back(b);
  }
  std::vector<std::string> files;
  for (bool guard : {false, true}) {
    std::vector<svg::HeatMap> maps;
    for (const auto& [model, integrator] : combos) {
      svg::HeatMap h;
      h.title = model + " / " + integrator;
      h.xlabels = xl;
      h.ylabels = yl;
      h.cells.assign(xl.size() * yl.size(), -1);
      for (const auto& c : cells) {
        if (c["model"] != model || c["integrator"] != integrator || c["guard"].get<bool>() != guard) continue;
        const size_t ix =
            std::find(stiffness.begin(), stiffness.end(), c["stiffness"].get<double>()) - stiffness.begin();
        const size_t iy = std::find(dts.begin(), dts.end(), c["dt"].get<double>()) - dts.begin();
        int& cell = h.cells[iy * xl.size() + ix];
        cell = std::max(cell, rank(c["outcome"]));
      }
      maps.push_back(h);
    }
    const std::string file = guard ? "stability_guard_on.svg" : "stability_guard_off.svg";
    write_file_atomic(opt.out_dir + "/" + file, svg::render(maps, legend, 3,
                                                            std::string("Stability, guard ") + (guard ? "on" : "off") +
                                                                " (worst outcome over loads and meshes)",
                                                            "spring stiffness k (N/m)", "time step dt (s)"));
    files.push_back(file);
  }
  {
    // Mesh quality x load, worst over stiffness and dt, guard off.
    std::vector<svg::HeatMap> maps;
    std::vector<std::string> ll;
    for (const Load& l : loads) ll.push_back(l.name);
    for (const auto& [model, integrator] : combos) {
      svg::HeatMap h;
      h.title = model + " / " + integrator;
      h.xlabels = meshes;
      h.ylabels = ll;
      h.cells.assign(meshes.size() * ll.size(), -1);
      for (const auto& c : cells) {
        if (c["model"] != model || c["integrator"] != integrator || c["guard"].get<bool>()) continue;
        const size_t ix = std::find(meshes.begin(), meshes.end(), c["mesh"].get<std::string>()) - meshes.begin();
        const size_t iy = std::find(ll.begin(), ll.end(), c["load"].get<std::string>()) - ll.begin();
        int& cell = h.cells[iy * meshes.size() + ix];
        cell = std::max(cell, rank(c["outcome"]));
      }
      maps.push_back(h);
    }
    write_file_atomic(
        opt.out_dir + "/stability_mesh_load_guard_off.svg",
        svg::render(maps, legend, 3, "Stability by mesh quality and load, guard off (worst over k and dt)", "mesh",
                    "load"));
    files.push_back("stability_mesh_load_guard_off.svg");
  }
  json result = {{"command", "bench stability"},
                 {"grid", full   ? "full"
                          : tiny ? "tiny"
                                 : "quick"},
                 {"organ", "icosphere 162 vertices / 320 faces, radius 50 mm, density 1060 kg/m^3, y < -40 mm held"},
                 {"steps_per_cell", steps},
                 {"summary", summary},
                 {"cells", cells},
                 {"rejected", rejected},
                 {"plots", files}};
  result["seconds"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return result;
}

}  // namespace softatlas::evidence
