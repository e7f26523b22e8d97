// `softatlas bench restore SET --organ NAME [--pull-mm 30] [--model M] --json`: the rest-drift,
// pull-and-release protocol of bench/include/softatlas/bench/restore.hpp on one organ of an organ
// set (paper 003 Table 1's restoration metrics are the anchor; docs/physics.md has the results).
#include "softatlas/bench/restore.hpp"

#include <CLI/CLI.hpp>
#include <Eigen/Dense>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>

#include "softatlas/bench/cli.hpp"
#include "softatlas/io/cli.hpp"
#include "softatlas/io/organ_set.hpp"
#include "softatlas/io/scene.hpp"

namespace softatlas::bench {

double rigid_residual(const sim::Model& m, const sim::State& s, int32_t organ) {
  const sim::OrganRange& r = m.organs[organ];
  const int32_t n = r.vert_end - r.vert_begin;
  if (n <= 0) return 0.0;
  Eigen::Vector3d pc = Eigen::Vector3d::Zero(), qc = Eigen::Vector3d::Zero();
  for (int32_t v = r.vert_begin; v < r.vert_end; ++v) {
    pc += Eigen::Vector3d(s.x[v], s.y[v], s.z[v]);
    qc += Eigen::Vector3d(m.vert_rest_x[v], m.vert_rest_y[v], m.vert_rest_z[v]);
  }
  pc /= n, qc /= n;
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();  // sum (p - pc)(q - qc)^T
  for (int32_t v = r.vert_begin; v < r.vert_end; ++v)
    H += (Eigen::Vector3d(s.x[v], s.y[v], s.z[v]) - pc) *
         (Eigen::Vector3d(m.vert_rest_x[v], m.vert_rest_y[v], m.vert_rest_z[v]) - qc).transpose();
  // Kabsch: R = V diag(1, 1, det(V U^T)) U^T maps the current shape onto the rest shape.
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  D(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1.0 : 1.0;
  const Eigen::Matrix3d R = svd.matrixV() * D * svd.matrixU().transpose();
  double worst2 = 0.0;
  for (int32_t v = r.vert_begin; v < r.vert_end; ++v) {
    const Eigen::Vector3d p = R * (Eigen::Vector3d(s.x[v], s.y[v], s.z[v]) - pc) + qc;
    worst2 =
        std::max(worst2, (p - Eigen::Vector3d(m.vert_rest_x[v], m.vert_rest_y[v], m.vert_rest_z[v])).squaredNorm());
  }
  return std::sqrt(worst2);
}

namespace {

// Largest displacement (m) of an organ's vertices from rest.
double organ_displacement(const sim::Model& m, const sim::State& s, int32_t organ) {
  const sim::OrganRange& r = m.organs[organ];
  double d2 = 0.0;
  for (int32_t v = r.vert_begin; v < r.vert_end; ++v) {
    const double dx = s.x[v] - m.vert_rest_x[v], dy = s.y[v] - m.vert_rest_y[v], dz = s.z[v] - m.vert_rest_z[v];
    d2 = std::max(d2, dx * dx + dy * dy + dz * dz);
  }
  return std::sqrt(d2);
}

bool organ_finite(const sim::Model& m, const sim::State& s, int32_t organ) {
  const sim::OrganRange& r = m.organs[organ];
  for (int32_t v = r.vert_begin; v < r.vert_end; ++v)
    if (!std::isfinite(s.x[v]) || !std::isfinite(s.y[v]) || !std::isfinite(s.z[v])) return false;
  return true;
}

// The anterior-inferior region (RAS: anterior +y, inferior -z): free vertices within 5 % of the
// organ's bounding-box diagonal of its extreme vertex along (0, 1, -1).
std::vector<int32_t> anterior_inferior_region(const sim::Model& m, int32_t organ) {
  const sim::OrganRange& r = m.organs[organ];
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  int32_t best = -1;
  double best_score = -1e300;
  for (int32_t v = r.vert_begin; v < r.vert_end; ++v) {
    const double p[3] = {m.vert_rest_x[v], m.vert_rest_y[v], m.vert_rest_z[v]};
    for (int c = 0; c < 3; ++c) lo[c] = std::min(lo[c], p[c]), hi[c] = std::max(hi[c], p[c]);
    const double score = p[1] - p[2];
    if (m.vert_inv_mass[v] > 0 && score > best_score) best_score = score, best = v;
  }
  std::vector<int32_t> verts;
  if (best < 0) return verts;
  const double diag = std::sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                                (hi[2] - lo[2]) * (hi[2] - lo[2]));
  const double radius2 = 0.05 * diag * 0.05 * diag;
  for (int32_t v = r.vert_begin; v < r.vert_end; ++v) {
    const double dx = m.vert_rest_x[v] - m.vert_rest_x[best], dy = m.vert_rest_y[v] - m.vert_rest_y[best],
                 dz = m.vert_rest_z[v] - m.vert_rest_z[best];
    if (m.vert_inv_mass[v] > 0 && dx * dx + dy * dy + dz * dz <= radius2) verts.push_back(v);
  }
  return verts;
}

}  // namespace

RestoreResult run_restore(const sim::SceneDesc& scene, const std::string& organ_name, const RestoreOptions& opt) {
  const sim::Model m = sim::compile(scene);
  const int32_t organ = sim::find_organ(m, organ_name);
  if (organ < 0) throw InputError("--organ", "organ '" + organ_name + "' is not simulated in this scene");
  const std::vector<int32_t> grasp = anterior_inferior_region(m, organ);
  if (grasp.empty()) throw InputError("--organ", "organ '" + organ_name + "' has no free vertex to grasp");
  sim::State s = sim::make_state(m);
  sim::Work w = sim::make_work(m);
  const sim::OrganRange& r = m.organs[organ];

  RestoreResult out;
  out.organ = organ_name;
  out.model = sim::to_string(r.model);
  out.integrator = sim::to_string(m.guard ? m.effective_integrator : m.integrator);
  out.dt_s = m.dt_s;
  out.grasped_vertices = static_cast<int>(grasp.size());

  sim::perturb(m, s, opt.perturb_m, opt.seed);  // rest plus a random perturbation

  const double rest_volume = m.organs[organ].rest_volume_m3;
  auto steps_for = [&](double seconds) { return static_cast<int64_t>(std::llround(seconds / m.dt_s)); };
  const int64_t n_rest = steps_for(opt.rest_s), n_pull = std::max<int64_t>(1, steps_for(opt.pull_s)),
                n_hold = steps_for(opt.hold_s), n_after = steps_for(opt.after_s);
  const int64_t n_total = n_rest + n_pull + n_hold + n_after;
  const int64_t n_residual = steps_for(opt.residual_at_s);
  int64_t k = 0;
  int64_t next_progress = steps_for(1.0);
  const auto t0 = std::chrono::steady_clock::now();
  auto advance = [&](const char* phase) {
    sim::step(m, s, w);
    ++k;
    if (!organ_finite(m, s, organ)) {
      out.finite = false;
      return false;
    }
    const double vol = sim::organ_volume(m, s, organ);
    const double pct = rest_volume != 0 ? 100.0 * (vol - rest_volume) / rest_volume : 0.0;
    if (std::abs(pct) > std::abs(out.volume_change_pct)) out.volume_change_pct = pct;
    if (opt.progress && k >= next_progress) {
      const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      std::fprintf(stderr, "bench restore: %s, %s, t = %.1f / %.1f s simulated (%.1f s wall)\n", organ_name.c_str(),
                   phase, k * m.dt_s, n_total * m.dt_s, wall);
      next_progress += steps_for(1.0);
    }
    return true;
  };
  bool ok = true;
  for (int64_t i = 0; i < n_rest && ok; ++i) {
    ok = advance("rest");
    if (ok) out.rest_drift_mm = std::max(out.rest_drift_mm, 1e3 * organ_displacement(m, s, organ));
  }
  // Pull along the region's outward direction, anterior-inferior.
  const double dir[3] = {0.0, std::sqrt(0.5), -std::sqrt(0.5)};
  if (ok)
    sim::attach(m, s, grasp, {opt.pull_m * dir[0], opt.pull_m * dir[1], opt.pull_m * dir[2]}, static_cast<int>(n_pull));
  for (int64_t i = 0; i < n_pull + n_hold && ok; ++i) ok = advance("pull");
  if (ok) {
    double c[3] = {0, 0, 0};
    for (int32_t v : grasp)
      c[0] += s.x[v] - m.vert_rest_x[v], c[1] += s.y[v] - m.vert_rest_y[v], c[2] += s.z[v] - m.vert_rest_z[v];
    out.pull_reached_mm = 1e3 * std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]) / grasp.size();
  }
  sim::release(s);
  for (int64_t i = 1; i <= n_after && ok; ++i) {
    ok = advance("released");
    if (!ok) break;
    const double res = rigid_residual(m, s, organ);
    if (out.restoration_time_s < 0 && res < opt.restored_below_m) out.restoration_time_s = i * m.dt_s;
    if (i == n_residual) out.residual_mm = 1e3 * res;
  }
  if (n_residual > n_after && ok) out.residual_mm = 1e3 * rigid_residual(m, s, organ);
  out.simulated_s = k * m.dt_s;
  out.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

namespace {
struct RestoreArgs {
  std::string set_dir, organ, model_name, integrator_name;
  double pull_mm = 30.0, dt = -1.0, damping_ratio = -1.0, flexion_stiffness = -1.0;
  int threads = 1;
  bool json_out = false, no_sleep = false, no_contact = false;
};

int bench_restore(const RestoreArgs& a) {
  const auto& [set_dir, organ, model_name, integrator_name, pull_mm, dt, damping_ratio, flexion_stiffness, threads,
               json_out, no_sleep, no_contact] = a;

  io::SceneOptions so;
  so.model_override = model_name;
  if (!integrator_name.empty() && !sim::parse_integrator(integrator_name, so.integrator))
    throw InputError("--integrator",
                     "unknown integrator '" + integrator_name + "' (expected verlet, semi-implicit or implicit)");
  if (dt > 0)
    so.dt_s = dt;
  else if (dt != -1.0)
    throw InputError("--dt", "expected a positive time step");
  sim::SceneDesc scene = io::scene_from_organ_set(io::read_organ_set(set_dir), so);
  scene.threads = threads;
  if (no_sleep) scene.allow_sleep = false;
  if (no_contact) scene.contact = false;
  if (damping_ratio >= 0)
    for (sim::OrganDesc& o : scene.organs) o.material.damping_ratio = damping_ratio;
  if (flexion_stiffness >= 0)
    for (sim::OrganDesc& o : scene.organs) o.material.flexion_stiffness = flexion_stiffness;
  RestoreOptions opt;
  opt.pull_m = pull_mm * 1e-3;
  opt.progress = true;
  const RestoreResult r = run_restore(scene, organ, opt);
  nlohmann::json j;
  j["organ"] = r.organ;
  j["model"] = r.model;
  j["rest_drift_mm"] = r.finite ? nlohmann::json(r.rest_drift_mm) : nlohmann::json(nullptr);
  j["pull_reached_mm"] = r.finite ? nlohmann::json(r.pull_reached_mm) : nlohmann::json(nullptr);
  j["residual_mm"] = r.finite ? nlohmann::json(r.residual_mm) : nlohmann::json(nullptr);
  j["restoration_time_s"] =
      r.finite && r.restoration_time_s >= 0 ? nlohmann::json(r.restoration_time_s) : nlohmann::json(nullptr);
  j["volume_change_pct"] = r.volume_change_pct;
  j["finite"] = r.finite;
  j["integrator"] = r.integrator;
  j["dt_s"] = r.dt_s;
  j["grasped_vertices"] = r.grasped_vertices;
  j["simulated_s"] = r.simulated_s;
  j["wall_s"] = r.wall_s;
  j["realtime_factor"] = r.wall_s > 0 ? r.simulated_s / r.wall_s : 0.0;
  if (json_out) {
    std::printf("%s\n", j.dump().c_str());
  } else {
    std::printf("%s [%s]: rest drift %.4f mm, pull %.1f mm, residual %.3f mm, volume %.2f %%, finite %s\n",
                r.organ.c_str(), r.model.c_str(), r.rest_drift_mm, r.pull_reached_mm, r.residual_mm,
                r.volume_change_pct, r.finite ? "yes" : "no");
  }
  return r.finite ? 0 : 3;
}

}  // namespace

void add_bench_restore(CLI::App& bench, cli::Status* status) {
  CLI::App* app = bench.add_subcommand("restore", "rest drift, pull 30 mm, release, residual shape error");
  auto a = std::make_shared<RestoreArgs>();
  app->add_option("set", a->set_dir, "organ-set folder")->required();
  app->add_option("--organ", a->organ, "organ to grasp and pull")->required();
  app->add_option("--pull-mm", a->pull_mm, "pull distance (mm)")->check(CLI::Range(0.0, 500.0));
  app->add_option("--model", a->model_name, "override every organ's model: tmsm | cmsm | nmsm | flexion");
  app->add_option("--integrator", a->integrator_name, "verlet | semi-implicit | implicit (default: the set's)");
  app->add_option("--dt", a->dt, "time step (s; default: the set's)");
  app->add_option("--threads", a->threads, "worker threads")->check(CLI::Range(1, 64));
  app->add_option("--damping-ratio", a->damping_ratio, "every spring's damping ratio (default: 000 eq 10)")
      ->check(CLI::Range(0.0, 100.0));
  app->add_option("--flexion-stiffness", a->flexion_stiffness, "flexion model: dihedral spring stiffness (N m / rad)")
      ->check(CLI::Range(0.0, 1e3));
  app->add_flag("--no-sleep", a->no_sleep, "resting organs are not put to sleep");
  app->add_flag("--no-contact", a->no_contact, "without contact between organs (sim/contact.hpp; on by default)");
  app->add_flag("--json", a->json_out, "print one JSON object");
  cli::on_run(app, status, [a] { return bench_restore(*a); });
}

}  // namespace softatlas::bench
