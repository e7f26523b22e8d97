// Plays a lesson headless against a scripted device: one PNG per step and report.json.
#pragma once

#include <string>
#include <vector>

#include "softatlas/app/lesson.hpp"
#include "softatlas/app/viewer.hpp"

namespace softatlas::app {

struct StepResult {
  int index = 0;
  std::string kind, where, png, reason;
  bool task = false, passed = true;
  double displacement_mm = 0, peak_force_N = 0, peak_device_force_N = 0, time_s = 0, wall_s = 0;
  double final_reaction_N[3] = {0, 0, 0};  // core tool_reaction at the end of a pull
  double final_device_force_N[3] = {0, 0, 0};
  std::string picked;
  int physics_steps = 0;
};

struct LessonReport {
  bool passed = true;
  std::vector<StepResult> steps;
  double physics_us_per_step = 0;
  int tasks = 0, tasks_passed = 0;
  std::string json;  // report.json text
};

// Shared by the headless player and the window, so both show a lesson the same way.
// The display effect of a non-task step (camera, highlight, hide, show, isolate, label, slice).
void apply_view_step(const LessonStep& step, Viewer& viewer, const AtlasScene& scene);
// "TITLE  -  step k/N: STEP TITLE": the step's own title, else the latest one before it.
std::string caption_title(const Lesson& lesson, size_t step);
// The end screen: one line per task (PASS/FAIL and why) and the score line.
struct TaskOutcome {
  bool done = false, passed = false;
  int attempts = 0;
  std::string reason;
};
void show_end_screen(const Lesson& lesson, const std::vector<TaskOutcome>& per_step, Viewer& viewer);

struct RunOptions {
  int width = 960, height = 540;
  bool write_png = true;
};

// Throws InputError for a bad script or a script that does not match the lesson. Writes
// DIR/step_NN_KIND.png, DIR/end.png (the score screen) and DIR/report.json (atomically) and
// returns the report.
LessonReport run_lesson(const Lesson& lesson, const DeviceScript& script, const std::string& out_dir,
                        const RunOptions& options = {});

}  // namespace softatlas::app
