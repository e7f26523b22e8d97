// Lessons (YAML, docs/lessons.md) and device scripts: parsed and validated once, on load.
// Every error is an InputError whose `where` is FILE:LINE:COLUMN (from yaml-cpp's marks,
// 1-based) and whose message says what was expected.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "softatlas/app/haptics.hpp"
#include "softatlas/app/scene.hpp"
#include "softatlas/io/organ_set.hpp"

namespace softatlas::app {

enum class StepKind { say, camera, highlight, hide, show, isolate, label, pull, pick, wait };
const char* to_string(StepKind kind);
inline bool is_task(StepKind k) { return k == StepKind::pull || k == StepKind::pick || k == StepKind::wait; }

struct CameraSpec {
  std::string view;          // anterior | posterior | left | right | superior | inferior | ""
  std::string target;        // organ to centre on ("" = whole scene)
  double distance_mm = -1;   // < 0: fit
  double yaw_deg = 1e9, pitch_deg = 1e9;  // 1e9: not given
};

struct PullTask {
  std::string organ;
  std::string region;        // anterior | posterior | superior | inferior | left | right
  bool has_landmark = false;
  Eigen::Vector3d landmark_mm{0, 0, 0};
  double radius_mm = 12.0;   // grasped patch around the region point
  double min_displacement_mm = 5.0;
  double max_force_N = 2.0;
  double time_limit_s = 3.0;
};

struct LessonStep {
  StepKind kind = StepKind::say;
  std::string where;         // FILE:LINE:COLUMN of the step
  std::string title, hint;
  std::string text;          // say
  std::vector<std::string> organs;  // highlight / hide / show / isolate / label; pick: [organ]
  CameraSpec camera;
  PullTask pull;
  double wait_s = 0.0;
};

struct Lesson {
  std::string file;
  std::string title;
  std::string organ_set_path;  // resolved against the lesson's folder
  std::vector<std::string> organs, context;
  PhysicsSettings physics;
  std::vector<LessonStep> steps;
  io::OrganSet set;            // loaded and checked against the names above
  int task_count() const;
};

// Reads, validates and loads the organ set of a lesson. Throws InputError on the first problem.
Lesson load_lesson(const std::string& path);

// Device script: one action per task (pull / pick / wait) of the lesson, in order.
struct ScriptAction {
  StepKind kind = StepKind::wait;
  std::string where;
  bool force_mode = false;
  std::vector<Keyframe> keys;          // pull: offsets (m) or forces (N)
  bool has_click_mm = false;
  Eigen::Vector3d click_mm{0, 0, 0};   // pick: the world point the user clicks on
  bool has_click_px = false;
  Eigen::Vector2d click_px{0, 0};
};

struct DeviceScript {
  std::string file;
  double max_force_N = 4.0;
  double ramp_s = 0.05;
  std::vector<ScriptAction> actions;
};

DeviceScript load_device_script(const std::string& path);
// The script's actions must match the lesson's tasks one to one (kind by kind).
void check_script_matches(const DeviceScript& script, const Lesson& lesson);

}  // namespace softatlas::app
