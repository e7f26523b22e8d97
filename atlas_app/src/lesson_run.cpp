#include "softatlas/app/lesson_run.hpp"

#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include "softatlas/app/viewer.hpp"
#include "softatlas/io/mesh_io.hpp"

namespace softatlas::app {
namespace {

double norm3(const Vec3d& v) { return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }

Eigen::Vector3f centroid_mm(const AtlasScene& scene, int v) {
  std::vector<float> p;
  scene.positions_mm(v, p);
  Eigen::Vector3f c(0, 0, 0);
  for (size_t i = 0; i + 2 < p.size(); i += 3) c += Eigen::Vector3f(p[i], p[i + 1], p[i + 2]);
  return p.empty() ? c : Eigen::Vector3f(c / static_cast<float>(p.size() / 3));
}

char buf[256];
const char* fmt(const char* f, double a, double b) {
  std::snprintf(buf, sizeof buf, f, a, b);
  return buf;
}

}  // namespace

void apply_view_step(const LessonStep& s, Viewer& viewer, const AtlasScene& scene) {
  auto vi = [&](const std::string& n) { return static_cast<size_t>(scene.view_index(n)); };
  switch (s.kind) {
    case StepKind::camera: {
      if (!s.camera.view.empty()) viewer.camera.set_view(s.camera.view);
      if (s.camera.yaw_deg < 1e8) viewer.camera.yaw_deg = static_cast<float>(s.camera.yaw_deg);
      if (s.camera.pitch_deg < 1e8) viewer.camera.pitch_deg = static_cast<float>(s.camera.pitch_deg);
      viewer.frame_all();
      if (!s.camera.target.empty()) viewer.camera.target = centroid_mm(scene, scene.view_index(s.camera.target));
      if (s.camera.distance_mm > 0) viewer.camera.distance = static_cast<float>(s.camera.distance_mm);
      break;
    }
    case StepKind::highlight:
      for (auto& st : viewer.styles) st.highlight = false;
      for (const auto& n : s.organs) viewer.styles[vi(n)].highlight = true;
      break;
    case StepKind::hide:
      for (const auto& n : s.organs) viewer.styles[vi(n)].visible = false;
      break;
    case StepKind::show:
      for (const auto& n : s.organs) viewer.styles[vi(n)].visible = true;
      break;
    case StepKind::isolate:
      for (auto& st : viewer.styles) st.visible = false;
      for (const auto& n : s.organs) viewer.styles[vi(n)].visible = true;
      break;
    case StepKind::label:
      for (const auto& n : s.organs) viewer.labeled[vi(n)] = true;
      break;
    case StepKind::slice:
      viewer.slice = slice_plane(s.slice);
      break;
    default:
      break;
  }
}

std::string caption_title(const Lesson& lesson, size_t step) {
  std::string t;
  for (size_t k = 0; k <= step && k < lesson.steps.size(); ++k)
    if (!lesson.steps[k].title.empty()) t = lesson.steps[k].title;
  return lesson.title + "  -  step " + std::to_string(step + 1) + "/" + std::to_string(lesson.steps.size()) +
         (t.empty() ? "" : ": " + t);
}

void show_end_screen(const Lesson& lesson, const std::vector<TaskOutcome>& per_step, Viewer& viewer) {
  int tasks = 0, passed = 0;
  std::string text;
  for (size_t i = 0; i < lesson.steps.size() && i < per_step.size(); ++i) {
    if (!is_task(lesson.steps[i].kind)) continue;
    const TaskOutcome& o = per_step[i];
    ++tasks;
    passed += o.passed ? 1 : 0;
    std::string title = caption_title(lesson, i);
    title = title.substr(title.find("step "));
    text += std::string(o.passed ? "PASS  "
                        : o.done ? "FAIL  "
                                 : "----  ") +
            title + " (" + to_string(lesson.steps[i].kind) + ")" + (o.reason.empty() ? "" : ": " + o.reason) +
            (o.attempts > 1 ? "  [" + std::to_string(o.attempts) + " tries]" : "") + "\n";
  }
  viewer.caption.title = lesson.title + "  -  lesson complete";
  viewer.caption.text = text;
  viewer.caption.status = "Score: " + std::to_string(passed) + " of " + std::to_string(tasks) + " tasks passed";
  viewer.caption.ok = passed == tasks;
  viewer.lines.clear();
  viewer.texts.clear();
  viewer.hover_names = true;
}

LessonReport run_lesson(const Lesson& lesson, const DeviceScript& script, const std::string& out_dir,
                        const RunOptions& opt) {
  check_script_matches(script, lesson);
  std::filesystem::create_directories(out_dir);
  AtlasScene scene(lesson.set, lesson.organs, lesson.context, lesson.physics);
  auto ctx = make_osmesa_context(opt.width, opt.height);
  Viewer viewer(*ctx, scene);
  viewer.camera.set_view("anterior");
  viewer.frame_all();

  LessonReport report;
  nlohmann::json steps = nlohmann::json::array();
  size_t action = 0;
  double total_physics_s = 0;
  long total_physics_steps = 0;
  double lesson_time_s = 0;
  const double dt = scene.model.dt_s;
  long guard_restores = 0;
  auto physics_step = [&]() {
    const auto t0 = std::chrono::steady_clock::now();
    const sim::StepReport sr = sim::step(scene.model, scene.state, scene.work);
    if (sr.status == sim::StepStatus::restored) ++guard_restores;
    total_physics_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    ++total_physics_steps;
    lesson_time_s += dt;
  };

  for (size_t i = 0; i < lesson.steps.size(); ++i) {
    const LessonStep& s = lesson.steps[i];
    const auto wall0 = std::chrono::steady_clock::now();
    StepResult r;
    r.index = static_cast<int>(i);
    r.kind = to_string(s.kind);
    r.where = s.where;
    r.task = is_task(s.kind);
    viewer.lines.clear();
    viewer.texts.clear();
    viewer.caption.title = caption_title(lesson, i);
    viewer.hover_names = s.kind != StepKind::pick && s.kind != StepKind::question;
    viewer.caption.status.clear();
    viewer.caption.ok = true;
    if (s.kind == StepKind::say)
      viewer.caption.text = s.text;
    else if (!s.hint.empty())
      viewer.caption.text = s.hint;
    auto vi = [&](const std::string& n) { return scene.view_index(n); };
    switch (s.kind) {
      case StepKind::say:
      case StepKind::camera:
      case StepKind::highlight:
      case StepKind::hide:
      case StepKind::show:
      case StepKind::isolate:
      case StepKind::label:
      case StepKind::slice:
        apply_view_step(s, viewer, scene);
        break;
      case StepKind::pull: {
        const ScriptAction& a = script.actions[action++];
        const PullTask& t = s.pull;
        const int v = vi(t.organ);
        const std::vector<int32_t> local = t.has_landmark ? scene.landmark_vertices(v, t.landmark_mm, t.radius_mm)
                                                          : scene.region_vertices(v, t.region, t.radius_mm);
        const std::vector<int32_t> verts = scene.global_vertices(v, local);
        if (verts.empty()) throw InputError(s.where, "pull: no free vertex of '" + t.organ + "' in that region");
        ScriptedDevice device(a.keys, a.force_mode, script.max_force_N);
        ForceShaper shaper{script.max_force_N, script.ramp_s};
        // The scripted timeline runs to its end or to the lesson's time limit, whichever is first;
        // one physics step per haptic tick (dt = 1 ms by default), as the 1 kHz loop would see it.
        const double duration = std::min(std::max(device.duration_s(), dt), t.time_limit_s);
        const int n = static_cast<int>(std::ceil(duration / dt));
        double peak = 0, disp = 0;
        for (int k = 0; k < n; ++k) {
          const double tk = (k + 1) * dt;
          const ToolCommand cmd = device.read(tk);
          if (cmd.force_mode)
            sim::pull_force(scene.model, scene.state, verts, cmd.force_N);
          else if (k == 0)
            sim::attach(scene.model, scene.state, verts, cmd.offset_m, 1);
          else
            sim::move_attachment(scene.state, cmd.offset_m);
          physics_step();
          const Vec3d reaction = sim::tool_reaction(scene.state);
          peak = std::max(peak, norm3(reaction));
          if (std::getenv("SOFTATLAS_DEBUG_PULL"))
            std::fprintf(stderr, "t %.3f reaction %.4f %.4f %.4f disp %.2f\n", tk, reaction[0], reaction[1],
                         reaction[2], scene.mean_displacement_mm(verts));
          device.write_force(shaper.shape(reaction, true, tk));
          disp = std::max(disp, scene.mean_displacement_mm(verts));
          r.physics_steps++;
        }
        const Vec3d fr = sim::tool_reaction(scene.state);
        for (int k = 0; k < 3; ++k) {
          r.final_reaction_N[k] = fr[k];
          r.final_device_force_N[k] = device.last_sent_N()[k];
        }
        r.displacement_mm = disp;
        r.peak_force_N = peak;
        r.peak_device_force_N = device.peak_sent_N();
        r.time_s = n * dt;
        const bool far_enough = disp >= t.min_displacement_mm;
        const bool gentle = peak <= t.max_force_N;
        r.passed = far_enough && gentle;
        if (!far_enough)
          r.reason =
              std::string("pulled too little: ") + fmt("%.1f mm of the %.1f mm needed", disp, t.min_displacement_mm);
        else if (!gentle)
          r.reason =
              std::string("pulled too hard: ") + fmt("peak force %.2f N above the %.2f N allowed", peak, t.max_force_N);
        else
          r.reason = std::string("reached ") + fmt("%.1f mm with a peak force of %.2f N", disp, peak);
        // Picture: the grasped patch, the tool line and the force arrow at the end of the pull.
        viewer.set_geometry_from_scene();
        Eigen::Vector3f c(0, 0, 0);
        for (int32_t g : verts)
          c += 1e3f * Eigen::Vector3f(static_cast<float>(scene.state.x[static_cast<size_t>(g)]),
                                      static_cast<float>(scene.state.y[static_cast<size_t>(g)]),
                                      static_cast<float>(scene.state.z[static_cast<size_t>(g)]));
        c /= static_cast<float>(verts.size());
        // Arrow: the force on the hand (device force), 60 mm per newton, at least 20 mm.
        const Eigen::Vector3f f(static_cast<float>(fr[0]), static_cast<float>(fr[1]), static_cast<float>(fr[2]));
        const float len = std::max(20.0f, 60.0f * f.norm());
        const Eigen::Vector3f tip =
            c + (f.norm() > 0 ? Eigen::Vector3f(f.normalized() * len) : Eigen::Vector3f(0, 0, 0));
        add_arrow(viewer.lines, c, tip, {1.0f, 0.85f, 0.1f, 1.0f});
        viewer.texts.push_back({tip, fmt("%.2f N", f.norm(), 0)});
        sim::release(scene.state);
        break;
      }
      case StepKind::pick: {
        const ScriptAction& a = script.actions[action++];
        float px = 0, py = 0;
        if (a.has_click_mm)
          viewer.camera.project(a.click_mm.cast<float>(), px, py);
        else {
          px = static_cast<float>(a.click_px.x());
          py = static_cast<float>(a.click_px.y());
        }
        viewer.set_geometry_from_scene();
        const PickHit hit = viewer.pick(px, py);
        r.picked = hit.organ >= 0 ? scene.name(hit.organ) : "";
        r.passed = r.picked == s.organs[0];
        r.reason = r.picked.empty()
                       ? "the click hit no organ"
                       : (r.passed ? "picked " + r.picked : "picked " + r.picked + ", expected " + s.organs[0]);
        if (hit.organ >= 0) {
          viewer.texts.push_back({hit.point, r.picked});
          const float m = 6.0f;
          for (int ax = 0; ax < 3; ++ax) {
            Eigen::Vector3f d(0, 0, 0);
            d[ax] = m;
            viewer.lines.push_back({hit.point - d, hit.point + d, {1.0f, 1.0f, 1.0f, 1.0f}});
          }
        }
        break;
      }
      case StepKind::question: {
        const ScriptAction& a = script.actions[action++];
        r.picked = a.choice;
        r.passed = a.choice == s.question.choices[static_cast<size_t>(s.question.answer)];
        r.reason = r.passed ? "answered " + a.choice
                            : "answered " + a.choice + ", the answer is " +
                                  s.question.choices[static_cast<size_t>(s.question.answer)];
        viewer.caption.text = question_text(s.question, a.choice);
        break;
      }
      case StepKind::wait: {
        ++action;
        const int n = static_cast<int>(std::ceil(s.wait_s / dt));
        for (int k = 0; k < n; ++k) physics_step();
        r.time_s = n * dt;
        r.physics_steps = n;
        break;
      }
    }
    if (r.task) {
      viewer.caption.status = std::string(r.passed ? "PASS: " : "FAIL: ") + r.reason;
      viewer.caption.ok = r.passed;
    }
    report.passed = report.passed && r.passed;
    viewer.set_geometry_from_scene();
    // Two frames: Dear ImGui sizes an auto-fitting window from the previous frame's content.
    viewer.render();
    viewer.render();
    char name[64];
    std::snprintf(name, sizeof name, "step_%02zu_%s.png", i + 1, r.kind.c_str());
    r.png = name;
    if (opt.write_png) viewer.save_png((std::filesystem::path(out_dir) / name).string());
    r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
    nlohmann::json j = {{"index", r.index + 1}, {"kind", r.kind}, {"where", r.where},   {"task", r.task},
                        {"passed", r.passed},   {"png", r.png},   {"time_s", r.time_s}, {"wall_s", r.wall_s}};
    if (s.kind == StepKind::pull) {
      j["organ"] = s.pull.organ;
      j["displacement_mm"] = r.displacement_mm;
      j["min_displacement_mm"] = s.pull.min_displacement_mm;
      j["peak_force_N"] = r.peak_force_N;
      j["max_force_N"] = s.pull.max_force_N;
      j["peak_device_force_N"] = r.peak_device_force_N;
      j["final_reaction_N"] = {r.final_reaction_N[0], r.final_reaction_N[1], r.final_reaction_N[2]};
      j["physics_steps"] = r.physics_steps;
    }
    if (s.kind == StepKind::pick) {
      j["organ"] = s.organs[0];
      j["picked"] = r.picked;
    }
    if (s.kind == StepKind::question) {
      j["answer"] = s.question.choices[static_cast<size_t>(s.question.answer)];
      j["chosen"] = r.picked;
    }
    if (s.kind == StepKind::slice) j["slice"] = {{"plane", s.slice.plane}, {"at_mm", s.slice.at_mm}};
    if (r.task) j["reason"] = r.reason;
    if (!s.hint.empty() && r.task && !r.passed) j["hint"] = s.hint;
    steps.push_back(j);
    report.steps.push_back(r);
  }
  std::vector<TaskOutcome> outcomes;
  for (const StepResult& r : report.steps) {
    outcomes.push_back({r.task, r.passed, r.task ? 1 : 0, r.task ? r.reason : ""});
    report.tasks += r.task ? 1 : 0;
    report.tasks_passed += r.task && r.passed ? 1 : 0;
  }
  show_end_screen(lesson, outcomes, viewer);
  viewer.render();
  viewer.render();
  if (opt.write_png) viewer.save_png((std::filesystem::path(out_dir) / "end.png").string());
  report.physics_us_per_step =
      total_physics_steps ? total_physics_s / static_cast<double>(total_physics_steps) * 1e6 : 0;
  nlohmann::json root = {{"lesson", lesson.title},
                         {"file", lesson.file},
                         {"organ_set", lesson.organ_set_path},
                         {"device_script", script.file},
                         {"passed", report.passed},
                         {"score", {{"tasks", report.tasks}, {"passed", report.tasks_passed}}},
                         {"end_png", "end.png"},
                         {"steps", steps},
                         {"simulated_time_s", lesson_time_s},
                         {"physics",
                          {{"organs", scene.model.organs.size()},
                           {"vertices", scene.model.nvert},
                           {"faces", scene.model.nface},
                           {"dt_s", scene.model.dt_s},
                           {"physics_us_per_step", report.physics_us_per_step},
                           {"guard_restores", guard_restores}}}};
  report.json = root.dump(2) + "\n";
  io::write_file_atomic((std::filesystem::path(out_dir) / "report.json").string(), report.json);
  return report;
}

}  // namespace softatlas::app
