// softatlas view | lesson check | lesson run | bench render | bench haptic, registered on the one
// command line (softatlas/io/cli.hpp).
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
#include "softatlas/io/cli.hpp"
#include "softatlas/io/output_folder.hpp"
#include "softatlas/sim/error.hpp"

namespace softatlas::app {
namespace {

bool is_lesson_file(const std::string& path) {
  namespace fs = std::filesystem;
  const std::string ext = fs::path(path).extension().string();
  return fs::is_regular_file(path) && (ext == ".yaml" || ext == ".yml");
}

struct ViewArgs {
  std::string target, screenshot, view = "anterior", slice;
  bool headless = false, labels = false, norealtime = false, frames_given = false, view_given = false;
  int frames = 1, width = 1280, height = 720;
};

int run_view(const ViewArgs& a) {
  const auto& [target, screenshot, given_view, slice, headless, labels, norealtime, frames_given, view_given, frames,
               width, height] = a;
  const SlicePlane slice_plane = parse_slice_option(slice);
  // Without --view, a slice is seen from its cut side: axial from above, sagittal from the right.
  std::string view = given_view;
  if (!view_given && slice_plane.active())
    view = slice_plane.axis == 2 ? "superior" : slice_plane.axis == 0 ? "right" : "anterior";
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
    if (frames_given) wo.frames = frames;
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
  if (!probe.set_view(view))
    throw InputError("--view",
                     "unknown view '" + view + "' (expected anterior, posterior, left, right, superior or inferior)");
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

int run_lesson_check(const std::string& lesson_path, const std::string& script_path) {
  {
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
}

struct LessonRunArgs {
  std::string lesson_path, script_path, out;
  RunOptions ro;
};

int run_lesson_run(const LessonRunArgs& a) {
  const auto& [lesson_path, script_path, out, ro] = a;
  {
    const Lesson lesson = load_lesson(lesson_path);
    const DeviceScript script = load_device_script(script_path);
    io::StagedFolder staged(out);  // the pictures and the report appear together or not at all
    const LessonReport r =
        staged.write_and_commit([&](const std::string& dir) { return run_lesson(lesson, script, dir, a.ro); });
    for (const StepResult& s : r.steps)
      if (s.task)
        std::fprintf(stderr, "  step %d %-5s %s  %s\n", s.index + 1, s.kind.c_str(), s.passed ? "pass" : "FAIL",
                     s.reason.c_str());
    std::fprintf(stderr, "lesson %s: %s; pictures and report in %s\n", lesson.title.c_str(),
                 r.passed ? "passed" : "failed", out.c_str());
    std::fputs(r.json.c_str(), stdout);
    return r.passed ? 0 : 3;
  }
}

void add_view(CLI::App& root, cli::Status* status) {
  CLI::App* app = root.add_subcommand("view", "show an organ set or a lesson (SET|LESSON)");
  auto a = std::make_shared<ViewArgs>();
  app->add_option("target", a->target, "organ set folder or lesson .yaml")->required();
  app->add_flag("--headless", a->headless, "render off-screen (OSMesa), no window");
  CLI::Option* frames =
      app->add_option("--frames", a->frames, "frames to render (headless)")->check(CLI::Range(1, 100000));
  app->add_option("--width", a->width, "width in pixels")->check(CLI::Range(16, 8192));
  app->add_option("--height", a->height, "height in pixels")->check(CLI::Range(16, 8192));
  app->add_option("--screenshot", a->screenshot, "write the last frame as PNG");
  CLI::Option* view = app->add_option(
      "--view", a->view,
      "anterior|posterior|left|right|superior|inferior (default anterior; with --slice, the plane's cut side)");
  app->add_flag("--labels", a->labels, "label every organ");
  app->add_option("--slice", a->slice, "cut the organs at a plane: axial:Z, coronal:Y or sagittal:X (mm, RAS)");
  app->add_flag("--no-realtime", a->norealtime, "do not ask for SCHED_FIFO for the haptic loop");
  cli::on_run(app, status, [a, frames, view] {
    a->frames_given = frames->count() > 0;
    a->view_given = view->count() > 0;
    return run_view(*a);
  });
}

void add_lesson(CLI::App& root, cli::Status* status) {
  CLI::App* lesson = cli::group(root, "lesson", "validate or play a lesson");
  {
    CLI::App* app = lesson->add_subcommand("check", "validate only: LESSON [--device SCRIPT]");
    auto paths = std::make_shared<std::pair<std::string, std::string>>();
    app->add_option("lesson", paths->first, "lesson .yaml")->required();
    app->add_option("--device", paths->second, "also validate a device script against the lesson");
    cli::on_run(app, status, [paths] { return run_lesson_check(paths->first, paths->second); });
  }
  CLI::App* app = lesson->add_subcommand("run", "play headless: LESSON --device SCRIPT --out DIR");
  auto a = std::make_shared<LessonRunArgs>();
  app->add_option("lesson", a->lesson_path, "lesson .yaml")->required();
  app->add_option("--device", a->script_path, "scripted device .yaml")->required();
  app->add_option("--out", a->out, "output folder (PNG per step, report.json)")->required();
  app->add_option("--width", a->ro.width, "picture width")->check(CLI::Range(16, 8192));
  app->add_option("--height", a->ro.height, "picture height")->check(CLI::Range(16, 8192));
  cli::on_run(app, status, [a] { return run_lesson_run(*a); });
}

struct RenderArgs {
  RenderBenchOptions o;
  bool json = false, static_mesh = false, no_ui = false;
};

struct HapticArgs {
  HapticBenchOptions o;
  bool json = false, norealtime = false;
};

void add_bench(CLI::App& root, cli::Status* status) {
  CLI::App* bench = cli::group(root, "bench", "benchmarks (JSON on stdout)");
  {
    CLI::App* app = bench->add_subcommand("render", "SET [--width W --height H --frames N] --json");
    auto a = std::make_shared<RenderArgs>();
    app->add_option("set", a->o.set, "organ set folder")->required();
    app->add_option("--width", a->o.width)->check(CLI::Range(16, 8192));
    app->add_option("--height", a->o.height)->check(CLI::Range(16, 8192));
    app->add_option("--frames", a->o.frames)->check(CLI::Range(1, 1000000));
    app->add_flag("--static", a->static_mesh, "do not deform / re-upload the meshes each frame");
    app->add_flag("--no-ui", a->no_ui, "no labels / ImGui overlay");
    app->add_flag("--json", a->json, "print JSON (the default output)");
    cli::on_run(app, status, [a] {
      RenderBenchOptions o = a->o;
      o.deform = !a->static_mesh;
      o.ui = !a->no_ui;
      std::fputs(bench_render(o).c_str(), stdout);
      return 0;
    });
  }
  CLI::App* app = bench->add_subcommand("haptic", "SET [--seconds S] --json");
  auto a = std::make_shared<HapticArgs>();
  app->add_option("set", a->o.set, "organ set folder")->required();
  app->add_option("--seconds", a->o.seconds)->check(CLI::Range(0.1, 3600.0));
  app->add_option("--width", a->o.width)->check(CLI::Range(16, 8192));
  app->add_option("--height", a->o.height)->check(CLI::Range(16, 8192));
  app->add_option("--render-threads", a->o.render_threads, "llvmpipe threads (LP_NUM_THREADS)")
      ->check(CLI::Range(1, 64));
  app->add_option("--render-fps", a->o.render_fps,
                  "pace the render loop like a display at this rate (default 60); 0 = as fast as it can")
      ->check(CLI::Range(0.0, 1000.0));
  app->add_flag("--no-realtime", a->norealtime, "do not ask for SCHED_FIFO");
  app->add_flag("--json", a->json, "print JSON (the default output)");
  cli::on_run(app, status, [a] {
    HapticBenchOptions o = a->o;
    o.realtime = !a->norealtime;
    std::fputs(bench_haptic(o).c_str(), stdout);
    return 0;
  });
}

}  // namespace

void add_commands(CLI::App& root, cli::Status* status) {
  add_view(root, status);
  add_lesson(root, status);
  add_bench(root, status);
}

int cli_main(const std::vector<std::string>& args) { return cli::run_only(add_commands, args); }

}  // namespace softatlas::app
