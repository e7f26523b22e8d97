#include "softatlas/app/interactive.hpp"

#include <GLFW/glfw3.h>
#include <imgui.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <mutex>
#include <thread>

#include "softatlas/app/haptics.hpp"
#include "softatlas/app/virtual_coupling.hpp"
#include "softatlas/app/lesson_run.hpp"
#include "softatlas/app/viewer.hpp"

namespace softatlas::app {
namespace {

using Clock = std::chrono::steady_clock;

// Physics on its own thread; the UI talks to it through small mutex-guarded requests (the UI is
// not real-time) and the haptic loop through the loop's lock-free SeqLocks.
struct PhysicsThread {
  AtlasScene* scene = nullptr;
  HapticLoop* loop = nullptr;
  std::mutex mutex;                    // guards requests and the snapshot
  std::vector<int32_t> grasp_request;  // global vertices to grasp (empty + release_request)
  bool grasp_pending = false, release_pending = false;
  std::vector<std::vector<float>> snapshot;
  double us_per_step = 0, max_disp_mm = 0;
  double realtime_factor = 0;  // simulated seconds per wall second (< 1: slow motion)
  double grasp_sim_s = 0;      // simulated seconds since the grasp began (lesson rules)
  std::atomic<bool> stop{false}, paused{false};
  std::thread thread;
  int cpu = -1;  // shared with the haptic loop (CpuPlan)

  void run() {
    pin_current_thread(cpu);
    const auto t0 = Clock::now();
    bool attached = false;
    std::vector<int32_t> verts;
    std::vector<std::vector<float>> local(snapshot.size());
    double avg = 0;
    double sim_offset = 0;
    CouplingPhysics coupling(scene->model);  // the grasp is held at the haptic loop's proxy
    double grasp_t0 = 0, rt_sim0 = scene->state.time_s;
    auto rt_wall0 = Clock::now();
    while (!stop.load()) {
      {
        std::lock_guard<std::mutex> lock(mutex);
        if (release_pending) {
          coupling.release(scene->state);
          attached = false;
          release_pending = false;
        }
        if (grasp_pending) {
          verts = grasp_request;
          grasp_pending = false;
          coupling.grasp(scene->model, scene->state, verts);
          attached = true;
          grasp_t0 = scene->state.time_s;
        }
      }
      ToolCommand cmd;
      if (attached && loop->latest_command(cmd)) coupling.apply(scene->model, scene->state, cmd);
      if (paused.load()) {
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
        sim_offset = scene->state.time_s - std::chrono::duration<double>(Clock::now() - t0).count();
        continue;
      }
      const auto s0 = Clock::now();
      sim::step(scene->model, scene->state, scene->work);
      const double us = std::chrono::duration<double>(Clock::now() - s0).count() * 1e6;
      avg = avg == 0 ? us : 0.98 * avg + 0.02 * us;
      loop->publish(coupling.local_model(scene->model, scene->state, scene->work));
      if (scene->state.step_count % 8 == 0) {
        for (size_t k = 0; k < local.size(); ++k) scene->positions_mm(static_cast<int>(k), local[k]);
        const double disp = attached ? scene->mean_displacement_mm(verts) : 0.0;
        const double wall = std::chrono::duration<double>(Clock::now() - rt_wall0).count();
        std::unique_lock<std::mutex> lock(mutex, std::try_to_lock);
        if (lock.owns_lock()) {
          snapshot.swap(local);
          us_per_step = avg;
          max_disp_mm = disp;
          grasp_sim_s = attached ? scene->state.time_s - grasp_t0 : 0.0;
          if (wall > 0.5) {  // over the last half second of wall time
            realtime_factor = (scene->state.time_s - rt_sim0) / wall;
            rt_sim0 = scene->state.time_s;
            rt_wall0 = Clock::now();
          }
        }
      }
      const double ahead = scene->state.time_s - sim_offset - std::chrono::duration<double>(Clock::now() - t0).count();
      if (ahead > 0) std::this_thread::sleep_for(std::chrono::duration<double>(ahead));
    }
  }
};

// A key press (not held): the frame's state against the previous frame's.
struct Keys {
  GLFWwindow* win = nullptr;
  std::map<int, bool> down;
  bool pressed(int key) {
    const bool now = glfwGetKey(win, key) == GLFW_PRESS;
    const bool was = down[key];
    down[key] = now;
    return now && !was;
  }
};

// The models the physics panel offers (material.model names, docs/organ-set.md).
const char* const kPanelModels[] = {"solid", "nmsm", "tmsm", "cmsm", "flexion"};
constexpr int kPanelModelCount = 5;

const char* kHelp =
    "Mouse\n"
    "  left drag on an organ   grasp and pull it (force arrow at the grasp point)\n"
    "  left click              answer a pick step\n"
    "  right drag / wheel      orbit / zoom\n"
    "Keys\n"
    "  Right / Left arrow      next / previous lesson step\n"
    "  1 .. 8                  answer a question step\n"
    "  r                       reset the organs and retry this step\n"
    "  space                   pause / resume the physics\n"
    "  h                       this help\n"
    "  Escape or q             quit";

}  // namespace

int run_window(const io::OrganSet& set, const Lesson* lesson, const WindowOptions& opt) {
  std::vector<std::string> shown, context;
  PhysicsSettings physics;
  if (lesson) {
    shown = lesson->organs;
    context = lesson->context;
    physics = lesson->physics;
  }
  // The window, the renderer and llvmpipe's threads on the render cores; physics and the haptic
  // loop share the remaining core (CpuPlan).
  const CpuPlan cpus = plan_cpus();
  pin_current_thread(cpus.render_cpus);
  auto ctx = make_glfw_context(opt.width, opt.height, lesson ? "SoftAtlas - " + lesson->title : "SoftAtlas");
  auto scene = std::make_unique<AtlasScene>(set, shown, context, physics);
  auto viewer = std::make_unique<Viewer>(*ctx, *scene);
  viewer->camera.set_view("anterior");
  viewer->frame_all();
  MouseDevice mouse(opt.max_force_N);
  std::string lock_msg;
  if (!lock_memory(lock_msg)) std::fprintf(stderr, "view: %s\n", lock_msg.c_str());
  auto loop = std::make_unique<HapticLoop>(mouse, ForceShaper{opt.max_force_N, 0.05}, 1000 * 3600);
  auto phys = std::make_unique<PhysicsThread>();
  auto start_physics = [&]() {
    phys = std::make_unique<PhysicsThread>();
    phys->scene = scene.get();
    phys->loop = loop.get();
    phys->cpu = cpus.haptic_cpu;
    phys->snapshot.resize(scene->view_organs().size());
    phys->thread = std::thread([p = phys.get()] { p->run(); });
  };
  start_physics();
  loop->start(opt.realtime, cpus.haptic_cpu);
  const HapticStats first = loop->stats();
  (void)first;

  bool dragging = false, orbiting = false;
  double last_x = 0, last_y = 0, grab_x = 0, grab_y = 0;
  Eigen::Vector3f grab_point(0, 0, 0);
  std::string status;
  int lesson_step = -1;
  double peak_force = 0, pull_disp = 0;  // pull_disp: reached within the time limit (simulated)
  PhysicsSettings live = physics;
  // The panel starts from the lesson's model, else the first simulated organ's material.
  const std::string start_model = !live.model.empty()        ? live.model
                                  : set.find(scene->name(0)) ? set.find(scene->name(0))->material.model
                                                             : "nmsm";
  int model_index = 0;
  for (int i = 0; i < kPanelModelCount; ++i)
    if (start_model == kPanelModels[i]) model_index = i;
  float young = static_cast<float>(live.young_modulus_pa > 0 ? live.young_modulus_pa : 4000.0);
  float elastica_b = static_cast<float>(live.elastica_b >= 0 ? live.elastica_b : 0.1);
  std::vector<std::vector<float>> draw(scene->view_organs().size());
  int frames = 0;
  int rebuild = 0;  // 1: recompile with the panel's parameters, 2: reset to rest (after the frame)
  double fps = 0;
  auto fps_t0 = Clock::now();

  // Lesson state: the current step (-1: none; steps.size(): the end screen) and one outcome per
  // step. A passed task stays passed; a failed one can be tried again (r, or a new grasp/click).
  std::vector<TaskOutcome> outcomes(lesson ? lesson->steps.size() : 0);
  bool show_help = false;
  auto current = [&]() -> const LessonStep* {
    if (!lesson || lesson_step < 0 || lesson_step >= static_cast<int>(lesson->steps.size())) return nullptr;
    return &lesson->steps[static_cast<size_t>(lesson_step)];
  };
  auto task_status = [&]() {
    const LessonStep* s = current();
    if (!s || !is_task(s->kind)) {
      viewer->caption.status.clear();
      return;
    }
    const TaskOutcome& o = outcomes[static_cast<size_t>(lesson_step)];
    viewer->caption.ok = !o.done || o.passed;
    if (!o.done)
      viewer->caption.status = s->kind == StepKind::pull       ? "grasp " + s->pull.organ + " and pull (drag)"
                               : s->kind == StepKind::pick     ? "click an organ"
                               : s->kind == StepKind::question ? "choose an answer (click it or press its number)"
                                                               : "";
    else
      viewer->caption.status = std::string(o.passed ? "PASS: " : "FAIL: ") + o.reason +
                               (o.passed ? "   (Right arrow: next step, r: retry)" : "   (try again; r: reset)");
  };
  // Shows step k: the display state of steps 0..k replayed from the start (so Left arrow undoes a
  // hide), the step's caption, and its outcome so far.
  auto goto_step = [&](int k) {
    if (!lesson) return;
    lesson_step = std::clamp(k, 0, static_cast<int>(lesson->steps.size()));
    for (auto& st : viewer->styles) {
      st.visible = true;
      st.highlight = false;
    }
    std::fill(viewer->labeled.begin(), viewer->labeled.end(), false);
    viewer->slice = SlicePlane{};
    viewer->camera.set_view("anterior");
    viewer->frame_all();
    if (lesson_step == static_cast<int>(lesson->steps.size())) {
      for (const LessonStep& s : lesson->steps) apply_view_step(s, *viewer, *scene);
      show_end_screen(*lesson, outcomes, *viewer);
      return;
    }
    for (int i = 0; i <= lesson_step; ++i) apply_view_step(lesson->steps[static_cast<size_t>(i)], *viewer, *scene);
    const LessonStep& s = *current();
    viewer->caption.title = caption_title(*lesson, static_cast<size_t>(lesson_step));
    viewer->caption.text = s.kind == StepKind::say ? s.text
                           : s.kind == StepKind::question
                               ? s.hint.empty() ? s.question.ask : s.hint + "\n" + s.question.ask
                               : s.hint;
    viewer->hover_names = s.kind != StepKind::pick && s.kind != StepKind::question;
    TaskOutcome& o = outcomes[static_cast<size_t>(lesson_step)];
    if (s.kind == StepKind::wait && !o.done) o = {true, true, 1, "waited"};
    task_status();
    peak_force = 0;
    pull_disp = 0;
  };
  auto record = [&](bool passed, const std::string& reason) {
    TaskOutcome& o = outcomes[static_cast<size_t>(lesson_step)];
    if (o.passed) return;  // a passed task stays passed
    o.done = true;
    o.passed = passed;
    o.reason = reason;
    task_status();
  };
  auto answer = [&](size_t choice) {
    const LessonStep* s = current();
    if (!s || s->kind != StepKind::question || choice >= s->question.choices.size()) return;
    if (outcomes[static_cast<size_t>(lesson_step)].passed) return;
    outcomes[static_cast<size_t>(lesson_step)].attempts++;
    const std::string& right = s->question.choices[static_cast<size_t>(s->question.answer)];
    const std::string& got = s->question.choices[choice];
    record(got == right, got == right ? "answered " + got : "answered " + got + ", not right");
  };
  // r / retry: the organs back to rest and the current task open again (its tries are kept).
  auto retry = [&]() {
    rebuild = 2;
    if (const LessonStep* c = current(); c && is_task(c->kind) && c->kind != StepKind::wait) {
      const int tries = outcomes[static_cast<size_t>(lesson_step)].attempts;
      outcomes[static_cast<size_t>(lesson_step)] = {false, false, tries, ""};
      task_status();
    }
  };
  if (lesson) goto_step(0);
  if (!opt.slice.empty()) viewer->slice = opt.slice_plane;
  int grasp_view = -1;
  std::vector<int32_t> grasp_local;
  Keys keys{ctx->window(), {}};
  // Sticky keys: a press shorter than a frame (llvmpipe can be slow) is still seen once.
  glfwSetInputMode(ctx->window(), GLFW_STICKY_KEYS, GLFW_TRUE);
  Eigen::Vector3f hand_off(0, 0, 0);  // the hand's offset from the grasp point (mm)

  GLFWwindow* win = ctx->window();
  while (!ctx->should_close()) {
    ctx->poll_events();
    ImGui::SetCurrentContext(viewer->imgui());
    const ImGuiIO& io = ImGui::GetIO();
    double mx, my;
    glfwGetCursorPos(win, &mx, &my);
    int ww, wh;
    glfwGetWindowSize(win, &ww, &wh);
    const float sx = static_cast<float>(ctx->width()) / static_cast<float>(std::max(ww, 1));
    const float sy = static_cast<float>(ctx->height()) / static_cast<float>(std::max(wh, 1));
    const float px = static_cast<float>(mx) * sx, py = static_cast<float>(my) * sy;
    {
      std::lock_guard<std::mutex> lock(phys->mutex);
      if (!phys->snapshot.empty() && !phys->snapshot[0].empty()) draw.swap(phys->snapshot);
    }
    if (!draw[0].empty()) viewer->set_geometry(draw);
    const PickHit hover = viewer->pick(px, py);
    viewer->hovered = hover.organ;
    if (!io.WantCaptureMouse) {
      const bool left = glfwGetMouseButton(win, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS;
      const bool right = glfwGetMouseButton(win, GLFW_MOUSE_BUTTON_RIGHT) == GLFW_PRESS;
      const LessonStep* cur = current();
      const bool answering = cur && (cur->kind == StepKind::pick || cur->kind == StepKind::question);
      const bool rigid_hit = hover.organ >= 0 && scene->is_rigid(hover.organ);
      if (left && !dragging && !answering && rigid_hit) {
        status = scene->display_name(hover.organ) + " is rigid (bone): it does not move";
      } else if (left && !dragging && !answering && hover.organ >= 0 && scene->model_organ(hover.organ) >= 0) {
        // Grasp: the patch within 10 mm of the picked point on the deformed surface.
        const int v = hover.organ;
        std::vector<int32_t> local;
        const auto& P = draw[static_cast<size_t>(v)];
        for (size_t i = 0; i < P.size() / 3; ++i)
          if ((Eigen::Vector3f(P[3 * i], P[3 * i + 1], P[3 * i + 2]) - hover.point).norm() < 10.0f)
            local.push_back(static_cast<int32_t>(i));
        if (local.empty()) local.push_back(hover.nearest_vertex);
        grasp_view = v;
        grasp_local = local;
        hand_off.setZero();
        peak_force = 0;
        pull_disp = 0;
        if (cur && cur->kind == StepKind::pull && !outcomes[static_cast<size_t>(lesson_step)].passed) {
          TaskOutcome& o = outcomes[static_cast<size_t>(lesson_step)];
          o.attempts++;
          o.done = false;  // a new try after a failure
          task_status();
        }
        std::lock_guard<std::mutex> lock(phys->mutex);
        phys->grasp_request = scene->global_vertices(v, local);
        phys->grasp_pending = !phys->grasp_request.empty();
        dragging = phys->grasp_pending;
        grab_x = px;
        grab_y = py;
        grab_point = hover.point;
        mouse.set({0, 0, 0}, true);
      } else if (left && dragging) {
        // Drag on the screen plane through the grasp point: pixels -> mm at that depth.
        const Eigen::Matrix4f view = viewer->camera.view();
        const Eigen::Vector3f right_v = view.block<1, 3>(0, 0).transpose();
        const Eigen::Vector3f up_v = view.block<1, 3>(1, 0).transpose();
        const float depth = (grab_point - viewer->camera.eye()).norm();
        const float mm_per_px = 2.0f * depth * std::tan(0.5f * viewer->camera.fov_y_deg * 3.14159265f / 180.0f) /
                                static_cast<float>(viewer->camera.height);
        const Eigen::Vector3f off =
            (right_v * (px - static_cast<float>(grab_x)) - up_v * (py - static_cast<float>(grab_y))) * mm_per_px;
        mouse.set({off.x() * 1e-3, off.y() * 1e-3, off.z() * 1e-3}, true);
        hand_off = off;
      } else if (!left && dragging) {
        dragging = false;
        grasp_view = -1;
        mouse.set({0, 0, 0}, false);
        std::lock_guard<std::mutex> lock(phys->mutex);
        phys->release_pending = true;
      }
      if (right && orbiting) {
        viewer->camera.yaw_deg -= static_cast<float>(mx - last_x) * 0.4f;
        viewer->camera.pitch_deg =
            std::clamp(viewer->camera.pitch_deg + static_cast<float>(my - last_y) * 0.4f, -89.0f, 89.0f);
      }
      orbiting = right;
      if (io.MouseWheel != 0) viewer->camera.distance *= std::pow(0.9f, io.MouseWheel);
      // pick task: a click on an organ is the answer; a wrong one can be corrected by clicking again
      if (cur && cur->kind == StepKind::pick && ImGui::IsMouseClicked(ImGuiMouseButton_Left) && hover.organ >= 0 &&
          !outcomes[static_cast<size_t>(lesson_step)].passed) {
        const std::string& want = cur->organs[0];
        const std::string got = scene->name(hover.organ);
        outcomes[static_cast<size_t>(lesson_step)].attempts++;
        record(got == want, got == want ? "picked " + got : "picked " + got + ", expected " + want);
      }
    }
    if (!io.WantCaptureKeyboard) {
      if (keys.pressed(GLFW_KEY_ESCAPE) || keys.pressed(GLFW_KEY_Q)) glfwSetWindowShouldClose(win, GLFW_TRUE);
      if (keys.pressed(GLFW_KEY_H)) show_help = !show_help;
      if (keys.pressed(GLFW_KEY_SPACE)) phys->paused.store(!phys->paused.load());
      if (keys.pressed(GLFW_KEY_R)) retry();
      if (keys.pressed(GLFW_KEY_RIGHT) && lesson) goto_step(lesson_step + 1);
      if (keys.pressed(GLFW_KEY_LEFT) && lesson) goto_step(lesson_step - 1);
      for (int k = 0; k < 8; ++k)
        if (keys.pressed(GLFW_KEY_1 + k)) answer(static_cast<size_t>(k));
    }
    last_x = mx;
    last_y = my;
    viewer->lines.clear();
    viewer->texts.clear();
    const Vec3d f = mouse.force();
    const float fmag = static_cast<float>(std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]));
    if (dragging && grasp_view >= 0 && !draw[static_cast<size_t>(grasp_view)].empty()) {
      peak_force = std::max(peak_force, static_cast<double>(fmag));
      // The grasp point where the tissue is now (the patch's centroid), the hand's target, and the
      // force on the hand as an arrow from the grasp point (60 mm per newton, at least 20 mm).
      const auto& P = draw[static_cast<size_t>(grasp_view)];
      Eigen::Vector3f c(0, 0, 0);
      for (int32_t i : grasp_local)
        c += Eigen::Vector3f(P[3 * static_cast<size_t>(i)], P[3 * static_cast<size_t>(i) + 1],
                             P[3 * static_cast<size_t>(i) + 2]);
      c /= static_cast<float>(grasp_local.size());
      const Eigen::Vector3f fv(static_cast<float>(f[0]), static_cast<float>(f[1]), static_cast<float>(f[2]));
      const Eigen::Vector3f tip =
          c + (fmag > 0 ? Eigen::Vector3f(fv / fmag * std::max(20.0f, 60.0f * fmag)) : Eigen::Vector3f::Zero());
      const Eigen::Vector3f hand = grab_point + hand_off;
      viewer->lines.push_back({c, hand, {0.8f, 0.8f, 0.85f, 0.7f}});
      add_arrow(viewer->lines, c, tip, {1.0f, 0.85f, 0.1f, 1.0f});
      char b[32];
      std::snprintf(b, sizeof b, "%.2f N", fmag);
      viewer->texts.push_back({tip, b});
      if (const LessonStep* cur = current();
          cur && cur->kind == StepKind::pull && cur->pull.organ == scene->name(grasp_view)) {
        double disp, since;
        {
          std::lock_guard<std::mutex> lock(phys->mutex);
          disp = phys->max_disp_mm;
          since = phys->grasp_sim_s;
        }
        // As `lesson run` judges it: what the pull reaches within time_limit_s of simulated time
        // after the grasp (a slow physics neither stretches nor shrinks the task).
        if (since <= cur->pull.time_limit_s) pull_disp = std::max(pull_disp, disp);
        disp = pull_disp;
        char r[128];
        if (peak_force > cur->pull.max_force_N) {
          std::snprintf(r, sizeof r, "pulled too hard: peak force %.2f N above the %.2f N allowed", peak_force,
                        cur->pull.max_force_N);
          record(false, r);
        } else if (disp >= cur->pull.min_displacement_mm) {
          std::snprintf(r, sizeof r, "reached %.1f mm with a peak force of %.2f N", disp, peak_force);
          record(true, r);
        }
      }
    }
    if (++frames % 30 == 0) {
      fps = 30.0 / std::chrono::duration<double>(Clock::now() - fps_t0).count();
      fps_t0 = Clock::now();
    }
    viewer->render([&] {
      ImGui::SetNextWindowPos(ImVec2(static_cast<float>(ctx->width()) - 330, 10), ImGuiCond_FirstUseEver);
      // As tall as the window: with ten structures in the organ list the Stats section (the
      // physics real-time factor) was below the panel's fold at 520 px.
      ImGui::SetNextWindowSize(ImVec2(320, std::max(520.0f, static_cast<float>(ctx->height()) - 20.0f)),
                               ImGuiCond_FirstUseEver);
      ImGui::Begin("SoftAtlas");
      if (ImGui::CollapsingHeader("Organs", ImGuiTreeNodeFlags_DefaultOpen)) {
        // Grouped by body system (digestive, urinary, ...), display names; hover a row for the
        // organ set's name and FMA id.
        std::vector<std::string> systems;
        for (size_t v = 0; v < viewer->styles.size(); ++v)
          if (std::find(systems.begin(), systems.end(), scene->system(static_cast<int>(v))) == systems.end())
            systems.push_back(scene->system(static_cast<int>(v)));
        for (const std::string& sys : systems) {
          if (!ImGui::TreeNodeEx(sys.c_str(), ImGuiTreeNodeFlags_DefaultOpen)) continue;
          for (size_t v = 0; v < viewer->styles.size(); ++v) {
            if (scene->system(static_cast<int>(v)) != sys) continue;
            ImGui::PushID(static_cast<int>(v));
            bool vis = viewer->styles[v].visible;
            if (ImGui::Checkbox(scene->display_name(static_cast<int>(v)).c_str(), &vis))
              viewer->styles[v].visible = vis;
            if (ImGui::IsItemHovered()) {
              const io::OrganEntry* e = set.find(scene->name(static_cast<int>(v)));
              ImGui::SetTooltip("%s  (label %d, %s)", scene->name(static_cast<int>(v)).c_str(), e ? e->label : 0,
                                e && !e->fma.empty() ? e->fma.c_str() : "no FMA id");
            }
            ImGui::SameLine(190);
            if (ImGui::SmallButton("isolate"))
              for (size_t k = 0; k < viewer->styles.size(); ++k) viewer->styles[k].visible = k == v;
            ImGui::SameLine();
            bool lab = viewer->labeled[v];
            if (ImGui::Checkbox("label", &lab)) viewer->labeled[v] = lab;
            ImGui::PopID();
          }
          ImGui::TreePop();
        }
        if (ImGui::Button("show all"))
          for (auto& s : viewer->styles) s.visible = true;
      }
      if (ImGui::CollapsingHeader("Slice", ImGuiTreeNodeFlags_DefaultOpen)) {
        // The sectional view: plane and position (drag the slider); the CT on it when the set has one.
        static const char* kPlanes[] = {"off", "sagittal (x)", "coronal (y)", "axial (z)"};
        int plane = viewer->slice.axis + 1;
        Eigen::Vector3f lo, hi;
        scene->bounds_mm(lo, hi);
        if (ImGui::Combo("plane", &plane, kPlanes, 4)) {
          viewer->slice.axis = plane - 1;
          if (viewer->slice.active()) viewer->slice.at_mm = 0.5f * (lo[plane - 1] + hi[plane - 1]);
        }
        if (viewer->slice.active()) {
          const int a = viewer->slice.axis;
          ImGui::SliderFloat("at (mm)", &viewer->slice.at_mm, lo[a] - 10.0f, hi[a] + 10.0f, "%.1f");
          ImGui::TextDisabled("%s", viewer->ct() ? "CT on the plane" : "this organ set records no CT");
        }
      }
      if (ImGui::CollapsingHeader("Physics", ImGuiTreeNodeFlags_DefaultOpen)) {
        ImGui::Combo("model", &model_index, kPanelModels, kPanelModelCount);
        ImGui::SliderFloat("E (Pa)", &young, 500.0f, 20000.0f, "%.0f", ImGuiSliderFlags_Logarithmic);
        ImGui::SliderFloat("elastica b", &elastica_b, 0.0f, 1.0f);
        bool paused = phys->paused.load();
        if (ImGui::Checkbox("pause", &paused)) phys->paused.store(paused);
        ImGui::SameLine();
        if (ImGui::Button("apply (recompile)")) rebuild = 1;
        ImGui::SameLine();
        if (ImGui::Button("reset")) rebuild = 2;
        ImGui::TextWrapped("%s", overlay_text(status).c_str());
      }
      if (lesson && ImGui::CollapsingHeader("Lesson", ImGuiTreeNodeFlags_DefaultOpen)) {
        ImGui::TextWrapped("%s", overlay_text(lesson->title).c_str());
        if (ImGui::Button("< prev")) goto_step(lesson_step - 1);
        ImGui::SameLine();
        if (ImGui::Button("next >")) goto_step(lesson_step + 1);
        ImGui::SameLine();
        if (ImGui::Button("retry (r)")) retry();
        int done = 0, passed = 0, tasks = 0;
        for (size_t i = 0; i < outcomes.size(); ++i)
          if (is_task(lesson->steps[i].kind)) {
            ++tasks;
            done += outcomes[i].done;
            passed += outcomes[i].passed;
          }
        if (const LessonStep* s = current()) {
          ImGui::Text("step %d/%zu: %s", lesson_step + 1, lesson->steps.size(), to_string(s->kind));
          if (s->kind == StepKind::pull) {
            double disp;
            {
              std::lock_guard<std::mutex> lock(phys->mutex);
              disp = phys->max_disp_mm;
            }
            ImGui::Text("pull %s: %.1f / %.1f mm, peak %.2f / %.2f N", s->pull.organ.c_str(), dragging ? disp : 0.0,
                        s->pull.min_displacement_mm, peak_force, s->pull.max_force_N);
          }
        } else {
          ImGui::Text("end of the lesson");
        }
        ImGui::Text("score: %d of %d tasks passed (%d tried)", passed, tasks, done);
      }
      if (ImGui::CollapsingHeader("Stats", ImGuiTreeNodeFlags_DefaultOpen)) {
        double us, rtf;
        {
          std::lock_guard<std::mutex> lock(phys->mutex);
          us = phys->us_per_step;
          rtf = phys->realtime_factor;
        }
        ImGui::Text("render %.0f fps (%s)", fps, ctx->backend());
        ImGui::Text("physics %.3f ms/step, %d vertices", us * 1e-3, scene->model.nvert);
        // simulated seconds per wall second: below 1 the scene moves in slow motion
        if (rtf > 0 && rtf < 0.95)
          ImGui::TextColored(ImVec4(1.0f, 0.6f, 0.2f, 1.0f), "physics %.2fx real time (slow motion)", rtf);
        else
          ImGui::Text("physics %.2fx real time", rtf);
        ImGui::Text("haptic loop: %s", loop->running() ? "1 kHz, running" : "stopped");
        ImGui::Text("tool force %.2f N (limit %.1f N)", fmag, opt.max_force_N);
      }
      ImGui::End();
      if (const LessonStep* s = current(); s && s->kind == StepKind::question) {
        ImGui::SetNextWindowPos(ImVec2(10, static_cast<float>(ctx->height()) - 230), ImGuiCond_Always);
        ImGui::SetNextWindowSizeConstraints(ImVec2(380, 0), ImVec2(600, 400));
        ImGui::SetNextWindowBgAlpha(0.85f);
        ImGui::Begin(
            "Question", nullptr,
            ImGuiWindowFlags_AlwaysAutoResize | ImGuiWindowFlags_NoSavedSettings | ImGuiWindowFlags_NoCollapse);
        ImGui::TextWrapped("%s", overlay_text(s->question.ask).c_str());
        for (size_t i = 0; i < s->question.choices.size(); ++i) {
          const std::string b = std::to_string(i + 1) + ")  " + overlay_text(s->question.choices[i]);
          if (ImGui::Button(b.c_str())) answer(i);
        }
        ImGui::End();
      }
      if (show_help) {
        ImGui::SetNextWindowPos(
            ImVec2(0.5f * static_cast<float>(ctx->width()), 0.5f * static_cast<float>(ctx->height())), ImGuiCond_Always,
            ImVec2(0.5f, 0.5f));
        ImGui::SetNextWindowBgAlpha(0.92f);
        ImGui::Begin(
            "Help (h to close)", nullptr,
            ImGuiWindowFlags_AlwaysAutoResize | ImGuiWindowFlags_NoSavedSettings | ImGuiWindowFlags_NoCollapse);
        ImGui::TextUnformatted(kHelp);
        ImGui::End();
      }
    });
    if (opt.frames > 0 && frames >= opt.frames) {
      if (!opt.screenshot.empty()) viewer->save_png(opt.screenshot);  // back buffer, before swap
      break;
    }
    ctx->swap();
    if (rebuild) {
      // Live parameters: stop the physics thread, recompile the scene (or reset it), start
      // again; the viewer is rebuilt on the new scene, keeping the camera and styles.
      phys->stop.store(true);
      phys->thread.join();
      dragging = false;
      mouse.set({0, 0, 0}, false);
      if (rebuild == 1) {
        live.model = kPanelModels[model_index];
        live.young_modulus_pa = young;
        live.elastica_b = elastica_b;
      }
      try {
        auto fresh = std::make_unique<AtlasScene>(set, shown, context, live);
        const Camera cam = viewer->camera;
        const auto styles = viewer->styles;
        const auto labeled = viewer->labeled;
        const Caption caption = viewer->caption;
        const SlicePlane slice = viewer->slice;
        const bool hover_names = viewer->hover_names;
        viewer.reset();
        scene.swap(fresh);
        viewer = std::make_unique<Viewer>(*ctx, *scene);
        viewer->camera = cam;
        viewer->styles = styles;
        viewer->labeled = labeled;
        viewer->caption = caption;
        viewer->slice = slice;
        viewer->hover_names = hover_names;
        status = rebuild == 1 ? "recompiled: " + std::to_string(scene->model.nvert) + " vertices" : "reset";
      } catch (const std::exception& e) {
        status = e.what();
      }
      draw.assign(scene->view_organs().size(), {});
      start_physics();
      rebuild = 0;
    }
  }
  loop->stop();
  phys->stop.store(true);
  phys->thread.join();
  const HapticStats st = loop->stats();
  std::fprintf(stderr, "view: haptic loop %lld cycles, period p50 %.0f us, p99 %.0f us, max %.0f us%s%s\n",
               static_cast<long long>(st.cycles), st.period_us_p50, st.period_us_p99, st.period_us_max,
               st.message.empty() ? "" : "; ", st.message.c_str());
  return 0;
}

}  // namespace softatlas::app
