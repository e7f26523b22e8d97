// Lessons (YAML, docs/lessons.md) and device scripts: parsed and validated once, on load.
// Every error is reported as FILE:LINE:COLUMN: message (from yaml-cpp's marks, 1-based) saying
// what was expected; a file's errors are collected and thrown together, in file order, as one
// InputError (yamlcheck::CheckErrors: what() holds one line per error).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "softatlas/app/haptics.hpp"
#include "softatlas/app/renderer.hpp"
#include "softatlas/app/scene.hpp"
#include "softatlas/io/organ_set.hpp"

namespace softatlas::app {

enum class StepKind { say, camera, highlight, hide, show, isolate, label, pull, pick, wait, question, slice };
const char* to_string(StepKind kind);
inline bool is_task(StepKind k) {
  return k == StepKind::pull || k == StepKind::pick || k == StepKind::wait || k == StepKind::question;
}

struct CameraSpec {
  std::string view;                       // anterior | posterior | left | right | superior | inferior | ""
  std::string target;                     // organ to centre on ("" = whole scene)
  double distance_mm = -1;                // < 0: fit
  double yaw_deg = 1e9, pitch_deg = 1e9;  // 1e9: not given
};

struct PullTask {
  std::string organ;
  // anterior | posterior | superior | inferior | left | right, or a named region of the organ
  // (the organ set's `regions`, e.g. gastric_impression): load_lesson turns a named region into
  // its landmark (has_landmark, landmark_mm) and keeps the name here.
  std::string region;
  bool has_landmark = false;
  Eigen::Vector3d landmark_mm{0, 0, 0};
  double radius_mm = 12.0;  // grasped patch around the region point
  double min_displacement_mm = 5.0;
  double max_force_N = 2.0;
  double time_limit_s = 3.0;
};

// Multiple choice: the student (or the device script's `answer`) picks one of `choices`.
struct QuestionTask {
  std::string ask;
  std::vector<std::string> choices;
  int answer = 0;  // index into choices
};

// A cut plane through the scene (sectional anatomy): axial (z = at_mm), coronal (y), sagittal (x).
struct SliceSpec {
  std::string plane;  // axial | coronal | sagittal
  double at_mm = 0.0;
};

struct LessonStep {
  StepKind kind = StepKind::say;
  std::string where;  // FILE:LINE:COLUMN of the step
  std::string title, hint;
  std::string text;                 // say
  std::vector<std::string> organs;  // highlight / hide / show / isolate / label; pick: [organ]
  CameraSpec camera;
  PullTask pull;
  double wait_s = 0.0;
  QuestionTask question;
  SliceSpec slice;
};

struct Lesson {
  std::string file;
  std::string title;
  std::string organ_set_path;  // resolved against the lesson's folder
  std::vector<std::string> organs, context;
  PhysicsSettings physics;
  std::vector<LessonStep> steps;
  io::OrganSet set;  // loaded and checked against the names above
  int task_count() const;
};

// Reads, validates and loads the organ set of a lesson. Throws InputError (yamlcheck::CheckErrors)
// with every problem found, in file order.
Lesson load_lesson(const std::string& path);

// The caption text of a question: the question, then its choices numbered 1.. (the chosen one,
// if any, marked).
std::string question_text(const QuestionTask& q, const std::string& chosen);
// The renderer's plane for a slice step.
SlicePlane slice_plane(const SliceSpec& s);
// `--slice PLANE:MM` (axial:1100, coronal:120, sagittal:-30); "" = no slice. Throws InputError.
SlicePlane parse_slice_option(const std::string& text);

// Device script: one action per task (pull / pick / wait / answer) of the lesson, in order.
struct ScriptAction {
  StepKind kind = StepKind::wait;
  std::string where;
  bool force_mode = false;
  std::vector<Keyframe> keys;  // pull: offsets (m) or forces (N)
  bool has_click_mm = false;
  Eigen::Vector3d click_mm{0, 0, 0};  // pick: the world point the user clicks on
  bool has_click_px = false;
  Eigen::Vector2d click_px{0, 0};
  std::string choice;  // answer: the chosen text
};

struct DeviceScript {
  std::string file;
  double max_force_N = 4.0;
  double ramp_s = 0.05;
  std::vector<ScriptAction> actions;
};

DeviceScript load_device_script(const std::string& path);
// The script's actions must match the lesson's tasks one to one (kind by kind); every mismatch is
// reported, in the script's file order, each naming both tasks.
void check_script_matches(const DeviceScript& script, const Lesson& lesson);

}  // namespace softatlas::app
