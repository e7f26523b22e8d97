// Markdown tables from results.json (docs/results.md is assembled from these): the numbers in the
// docs come from the runs, never typed by hand.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <sstream>

#include "softatlas/evidence/evidence.hpp"

namespace softatlas::evidence {

using nlohmann::json;

namespace {

std::string f(double v, int digits = 3) {
  if (!std::isfinite(v)) return "n/a";
  char b[64];
  std::snprintf(b, sizeof b, "%.*g", digits, v);
  return b;
}
std::string fx(double v, int decimals = 2) {
  if (!std::isfinite(v)) return "n/a";
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", decimals, v);
  return b;
}
double num(const json& j) { return j.is_number() ? j.get<double>() : NAN; }
// A field that only some runs have (attachment loads): blank when absent.
std::string opt_num(const json& run, const char* key, int decimals) {
  return run.contains(key) ? fx(num(run[key]), decimals) : "";
}

}  // namespace

std::string integrator_label(const json& run) {
  std::string label = run["integrator"].get<std::string>();
  const double dt = run.contains("dt_s") ? num(run["dt_s"]) : 1e-3;
  if (dt > 0 && std::abs(dt - 1e-3) > 1e-12) label += ", dt " + f(1e3 * dt) + " ms";
  return label;
}

std::string accuracy_markdown(const json& r) {
  std::ostringstream o;
  o << "### FEM verification (closed forms)\n\n| case | quantity | analytic | computed | relative error | tets "
       "|\n|---|---|---|---|---|---|\n";
  for (const auto& v : r["fem_verification"])
    o << "| " << v["case"].get<std::string>() << " | " << v.value("quantity", "") << " | " << f(num(v["analytic"]), 5)
      << " | " << f(num(v["computed"]), 5) << " | " << f(num(v["rel_error"]), 3) << " | " << v.value("tets", 0)
      << " |\n";
  if (r.contains("reference")) {
    const auto& ref = r["reference"];
    o << "\nReference: " << ref["model"].get<std::string>() << ", " << ref["nodes"] << " nodes, " << ref["tets"]
      << " tetrahedra (CGAL Mesh_3, cell " << f(num(ref["cell_size_m"])) << " m"
      << (ref.contains("tool_refinement") ? "; " + ref["tool_refinement"].get<std::string>() : std::string())
      << "), E = " << f(num(ref["young_modulus_pa"])) << " Pa, nu = " << f(num(ref["poisson_ratio"]))
      << ".\n\n| load | Newton iterations | converged | relative residual | seconds | reaction on tool (N) | grasp "
         "stiffness (N/m) |\n|---|---|---|---|---|---|---|\n";
    for (const auto& s : ref["solutions"])
      o << "| " << s["load"].get<std::string>() << " | " << s["newton_iterations"] << " | "
        << (s["converged"].get<bool>() ? "yes" : "no") << " | " << f(num(s["relative_residual"]), 2) << " | "
        << fx(num(s["seconds"]), 2) << " | [" << f(num(s["reaction_N"][0])) << ", " << f(num(s["reaction_N"][1]))
        << ", " << f(num(s["reaction_N"][2])) << "] | "
        << (s.contains("grasp_stiffness_N_per_m") ? f(num(s["grasp_stiffness_N_per_m"])) : "") << " |\n";
    if (ref.contains("refinement")) {
      const auto& rf = ref["refinement"];
      o << "\nMesh convergence of the reference: load " << rf["load"].get<std::string>() << " solved again with cell "
        << f(num(rf["cell_size_m"])) << " m (" << rf["tets"] << " tetrahedra, " << rf["nodes"]
        << " nodes, converged: " << (rf["converged"].get<bool>() ? "yes" : "no") << "): the liver's surface moves by "
        << fx(num(rf["rms_change_mm"]), 3) << " mm RMS (" << fx(num(rf["max_change_mm"]), 3)
        << " mm max), the reaction by " << fx(num(rf["reaction_change_pct"]), 2) << " %.\n";
    }
  }
  // Final runs per model/integrator/load at the largest and smallest face counts.
  std::set<int> faces;
  for (const auto& run : r["runs"])
    if (run["model"] != "fem") faces.insert(run["faces"].get<int>());
  std::set<std::string> loads;
  for (const auto& run : r["runs"]) loads.insert(run["load"].get<std::string>());
  o << "\n### Final state of every run (after the stopping rule or the step budget)\n\n";
  for (const std::string& load : loads) {
    o << "\n**Load " << load
      << "**\n\n| model | integrator | faces | iterations | ms/step | RMS err (mm) | max err (mm) | volume (%) | tool "
         "force vs ref (%) | grasp stiffness / ref | restoration x̄ / s (mm) "
         "|\n|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (const auto& run : r["runs"]) {
      if (run["load"] != load || !run.value("final", false)) continue;
      if (run["model"] != "fem" && run["faces"].get<int>() != *faces.begin() &&
          run["faces"].get<int>() != *faces.rbegin())
        continue;
      std::string rest = run.contains("restoration_mean_mm")
                             ? fx(num(run["restoration_mean_mm"]), 2) + " / " + fx(num(run["restoration_sd_mm"]), 2)
                             : "";
      o << "| " << run["model"].get<std::string>() << " | " << integrator_label(run) << " | " << run["faces"] << " | "
        << run["iterations"] << (run.value("converged", false) ? " (rest)" : "") << " | " << f(num(run["ms_per_step"]))
        << " | " << fx(num(run["rms_error_mm"])) << " | " << fx(num(run["max_error_mm"])) << " | "
        << fx(num(run["volume_change_pct"])) << " | " << opt_num(run, "force_error_pct", 1) << " | "
        << opt_num(run, "grasp_stiffness_ratio", 3) << " | " << rest << " |\n";
    }
  }
  // Pareto front of the main load.
  o << "\n### Pareto front (RMS error against ms per step), per load\n\n| load | model | integrator | faces | "
       "iterations | ms/step | RMS err (mm) |\n|---|---|---|---|---|---|---|\n";
  for (const std::string& load : loads)
    for (const auto& run : r["runs"])
      if (run["load"] == load && run.value("pareto", false))
        o << "| " << load << " | " << run["model"].get<std::string>() << " | " << integrator_label(run) << " | "
          << run["faces"] << " | " << run["iterations"] << " | " << f(num(run["ms_per_step"])) << " | "
          << fx(num(run["rms_error_mm"])) << " |\n";
  // Recommendation: from the runs, per use. The budget is CPU time per simulated time (a 1 ms
  // step in 0.5 ms and an 8 ms step in 4 ms both run at 2x real time).
  struct Use {
    std::string name;
    double cpu_per_sim;  // largest ms_per_step / (dt in ms)
  };
  o << "\n### Recommendation (computed from the runs: the lowest mean RMS error over the loads among settings within "
       "the budget)\n\n"
       "| use | CPU time per simulated time | model | integrator | faces | mean RMS err (mm) | mean abs. volume change "
       "(%) | mean grasp stiffness error (%) | ms/step | CPU / simulated "
       "|\n|---|---|---|---|---|---|---|---|---|---|\n";
  for (const Use& use : {Use{"a scene of several organs at 2x real time", 0.125}, Use{"one organ at 2x real time", 0.5},
                         Use{"accuracy (no budget)", INFINITY}}) {
    std::map<std::string, std::vector<const json*>> groups;
    for (const auto& run : r["runs"]) {
      if (!run.value("final", false) || !run.value("finite", true)) continue;
      const std::string key =
          run["model"].get<std::string>() + "|" + integrator_label(run) + "|" + std::to_string(run["faces"].get<int>());
      groups[key].push_back(&run);
    }
    std::string best;
    double best_err = INFINITY, vol = 0, force = 0, ms = 0, ratio = 0;
    for (const auto& [key, rs] : groups) {
      double e = 0, v = 0, fe = 0, t = 0, c = 0;
      int nfe = 0;
      for (const json* p : rs) {
        e += num((*p)["rms_error_mm"]);
        v += std::abs(num((*p)["volume_change_pct"]));
        if (p->contains("grasp_stiffness_ratio"))
          fe += 100.0 * std::abs(num((*p)["grasp_stiffness_ratio"]) - 1.0), ++nfe;
        t = std::max(t, num((*p)["ms_per_step"]));
        const double dt_ms = 1e3 * num((*p)["dt_s"]);
        c = std::max(c, dt_ms > 0 ? num((*p)["ms_per_step"]) / dt_ms : INFINITY);  // static solves: no time
      }
      e /= rs.size(), v /= rs.size(), fe = nfe ? fe / nfe : NAN;
      if (rs.size() < loads.size() / 2 || c > use.cpu_per_sim || !(e < best_err)) continue;
      best = key, best_err = e, vol = v, force = fe, ms = t, ratio = c;
    }
    const std::string budget = std::isfinite(use.cpu_per_sim) ? "<= " + f(use.cpu_per_sim) : "none";
    if (best.empty()) {
      o << "| " << use.name << " | " << budget << " | none fits | | | | | | | |\n";
      continue;
    }
    const size_t a = best.find('|'), b = best.find('|', a + 1);
    o << "| " << use.name << " | " << budget << " | " << best.substr(0, a) << " | " << best.substr(a + 1, b - a - 1)
      << " | " << best.substr(b + 1) << " | " << fx(best_err) << " | " << fx(vol) << " | " << fx(force, 1) << " | "
      << f(ms) << " | " << (std::isfinite(ratio) ? f(ratio) : "static") << " |\n";
  }
  if (r.contains("fitting")) {
    const auto& fit = r["fitting"];
    std::string fractions;
    for (const auto& v : fit["training_path_fractions"])
      fractions += (fractions.empty() ? "" : ", ") + f(v.get<double>());
    o << "\n### Parameter fitting (trained on " << fit["training_load"].get<std::string>()
      << "'s quasi-static path, at " << fractions << " of the load, " << fit["faces"] << " faces, "
      << fit["budget_evaluations"] << " evaluations per optimiser)\n\nEvery comparison at rest ("
      << fit["rest_rule"].get<std::string>() << "). \"path\": the training objective, the RMS over the path points "
      << "(fitted | paper parameters); the load rows test at rest.\n\n| model | PSO best (mm) | Nelder-Mead best (mm) "
         "| better | parameters | path (mm) | load | RMS fitted (mm) | RMS paper parameters (mm) "
         "|\n|---|---|---|---|---|---|---|---|---|\n";
    for (const auto& m : fit["models"]) {
      std::string ps;
      for (auto it = m["parameters"].begin(); it != m["parameters"].end(); ++it)
        ps += it.key() + " = " + f(it.value().get<double>()) +
              (m["parameters_at_bound"].value(it.key(), false) ? " (at bound)" : "") + "; ";
      const std::string path = fx(num(m[m["better"].get<std::string>() + "_best_rms_mm"])) + " \\| " +
                               fx(num(m["paper_path_rms_mm"])) + ", " +
                               std::to_string(m["training_runs_stopped_by_cap"].get<int64_t>()) + " of " +
                               std::to_string(2 * fit["budget_evaluations"].get<int64_t>() *
                                              static_cast<int64_t>(fit["training_path_fractions"].size())) +
                               " training runs stopped by the cap";
      bool first = true;
      for (const auto& t : m["test"]) {
        o << "| " << (first ? m["model"].get<std::string>() : "") << " | "
          << (first ? fx(num(m["pso_best_rms_mm"])) : "") << " | "
          << (first ? fx(num(m["nelder_mead_best_rms_mm"])) : "") << " | "
          << (first ? m["better"].get<std::string>() : "") << " | " << (first ? ps : "") << " | " << (first ? path : "")
          << " | " << t["load"].get<std::string>() << (t["training"].get<bool>() ? " (training)" : "") << " | "
          << fx(num(t["rms_error_mm_fitted"])) << " | " << fx(num(t["rms_error_mm_paper_parameters"])) << " |\n";
        first = false;
      }
    }
  }
  if (r.contains("paper_tables")) {
    const auto& pt = r["paper_tables"];
    const auto& t1 = pt["table_1"];
    o << "\n### Paper 000 Table I (forces x 1e-3 N on the top of the 1000-face liver, Verlet, run to rest)\n\n"
         "| model | force | volume change % (paper) | volume change % (ours) | CPU s (paper) | CPU s (ours) | time "
         "ratio ours/paper | feedback (paper) | feedback (ours) | iterations (ours) "
         "|\n|---|---|---|---|---|---|---|---|---|---|\n";
    const char* fl[3] = {"[1 0 0]", "[1 1 0]", "[1 1 1]"};
    for (const std::string m : {"tmsm", "cmsm", "nmsm"})
      for (int i = 0; i < 3; ++i) {
        const auto& p = t1["paper"][m];
        const auto& u = t1["ours"][m];
        auto vec = [&](const json& v) { return "[" + fx(num(v[0])) + " " + fx(num(v[1])) + " " + fx(num(v[2])) + "]"; };
        o << "| " << m << " | " << fl[i] << " | " << fx(num(p["volume_change_pct"][i])) << " | "
          << fx(num(u["volume_change_pct"][i])) << " | " << fx(num(p["cpu_time_s"][i]), 3) << " | "
          << fx(num(u["cpu_time_s"][i]), 3) << " | " << fx(num(u["cpu_time_s"][i]) / num(p["cpu_time_s"][i]), 2)
          << " | " << vec(p["feedback"][i]) << " | " << vec(u["feedback"][i]) << " | " << u["iterations"][i]
          << (u["converged"][i].get<bool>() ? " (rest)" : " (cap)") << " |\n";
      }
    const auto& t2 = pt["table_2"];
    o << "\n### Paper 000 Table II (one face moved in 30 Verlet iterations)\n\n| case | model | VC % (paper) | VC % "
         "(ours) | time s (paper) | time s (ours) | ratio ours/paper |\n|---|---|---|---|---|---|---|\n";
    for (const std::string c : {"small_1000", "small_2000", "large_1000", "large_2000"})
      for (int i = 0; i < 3; ++i) {
        const char* names[3] = {"tmsm", "cmsm", "nmsm"};
        const double pt_ = num(t2["paper"][c]["time_s"][i]), ot = num(t2["ours"][c]["time_s"][i]);
        o << "| " << c << " | " << names[i] << " | " << fx(num(t2["paper"][c]["vc_pct"][i])) << " | "
          << fx(num(t2["ours"][c]["vc_pct"][i])) << " | " << fx(pt_, 3) << " | " << f(ot) << " | " << fx(ot / pt_, 2)
          << " |\n";
      }
    const auto& t3 = pt["table_3"];
    o << "\n### Paper 000 Table III (NMSM vs CMSM, 30 Verlet iterations of a [0, 20, 20] mm attachment)\n\n| faces | b "
         "| NMSM VC % (paper / ours) | CMSM VC % (paper / ours) | NMSM s (paper / ours) | CMSM s (paper / ours) | NMSM "
         "time ratio | CMSM time ratio |\n|---|---|---|---|---|---|---|---|\n";
    for (size_t i = 0; i < t3["ours"]["faces"].size(); ++i) {
      const double nf = num(t3["ours"]["faces"][i]);
      size_t j = 0;
      while (j < t3["paper"]["faces"].size() && num(t3["paper"]["faces"][j]) != nf) ++j;
      if (j == t3["paper"]["faces"].size()) continue;
      o << "| " << f(nf) << " | " << f(num(t3["ours"]["b"][i])) << " | " << fx(num(t3["paper"]["nmsm_vc_pct"][j]))
        << " / " << fx(num(t3["ours"]["nmsm_vc_pct"][i])) << " | " << fx(num(t3["paper"]["cmsm_vc_pct"][j])) << " / "
        << fx(num(t3["ours"]["cmsm_vc_pct"][i])) << " | " << fx(num(t3["paper"]["nmsm_time_s"][j]), 3) << " / "
        << f(num(t3["ours"]["nmsm_time_s"][i])) << " | " << fx(num(t3["paper"]["cmsm_time_s"][j]), 3) << " / "
        << f(num(t3["ours"]["cmsm_time_s"][i])) << " | "
        << fx(num(t3["ours"]["nmsm_time_s"][i]) / num(t3["paper"]["nmsm_time_s"][j]), 2) << " | "
        << fx(num(t3["ours"]["cmsm_time_s"][i]) / num(t3["paper"]["cmsm_time_s"][j]), 2) << " |\n";
    }
    const auto& sp = pt["sphere"];
    o << "\n### Sphere test (paper 000 Figs 3-4 settings)\n\nTMSM volume change at f = [0, 4, 4]: "
      << fx(num(sp["tmsm_volume_change_pct_at_f4"]))
      << " %.\n\n| a | b | NMSM volume change % at f = [0, 4, 4] | iterations | at rest |\n|---|---|---|---|---|\n";
    for (const auto& v : sp["volume_vs_a"])
      o << "| " << f(num(v["a"])) << " | " << f(num(v["b"])) << " | " << fx(num(v["volume_change_pct"])) << " | "
        << v["iterations"] << " | " << (v["converged"].get<bool>() ? "yes" : "no") << " |\n";
    o << "\n| model | a | b | force | mean displacement | at rest |\n|---|---|---|---|---|---|\n";
    for (const auto& v : sp["force_displacement"])
      o << "| " << v["model"].get<std::string>() << " | " << f(num(v["a"])) << " | " << f(num(v["b"])) << " | [0 "
        << v["force"][1] << " " << v["force"][2] << "] | " << fx(num(v["mean_displacement"]), 3) << " | "
        << (v["converged"].get<bool>() ? "yes" : "no") << " |\n";
  }
  return o.str();
}

std::string stability_markdown(const json& r) {
  std::ostringstream o;
  const auto& s = r["summary"];
  o << "Cells: " << s["cells"] << " (plus " << s["rejected_meshes"]
    << " rejected by the model compiler, listed under `rejected`). "
    << "Steps per cell: " << r["steps_per_cell"]
    << ". Largest energy drift with the guard on: " << f(num(s["max_energy_drift_guard_on"])) << ".\n\n";
  std::map<std::string, std::map<std::string, int>> counts;
  std::set<std::string> keys;
  for (const auto& c : r["cells"]) {
    const std::string k = c["model"].get<std::string>() + " / " + c["integrator"].get<std::string>();
    keys.insert(k);
    counts[k + (c["guard"].get<bool>() ? " on" : " off")][c["outcome"].get<std::string>()] += 1;
  }
  o << "| model / integrator | guard | stable | guarded | diverged | non-finite |\n|---|---|---|---|---|---|\n";
  for (const auto& k : keys)
    for (const std::string g : {"off", "on"}) {
      auto& m = counts[k + " " + g];
      o << "| " << k << " | " << g << " | " << m["stable"] << " | " << m["guarded"] << " | " << m["diverged"] << " | "
        << m["non-finite"] << " |\n";
    }
  return o.str();
}

}  // namespace softatlas::evidence
