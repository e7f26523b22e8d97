// `softatlas bench contact SET [--push-mm 20] [--organ NAME] [--compare] --json`: pushes each
// simulated organ toward its nearest neighbour and measures how deep any vertex of one organ gets
// inside another (sim/contact.hpp, docs/physics.md "Contact").
//
// Per organ (every organ that moves, or --organ): the nearest other organ N at rest (closest
// vertex pair); a patch of the organ's free vertices within 10 mm of its vertex closest to N is
// held and moved --push-mm toward N (along the line between the closest vertices, or along the
// organ's outward normal there when they are closer than 2 mm, i.e. touching) over 0.5 s, then
// held 0.5 s. Every 5 steps the deepest vertex inside another organ is measured (nearest face at
// any distance; vertices inside another organ at rest are left out). ms_per_step is the wall
// time of step() alone. --compare runs the same pushes without contact as a baseline.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>

#include "softatlas/bench/cli.hpp"
#include "softatlas/io/cli.hpp"
#include "softatlas/io/organ_set.hpp"
#include "softatlas/io/scene.hpp"
#include "softatlas/sim/sim.hpp"

namespace softatlas::bench {

namespace {

struct ContactArgs {
  std::string set_dir, organ;
  double push_mm = 20.0;
  int threads = 1;
  bool json_out = false, compare = false;
};

struct Push {
  int32_t organ = -1, neighbour = -1;
  std::vector<int32_t> patch;
  double dir[3] = {0, 0, 0};
  double gap_mm = 0.0;
};

// Nearest other organ at rest, the patch to hold and the direction to push.
Push plan_push(const sim::Model& m, int32_t organ) {
  Push p;
  p.organ = organ;
  const sim::OrganRange& r = m.organs[organ];
  auto rest = [&](int32_t v, int k) {
    return k == 0 ? m.vert_rest_x[v] : k == 1 ? m.vert_rest_y[v] : m.vert_rest_z[v];
  };
  double best2 = INFINITY;
  int32_t va = -1, vb = -1;
  for (size_t o = 0; o < m.organs.size(); ++o) {
    if (static_cast<int32_t>(o) == organ) continue;
    const sim::OrganRange& q = m.organs[o];
    for (int32_t a = r.vert_begin; a < r.vert_end; ++a) {
      if (m.vert_inv_mass[a] == 0) continue;
      for (int32_t b = q.vert_begin; b < q.vert_end; ++b) {
        double d2 = 0;
        for (int k = 0; k < 3; ++k) d2 += (rest(a, k) - rest(b, k)) * (rest(a, k) - rest(b, k));
        if (d2 < best2) best2 = d2, va = a, vb = b, p.neighbour = static_cast<int32_t>(o);
      }
    }
  }
  if (va < 0) return p;
  p.gap_mm = 1e3 * std::sqrt(best2);
  double d[3];
  if (p.gap_mm > 2.0) {
    for (int k = 0; k < 3; ++k) d[k] = rest(vb, k) - rest(va, k);
  } else {  // touching: the organ's outward normal at va (area-weighted over its faces)
    d[0] = d[1] = d[2] = 0;
    const double sg = r.rest_volume_m3 < 0 ? -1.0 : 1.0;
    for (int32_t f = r.face_begin; f < r.face_end; ++f) {
      const int32_t* fv = &m.face_vert[3 * f];
      if (fv[0] != va && fv[1] != va && fv[2] != va) continue;
      double e1[3], e2[3];
      for (int k = 0; k < 3; ++k) e1[k] = rest(fv[1], k) - rest(fv[0], k), e2[k] = rest(fv[2], k) - rest(fv[0], k);
      d[0] += sg * (e1[1] * e2[2] - e1[2] * e2[1]);
      d[1] += sg * (e1[2] * e2[0] - e1[0] * e2[2]);
      d[2] += sg * (e1[0] * e2[1] - e1[1] * e2[0]);
    }
  }
  const double n = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  if (!(n > 0)) return p;
  for (int k = 0; k < 3; ++k) p.dir[k] = d[k] / n;
  for (int32_t v = r.vert_begin; v < r.vert_end; ++v) {
    if (m.vert_inv_mass[v] == 0) continue;
    double d2 = 0;
    for (int k = 0; k < 3; ++k) d2 += (rest(v, k) - rest(va, k)) * (rest(v, k) - rest(va, k));
    if (d2 <= 1e-4) p.patch.push_back(v);  // within 10 mm
  }
  return p;
}

struct PushResult {
  double max_penetration_m = 0.0, ms_per_step = 0.0;
  int32_t deepest_organ = -1, into_organ = -1;
  int max_contacts = 0;
  bool finite = true;
};

// measure: the model whose contact data (rest exemptions) the measurement uses.
PushResult run_push(const sim::Model& m, const sim::Model& measure, const Push& p, double push_m) {
  sim::State s = sim::make_state(m);
  sim::Work w = sim::make_work(m);
  const int32_t n_push = std::max<int32_t>(1, static_cast<int32_t>(std::lround(0.5 / m.dt_s)));
  const int32_t n_total = 2 * n_push;
  sim::attach(m, s, p.patch, {push_m * p.dir[0], push_m * p.dir[1], push_m * p.dir[2]}, n_push);
  PushResult out;
  double wall = 0.0;
  for (int32_t i = 1; i <= n_total; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    const sim::StepReport rep = sim::step(m, s, w);
    wall += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    out.max_contacts = std::max(out.max_contacts, rep.contacts);
    if (i % 5 != 0 && i != n_total) continue;
    for (double x : s.x) out.finite = out.finite && std::isfinite(x);
    if (!out.finite) break;
    int32_t v = -1, into = -1;
    const double d = sim::max_penetration(measure, s, &v, &into);
    if (d > out.max_penetration_m) {
      out.max_penetration_m = d;
      out.deepest_organ = v >= 0 ? m.vert_organ[v] : -1;
      out.into_organ = into;
    }
  }
  out.ms_per_step = 1e3 * wall / n_total;
  return out;
}

int bench_contact(const ContactArgs& a) {
  sim::SceneDesc scene = io::scene_from_organ_set(io::read_organ_set(a.set_dir), io::SceneOptions{});
  scene.threads = a.threads;
  scene.contact = true;
  const sim::Model m = sim::compile(scene);
  if (!m.contact.on) throw InputError(a.set_dir, "contact needs at least two simulated organs");
  sim::Model off;
  if (a.compare) {
    scene.contact = false;
    off = sim::compile(scene);
  }
  std::vector<int32_t> organs;
  if (!a.organ.empty()) {
    const int32_t o = sim::find_organ(m, a.organ);
    if (o < 0) throw InputError("--organ", "organ '" + a.organ + "' is not simulated in this scene");
    organs.push_back(o);
  } else {
    for (size_t o = 0; o < m.organs.size(); ++o)
      if (m.organs[o].model != sim::ModelKind::rigid) organs.push_back(static_cast<int32_t>(o));
  }
  nlohmann::json rows = nlohmann::json::array();
  double worst = 0.0, worst_off = 0.0, ms_sum = 0.0, ms_max = 0.0;
  bool finite = true;
  int k = 0;
  const auto t0 = std::chrono::steady_clock::now();
  for (int32_t o : organs) {
    ++k;
    const Push p = plan_push(m, o);
    if (p.patch.empty() || p.neighbour < 0) continue;
    const PushResult r = run_push(m, m, p, a.push_mm * 1e-3);
    nlohmann::json row = {{"organ", m.organs[o].name},
                          {"neighbour", m.organs[p.neighbour].name},
                          {"gap_mm", p.gap_mm},
                          {"held_vertices", p.patch.size()},
                          {"max_penetration_mm", 1e3 * r.max_penetration_m},
                          {"deepest", r.deepest_organ >= 0 ? m.organs[r.deepest_organ].name : ""},
                          {"into", r.into_organ >= 0 ? m.organs[r.into_organ].name : ""},
                          {"max_contacts", r.max_contacts},
                          {"ms_per_step", r.ms_per_step},
                          {"finite", r.finite}};
    if (a.compare) {
      const PushResult b = run_push(off, m, p, a.push_mm * 1e-3);
      row["max_penetration_mm_without_contact"] = 1e3 * b.max_penetration_m;
      row["ms_per_step_without_contact"] = b.ms_per_step;
      worst_off = std::max(worst_off, b.max_penetration_m);
    }
    rows.push_back(row);
    worst = std::max(worst, r.max_penetration_m);
    ms_sum += r.ms_per_step, ms_max = std::max(ms_max, r.ms_per_step);
    finite = finite && r.finite;
    const double el = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::fprintf(stderr, "bench contact: %d of %zu (%s toward %s): %.2f mm, %.2f ms/step; ETA %.0f s\n", k,
                 organs.size(), m.organs[o].name.c_str(), m.organs[p.neighbour].name.c_str(), 1e3 * r.max_penetration_m,
                 r.ms_per_step, el / k * (organs.size() - k));
  }
  nlohmann::json j = {{"set", a.set_dir},
                      {"push_mm", a.push_mm},
                      {"dt_s", m.dt_s},
                      {"max_penetration_mm", 1e3 * worst},
                      {"ms_per_step", rows.empty() ? 0.0 : ms_sum / rows.size()},
                      {"ms_per_step_max", ms_max},
                      {"finite", finite},
                      {"organs", rows}};
  if (a.compare) j["max_penetration_mm_without_contact"] = 1e3 * worst_off;
  if (a.json_out) {
    std::printf("%s\n", j.dump().c_str());
  } else {
    for (const auto& r : rows)
      std::printf("%-24s -> %-24s %6.2f mm  %5.2f ms/step\n", r["organ"].get<std::string>().c_str(),
                  r["neighbour"].get<std::string>().c_str(), r["max_penetration_mm"].get<double>(),
                  r["ms_per_step"].get<double>());
    std::printf("max_penetration_mm %.2f, ms_per_step %.2f\n", 1e3 * worst, j["ms_per_step"].get<double>());
  }
  return finite ? 0 : 3;
}

}  // namespace

void add_bench_contact(CLI::App& bench, cli::Status* status) {
  CLI::App* app = bench.add_subcommand("contact", "push each organ toward its nearest neighbour, deepest penetration");
  auto a = std::make_shared<ContactArgs>();
  app->add_option("set", a->set_dir, "organ-set folder")->required();
  app->add_option("--organ", a->organ, "push only this organ");
  app->add_option("--push-mm", a->push_mm, "push distance (mm)")->check(CLI::Range(0.0, 200.0));
  app->add_option("--threads", a->threads, "worker threads")->check(CLI::Range(1, 64));
  app->add_flag("--compare", a->compare, "also run every push without contact (baseline)");
  app->add_flag("--json", a->json_out, "print one JSON object");
  cli::on_run(app, status, [a] { return bench_contact(*a); });
}

}  // namespace softatlas::bench
