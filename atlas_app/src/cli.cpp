// softatlas view | lesson check | lesson run | bench render | bench haptic
#include "softatlas/app/cli.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <filesystem>
#include <iostream>

#include "softatlas/app/bench.hpp"
#include "softatlas/app/interactive.hpp"
#include "softatlas/app/lesson.hpp"
#include "softatlas/app/lesson_run.hpp"
#include "softatlas/app/viewer.hpp"
#include "softatlas/sim/error.hpp"

namespace softatlas::app {
namespace {

// CLI11 wants argv-style input; args[0..skip) are the subcommand words.
int parse(CLI::App& app, const std::vector<std::string>& args, size_t skip) {
  std::vector<std::string> rest(args.begin() + static_cast<long>(skip), args.end());
  std::reverse(rest.begin(), rest.end());
  try {
    app.parse(rest);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? -1 : 2;  // --help: -1 (print and stop with 0)
  }
  return 0;
}

bool is_lesson_file(const std::string& path) {
  namespace fs = std::filesystem;
  const std::string ext = fs::path(path).extension().string();
  return fs::is_regular_file(path) && (ext == ".yaml" || ext == ".yml");
}

int cmd_view(const std::vector<std::string>& args) {
  CLI::App app{"softatlas view SET|LESSON: show an organ set or a lesson"};
  std::string target, screenshot, view = "anterior";
  bool headless = false, labels = false, norealtime = false;
  int frames = 1, width = 1280, height = 720;
  app.add_option("target", target, "organ set folder or lesson .yaml")->required();
  app.add_flag("--headless", headless, "render off-screen (OSMesa), no window");
  app.add_option("--frames", frames, "frames to render (headless)")->check(CLI::Range(1, 100000));
  app.add_option("--width", width, "width in pixels")->check(CLI::Range(16, 8192));
  app.add_option("--height", height, "height in pixels")->check(CLI::Range(16, 8192));
  app.add_option("--screenshot", screenshot, "write the last frame as PNG");
  app.add_option("--view", view, "anterior|posterior|left|right|superior|inferior");
  app.add_flag("--labels", labels, "label every organ");
  std::string slice;
  app.add_option("--slice", slice, "cut the organs at a plane: axial:Z, coronal:Y or sagittal:X (mm, RAS)");
  app.add_flag("--no-realtime", norealtime, "do not ask for SCHED_FIFO for the haptic loop");
  if (int rc = parse(app, args, 1)) return rc < 0 ? 0 : rc;
  const SlicePlane slice_plane = parse_slice_option(slice);
  std::unique_ptr<Lesson> lesson;
  io::OrganSet set;
  if (is_lesson_file(target)) {
    lesson = std::make_unique<Lesson>(load_lesson(target));
    set = lesson->set;
  } else {
    set = io::read_organ_set(target);
  }
  if (!headless) {
    WindowOptions wo;
    wo.width = width;
    wo.height = height;
    wo.realtime = !norealtime;
    if (app.count("--frames")) wo.frames = frames;
    wo.screenshot = screenshot;
    wo.slice = slice;
    wo.slice_plane = slice_plane;
    return run_window(set, lesson.get(), wo);
  }
  std::vector<std::string> shown, context;
  PhysicsSettings physics;
  if (lesson) {
    shown = lesson->organs;
    context = lesson->context;
    physics = lesson->physics;
  }
  AtlasScene scene(set, shown, context, physics);
  auto ctx = make_osmesa_context(width, height);
  Viewer viewer(*ctx, scene);
  Camera probe;
  if (!probe.set_view(view)) throw InputError("--view", "unknown view '" + view + "' (expected anterior, posterior, left, right, superior or inferior)");
  viewer.camera.set_view(view);
  viewer.frame_all();
  if (labels) viewer.labeled.assign(viewer.labeled.size(), true);
  viewer.slice = slice_plane;
  if (lesson) viewer.caption.title = lesson->title;
  std::fprintf(stderr, "view: %s, %zu organs, %zu faces, %s\n", target.c_str(), scene.view_organs().size(),
               viewer.renderer().face_count(), ctx->describe().c_str());
  for (int f = 0; f < frames; ++f) {
    if (f > 0) {
      sim::step(scene.model, scene.state, scene.work);
      viewer.set_geometry_from_scene();
    }
    viewer.render();
  }
  if (!screenshot.empty()) {
    viewer.save_png(screenshot);
    std::fprintf(stderr, "view: wrote %s (%dx%d)\n", screenshot.c_str(), width, height);
  }
  return 0;
}

int cmd_lesson(const std::vector<std::string>& args) {
  const std::string sub = args.size() > 1 ? args[1] : "";
  if (sub == "check") {
    CLI::App app{"softatlas lesson check LESSON [--device SCRIPT]: validate only"};
    std::string lesson_path, script_path;
    app.add_option("lesson", lesson_path, "lesson .yaml")->required();
    app.add_option("--device", script_path, "also validate a device script against the lesson");
    if (int rc = parse(app, args, 2)) return rc < 0 ? 0 : rc;
    // Every error of the lesson and of the script, one FILE:LINE:COLUMN: message line each (the
    // format editors and CI problem matchers read), then exit 1.
    int errors = 0;
    auto report = [&](const InputError& e) {
      std::fprintf(stderr, "%s\n", e.what());
      ++errors;
    };
    std::unique_ptr<Lesson> loaded;
    try {
      loaded = std::make_unique<Lesson>(load_lesson(lesson_path));
    } catch (const InputError& e) {
      report(e);
    }
    if (!script_path.empty()) {
      try {
        const DeviceScript script = load_device_script(script_path);
        if (loaded) check_script_matches(script, *loaded);
      } catch (const InputError& e) {
        report(e);
      }
    }
    if (errors) return 1;
    const Lesson& lesson = *loaded;
    std::printf("%s: ok (%zu steps, %d tasks, organ set %s)\n", lesson_path.c_str(), lesson.steps.size(),
                lesson.task_count(), lesson.organ_set_path.c_str());
    return 0;
  }
  if (sub == "run") {
    CLI::App app{"softatlas lesson run LESSON --device SCRIPT --out DIR: play headless"};
    std::string lesson_path, script_path, out;
    RunOptions ro;
    app.add_option("lesson", lesson_path, "lesson .yaml")->required();
    app.add_option("--device", script_path, "scripted device .yaml")->required();
    app.add_option("--out", out, "output folder (PNG per step, report.json)")->required();
    app.add_option("--width", ro.width, "picture width")->check(CLI::Range(16, 8192));
    app.add_option("--height", ro.height, "picture height")->check(CLI::Range(16, 8192));
    if (int rc = parse(app, args, 2)) return rc < 0 ? 0 : rc;
    const Lesson lesson = load_lesson(lesson_path);
    const DeviceScript script = load_device_script(script_path);
    const LessonReport r = run_lesson(lesson, script, out, ro);
    for (const StepResult& s : r.steps)
      if (s.task)
        std::fprintf(stderr, "  step %d %-5s %s  %s\n", s.index + 1, s.kind.c_str(), s.passed ? "pass" : "FAIL", s.reason.c_str());
    std::fprintf(stderr, "lesson %s: %s; pictures and report in %s\n", lesson.title.c_str(),
                 r.passed ? "passed" : "failed", out.c_str());
    std::fputs(r.json.c_str(), stdout);
    return r.passed ? 0 : 3;
  }
  std::fprintf(stderr, "usage: softatlas lesson check LESSON | lesson run LESSON --device SCRIPT --out DIR\n");
  return 2;
}

int cmd_bench(const std::vector<std::string>& args) {
  const std::string sub = args[1];
  if (sub == "render") {
    CLI::App app{"softatlas bench render SET [--width W --height H --frames N] --json"};
    RenderBenchOptions o;
    bool json = false, static_mesh = false, no_ui = false;
    app.add_option("set", o.set, "organ set folder")->required();
    app.add_option("--width", o.width)->check(CLI::Range(16, 8192));
    app.add_option("--height", o.height)->check(CLI::Range(16, 8192));
    app.add_option("--frames", o.frames)->check(CLI::Range(1, 1000000));
    app.add_flag("--static", static_mesh, "do not deform / re-upload the meshes each frame");
    app.add_flag("--no-ui", no_ui, "no labels / ImGui overlay");
    app.add_flag("--json", json, "print JSON (the default output)");
    if (int rc = parse(app, args, 2)) return rc < 0 ? 0 : rc;
    o.deform = !static_mesh;
    o.ui = !no_ui;
    std::fputs(bench_render(o).c_str(), stdout);
    return 0;
  }
  CLI::App app{"softatlas bench haptic SET [--seconds S] --json"};
  HapticBenchOptions o;
  bool json = false, norealtime = false;
  app.add_option("set", o.set, "organ set folder")->required();
  app.add_option("--seconds", o.seconds)->check(CLI::Range(0.1, 3600.0));
  app.add_option("--width", o.width)->check(CLI::Range(16, 8192));
  app.add_option("--height", o.height)->check(CLI::Range(16, 8192));
  app.add_option("--render-threads", o.render_threads, "llvmpipe threads (LP_NUM_THREADS)")->check(CLI::Range(1, 64));
  app.add_option("--render-fps", o.render_fps,
                 "pace the render loop like a display at this rate (default 60); 0 = as fast as it can")
      ->check(CLI::Range(0.0, 1000.0));
  app.add_flag("--no-realtime", norealtime, "do not ask for SCHED_FIFO");
  app.add_flag("--json", json, "print JSON (the default output)");
  if (int rc = parse(app, args, 2)) return rc < 0 ? 0 : rc;
  o.realtime = !norealtime;
  std::fputs(bench_haptic(o).c_str(), stdout);
  return 0;
}

}  // namespace

int cli_main(const std::vector<std::string>& args) {
  if (args.empty()) return 2;
  if (args[0] == "view") return cmd_view(args);
  if (args[0] == "lesson") return cmd_lesson(args);
  if (args[0] == "bench" && args.size() > 1 && (args[1] == "render" || args[1] == "haptic")) return cmd_bench(args);
  std::fprintf(stderr, "softatlas: unknown app command\n");
  return 2;
}

}  // namespace softatlas::app
