#include "softatlas/app/bench.hpp"

#include <nlohmann/json.hpp>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <thread>

#include "softatlas/app/haptics.hpp"
#include "softatlas/app/virtual_coupling.hpp"
#include "softatlas/app/viewer.hpp"

namespace softatlas::app {
namespace {
using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }
}  // namespace

std::string bench_render(const RenderBenchOptions& o) {
  AtlasScene scene(io::read_organ_set(o.set), {}, {}, PhysicsSettings{});
  auto ctx = make_osmesa_context(o.width, o.height);
  Viewer viewer(*ctx, scene);
  viewer.camera.set_view("anterior");
  viewer.frame_all();
  for (size_t v = 0; v < viewer.labeled.size() && o.ui; ++v) viewer.labeled[v] = true;
  if (o.ui) viewer.caption.title = "bench render";
  std::vector<std::vector<float>> rest(scene.view_organs().size()), cur;
  for (size_t v = 0; v < rest.size(); ++v) scene.positions_mm(static_cast<int>(v), rest[v]);
  cur = rest;
  // Warm-up: shader compilation and first uploads are not part of the steady state.
  for (int i = 0; i < 5; ++i) viewer.render();
  ctx->gl().Finish();
  const auto t0 = Clock::now();
  for (int f = 0; f < o.frames; ++f) {
    if (o.deform) {
      // A breathing-like deformation so every frame uploads new positions and normals.
      const float s = 1.0f + 0.02f * std::sin(0.1f * static_cast<float>(f));
      for (size_t v = 0; v < cur.size(); ++v)
        for (size_t i = 0; i < cur[v].size(); ++i) cur[v][i] = rest[v][i] * (i % 3 == 2 ? 1.0f : s);
      viewer.set_geometry(cur);
    }
    viewer.camera.yaw_deg = 20.0f * std::sin(0.02f * static_cast<float>(f));
    viewer.render();
  }
  ctx->gl().Finish();
  const double s = seconds_since(t0);
  nlohmann::json j = {{"benchmark", "render"},
                      {"set", o.set},
                      {"backend", ctx->backend()},
                      {"gl", ctx->describe()},
                      {"width", o.width},
                      {"height", o.height},
                      {"frames", o.frames},
                      {"faces", viewer.renderer().face_count()},
                      {"deform", o.deform},
                      {"ui", o.ui},
                      {"seconds", s},
                      {"fps", o.frames / s},
                      {"ms_per_frame", s / o.frames * 1e3}};
  return j.dump(2) + "\n";
}

std::string bench_haptic(const HapticBenchOptions& o) {
  // Bound llvmpipe's render threads so that render + physics + haptic fit on the cores.
  if (!std::getenv("LP_NUM_THREADS")) setenv("LP_NUM_THREADS", std::to_string(o.render_threads).c_str(), 1);
  std::string lock_msg;
  const bool locked = lock_memory(lock_msg);
  if (!locked) std::fprintf(stderr, "bench haptic: %s\n", lock_msg.c_str());
  AtlasScene scene(io::read_organ_set(o.set), {}, {}, PhysicsSettings{});
  // Renderer (and the llvmpipe threads the context creates) on the render cores; physics and
  // the haptic loop share the remaining core (CpuPlan).
  const CpuPlan cpus = plan_cpus();
  pin_current_thread(cpus.render_cpus);
  auto ctx = make_osmesa_context(o.width, o.height);
  Viewer viewer(*ctx, scene);
  viewer.camera.set_view("anterior");
  viewer.frame_all();

  // The tool: the liver's inferior edge (or the first organ's), moved by a scripted device
  // that pulls down and back sinusoidally.
  int v = scene.view_index("liver");
  if (v < 0) v = 0;
  const std::vector<int32_t> verts = scene.global_vertices(v, scene.region_vertices(v, "inferior", 12.0));
  std::vector<Keyframe> keys;
  for (int i = 0; i <= static_cast<int>(o.seconds * 10) + 20; ++i) {
    const double t = i * 0.1;
    keys.push_back({t, {0.0, 0.0, -o.amplitude_mm * 1e-3 * 0.5 * (1 - std::cos(2.0 * t))}});
  }
  ScriptedDevice device(keys, false, 4.0);
  HapticLoop loop(device, ForceShaper{4.0, 0.05}, static_cast<int64_t>(o.seconds * 1000 * 1.2) + 1000);

  std::mutex snapshot_mutex;
  std::vector<std::vector<float>> snapshot(scene.view_organs().size());
  std::atomic<bool> stop{false};
  std::atomic<long> physics_steps{0};
  std::atomic<double> physics_busy_s{0};
  std::atomic<double> physics_wall_s{0};
  std::thread physics([&] {
    // Real-time paced: one step per dt of wall time; if a step takes longer, it lags. The haptic
    // loop recomputes the force every tick from the local model each step publishes, and the
    // step holds the grasp at the coupling's proxy (virtual_coupling.hpp).
    pin_current_thread(cpus.haptic_cpu);
    const auto t0 = Clock::now();
    CouplingPhysics coupling(scene.model);
    if (!verts.empty()) coupling.grasp(scene.model, scene.state, verts);
    std::vector<std::vector<float>> local(snapshot.size());
    double busy = 0;
    long n = 0;
    while (!stop.load()) {
      ToolCommand cmd;
      if (loop.latest_command(cmd)) coupling.apply(scene.model, scene.state, cmd);
      const auto s0 = Clock::now();
      sim::step(scene.model, scene.state, scene.work);
      busy += seconds_since(s0);
      ++n;
      loop.publish(coupling.local_model(scene.model, scene.state, scene.work));
      if (n % 16 == 0) {  // hand positions to the renderer now and then, never waiting for it
        for (size_t k = 0; k < local.size(); ++k) scene.positions_mm(static_cast<int>(k), local[k]);
        std::unique_lock<std::mutex> lock(snapshot_mutex, std::try_to_lock);
        if (lock.owns_lock()) snapshot.swap(local);
      }
      const double ahead = scene.state.time_s - seconds_since(t0);
      if (ahead > 0) std::this_thread::sleep_for(std::chrono::duration<double>(ahead));
    }
    physics_steps.store(n);
    physics_busy_s.store(busy);
    physics_wall_s.store(seconds_since(t0));
  });
  loop.start(o.realtime, cpus.haptic_cpu);
  const auto t0 = Clock::now();
  long frames = 0;
  std::vector<std::vector<float>> draw(snapshot.size());
  while (seconds_since(t0) < o.seconds) {
    {
      std::lock_guard<std::mutex> lock(snapshot_mutex);
      if (!snapshot[0].empty()) draw.swap(snapshot);
    }
    if (!draw[0].empty()) viewer.set_geometry(draw);
    viewer.render();
    ctx->gl().Finish();
    ++frames;
    if (o.render_fps > 0) {  // next frame at the display's next refresh
      const double next = frames / o.render_fps, now = seconds_since(t0);
      if (next > now) std::this_thread::sleep_for(std::chrono::duration<double>(next - now));
    }
  }
  const double render_s = seconds_since(t0);
  loop.stop();
  stop.store(true);
  physics.join();
  const HapticStats st = loop.stats();
  if (!st.message.empty()) std::fprintf(stderr, "bench haptic: %s\n", st.message.c_str());
  const long ns = physics_steps.load();
  nlohmann::json j = {{"benchmark", "haptic"},
                      {"set", o.set},
                      {"seconds", o.seconds},
                      {"cycles", st.cycles},
                      {"rate_hz", st.cycles / render_s},
                      {"period_us_p50", st.period_us_p50},
                      {"period_us_p99", st.period_us_p99},
                      {"period_us_max", st.period_us_max},
                      {"period_us_p999", st.period_us_p999},
                      {"periods_over_2ms", st.late_2ms},
                      {"period_us_mean", st.period_us_mean},
                      {"physics_steps", ns},
                      {"physics_us_per_step", ns ? physics_busy_s.load() / static_cast<double>(ns) * 1e6 : 0.0},
                      // simulated seconds of the whole scene per wall second of the physics thread
                      {"physics_realtime_factor", scene.state.time_s / physics_wall_s.load()},
                      {"physics_step_s", scene.model.dt_s},
                      // ticks whose force was recomputed from the tissue model, per second
                      {"force_update_hz", static_cast<double>(st.model_ticks) / render_s},
                      {"model_update_hz", static_cast<double>(st.model_updates) / render_s},
                      {"force_jump_max_N", st.force_jump_max_N},
                      {"force_peak_N", st.peak_force_N},
                      {"coupling_stiffness_N_m", loop.coupling().params().stiffness_N_m},
                      {"coupling_damping_N_s_m", loop.coupling().params().damping_N_s_m},
                      {"render_fps", frames / render_s},
                      {"render_fps_target", o.render_fps},
                      {"haptic_physics_cpu", cpus.haptic_cpu},
                      {"render_cpus", cpus.render_cpus},
                      {"render_size", {o.width, o.height}},
                      {"render_threads", std::getenv("LP_NUM_THREADS") ? std::getenv("LP_NUM_THREADS") : ""},
                      {"peak_force_N", st.peak_force_N},
                      {"realtime", st.realtime},
                      {"memory_locked", locked},
                      {"message", st.message.empty() ? lock_msg : st.message},
                      {"faces", scene.model.nface},
                      {"vertices", scene.model.nvert}};
  return j.dump(2) + "\n";
}

}  // namespace softatlas::app
