#include "softatlas/app/lesson.hpp"

#include <algorithm>
#include <filesystem>

#include "softatlas/io/mesh_io.hpp"
#include "yaml_check.hpp"

namespace softatlas::app {

using yamlcheck::Ctx;

const char* to_string(StepKind k) {
  switch (k) {
    case StepKind::say: return "say";
    case StepKind::camera: return "camera";
    case StepKind::highlight: return "highlight";
    case StepKind::hide: return "hide";
    case StepKind::show: return "show";
    case StepKind::isolate: return "isolate";
    case StepKind::label: return "label";
    case StepKind::pull: return "pull";
    case StepKind::pick: return "pick";
    case StepKind::wait: return "wait";
  }
  return "?";
}

int Lesson::task_count() const {
  return static_cast<int>(std::count_if(steps.begin(), steps.end(), [](const LessonStep& s) { return is_task(s.kind); }));
}

namespace {

const char* kRegions[] = {"anterior", "posterior", "superior", "inferior", "left", "right"};
const char* kViews[] = {"anterior", "posterior", "superior", "inferior", "left", "right"};

bool one_of(const std::string& s, const char* const* list, size_t n) {
  for (size_t i = 0; i < n; ++i)
    if (s == list[i]) return true;
  return false;
}

void parse_physics(const Ctx& c, const YAML::Node& n, PhysicsSettings& p) {
  c.keys(n, "scene.physics", {"model", "integrator", "dt_s", "gravity", "young_modulus_pa",
                              "elastica_b", "damping_scale", "max_tool_force_N"});
  if (n["model"]) {
    p.model = c.str(n["model"], "model");
    sim::ModelKind k;
    if (!sim::parse_model_kind(p.model, k)) c.fail(n["model"], "unknown model '" + p.model + "' (expected tmsm, cmsm, nmsm or flexion)");
  }
  if (n["integrator"]) {
    const std::string s = c.str(n["integrator"], "integrator");
    if (!sim::parse_integrator(s, p.integrator))
      c.fail(n["integrator"], "unknown integrator '" + s + "' (expected verlet, semi_implicit or implicit)");
  }
  if (n["dt_s"]) p.dt_s = c.num(n["dt_s"], "dt_s", 1e-5, 0.01);
  if (n["gravity"]) p.gravity = c.boolean(n["gravity"], "gravity");
  if (n["young_modulus_pa"]) p.young_modulus_pa = c.num(n["young_modulus_pa"], "young_modulus_pa", 10, 1e7);
  if (n["elastica_b"]) p.elastica_b = c.num(n["elastica_b"], "elastica_b", 0, 10);
  if (n["damping_scale"]) p.damping_scale = c.num(n["damping_scale"], "damping_scale", 0, 100);
  if (n["max_tool_force_N"]) p.max_tool_force_N = c.num(n["max_tool_force_N"], "max_tool_force_N", 0.01, 100);
}

LessonStep parse_step(const Ctx& c, const YAML::Node& n, size_t index) {
  LessonStep s;
  s.where = c.at(n);
  const std::string name = "steps[" + std::to_string(index) + "]";
  c.keys(n, name, {"say", "camera", "highlight", "hide", "show", "isolate", "label", "pull", "pick",
                   "wait", "hint", "title"});
  int actions = 0;
  for (const auto& kv : n) {
    const std::string k = kv.first.Scalar();
    if (k != "hint" && k != "title") ++actions;
  }
  if (actions != 1)
    c.fail(n, name + " must have exactly one action (say, camera, highlight, hide, show, isolate, "
                     "label, pull, pick or wait), found " + std::to_string(actions));
  if (n["hint"]) s.hint = c.str(n["hint"], "hint");
  if (n["title"]) s.title = c.str(n["title"], "title");
  if (n["say"]) {
    s.kind = StepKind::say;
    s.text = c.str(n["say"], "say");
  } else if (n["camera"]) {
    s.kind = StepKind::camera;
    const YAML::Node m = n["camera"];
    c.keys(m, "camera", {"view", "target", "distance_mm", "yaw_deg", "pitch_deg"});
    if (m["view"]) {
      s.camera.view = c.str(m["view"], "view");
      if (!one_of(s.camera.view, kViews, 6))
        c.fail(m["view"], "unknown view '" + s.camera.view + "' (expected anterior, posterior, superior, inferior, left or right)");
    }
    if (m["target"]) s.camera.target = c.str(m["target"], "target");
    if (m["distance_mm"]) s.camera.distance_mm = c.num(m["distance_mm"], "distance_mm", 10, 10000);
    if (m["yaw_deg"]) s.camera.yaw_deg = c.num(m["yaw_deg"], "yaw_deg", -360, 360);
    if (m["pitch_deg"]) s.camera.pitch_deg = c.num(m["pitch_deg"], "pitch_deg", -89.9, 89.9);
  } else if (n["pull"]) {
    s.kind = StepKind::pull;
    const YAML::Node m = n["pull"];
    c.keys(m, "pull", {"organ", "region", "landmark_mm", "radius_mm", "min_displacement_mm",
                       "max_force_N", "time_limit_s"});
    s.pull.organ = c.str(c.require(m, "organ", "pull"), "organ");
    if (m["region"] && m["landmark_mm"]) c.fail(m, "pull takes either 'region' or 'landmark_mm', not both");
    if (m["region"]) {
      s.pull.region = c.str(m["region"], "region");
      if (!one_of(s.pull.region, kRegions, 6))
        c.fail(m["region"], "unknown region '" + s.pull.region + "' (expected anterior, posterior, superior, inferior, left or right)");
    } else if (m["landmark_mm"]) {
      const auto v = c.vec(m["landmark_mm"], "landmark_mm", 3, -1e5, 1e5);
      s.pull.has_landmark = true;
      s.pull.landmark_mm = {v[0], v[1], v[2]};
    } else {
      c.fail(m, "pull needs 'region' (anterior, posterior, superior, inferior, left, right) or 'landmark_mm'");
    }
    if (m["radius_mm"]) s.pull.radius_mm = c.num(m["radius_mm"], "radius_mm", 1, 100);
    s.pull.min_displacement_mm = c.num(c.require(m, "min_displacement_mm", "pull"), "min_displacement_mm", 0.1, 200);
    s.pull.max_force_N = c.num(c.require(m, "max_force_N", "pull"), "max_force_N", 0.001, 50);
    if (m["time_limit_s"]) s.pull.time_limit_s = c.num(m["time_limit_s"], "time_limit_s", 0.01, 60);
    s.organs = {s.pull.organ};
  } else if (n["pick"]) {
    s.kind = StepKind::pick;
    const YAML::Node m = n["pick"];
    c.keys(m, "pick", {"organ"});
    s.organs = {c.str(c.require(m, "organ", "pick"), "organ")};
  } else if (n["wait"]) {
    s.kind = StepKind::wait;
    const YAML::Node m = n["wait"];
    c.keys(m, "wait", {"seconds"});
    s.wait_s = c.num(c.require(m, "seconds", "wait"), "seconds", 0, 60);  // a lesson step, not a pause: at most a minute
  } else {
    const std::pair<const char*, StepKind> lists[] = {{"highlight", StepKind::highlight}, {"hide", StepKind::hide},
                                                      {"show", StepKind::show}, {"isolate", StepKind::isolate},
                                                      {"label", StepKind::label}};
    for (const auto& [key, kind] : lists)
      if (n[key]) {
        s.kind = kind;
        s.organs = c.names(n[key], key);
      }
  }
  return s;
}

}  // namespace

Lesson load_lesson(const std::string& path) {
  namespace fs = std::filesystem;
  Lesson L;
  L.file = path;
  const Ctx c{path};
  const YAML::Node root = yamlcheck::load_file(path, io::read_text_file(path));
  if (!root || root.IsNull()) throw InputError(path, "empty lesson (expected lesson, organ_set, scene, steps)");
  c.keys(root, "the lesson", {"lesson", "organ_set", "scene", "steps"});
  L.title = c.str(c.require(root, "lesson", "the lesson"), "lesson");
  const YAML::Node set_node = c.require(root, "organ_set", "the lesson");
  const std::string set_rel = c.str(set_node, "organ_set");
  fs::path set_path(set_rel);
  if (set_path.is_relative()) set_path = fs::path(path).parent_path() / set_path;
  L.organ_set_path = set_path.lexically_normal().string();

  const YAML::Node scene = c.require(root, "scene", "the lesson");
  c.keys(scene, "scene", {"organs", "context", "physics"});
  const YAML::Node organs_node = c.require(scene, "organs", "scene");
  L.organs = c.names(organs_node, "organs");
  if (scene["context"]) L.context = c.names(scene["context"], "context");
  if (scene["physics"]) parse_physics(c, scene["physics"], L.physics);

  const YAML::Node steps = c.require(root, "steps", "the lesson");
  if (!steps.IsSequence() || steps.size() == 0) c.fail(steps, "'steps' must be a non-empty list of steps");
  std::vector<YAML::Node> step_nodes;
  for (size_t i = 0; i < steps.size(); ++i) {
    L.steps.push_back(parse_step(c, steps[i], i));
    step_nodes.push_back(steps[i]);
  }

  // The organ set, then every organ name against it and against the scene.
  if (!fs::is_directory(L.organ_set_path))
    c.fail(set_node, "organ set folder '" + L.organ_set_path + "' does not exist (expected a folder with atlas.yaml)");
  try {
    L.set = io::read_organ_set(L.organ_set_path);
  } catch (const InputError& e) {
    c.fail(set_node, "cannot read organ set: " + std::string(e.what()));
  }
  std::string available;
  for (const auto& o : L.set.organs) available += (available.empty() ? "" : ", ") + o.name;
  auto check_in_set = [&](const YAML::Node& list_node, const std::vector<std::string>& names) {
    for (size_t i = 0; i < names.size(); ++i)
      if (L.set.index_of(names[i]) < 0)
        c.fail(list_node.IsSequence() ? list_node[i] : list_node,
               "organ '" + names[i] + "' is not in the organ set " + L.organ_set_path + " (it has: " + available + ")");
  };
  check_in_set(organs_node, L.organs);
  if (scene["context"]) check_in_set(scene["context"], L.context);
  for (const std::string& n : L.context)
    if (std::find(L.organs.begin(), L.organs.end(), n) != L.organs.end())
      c.fail(scene["context"], "organ '" + n + "' is listed in both organs and context");
  std::vector<std::string> in_view = L.organs;
  in_view.insert(in_view.end(), L.context.begin(), L.context.end());
  for (size_t i = 0; i < L.steps.size(); ++i) {
    const LessonStep& s = L.steps[i];
    std::vector<std::string> names = s.organs;
    if (s.kind == StepKind::camera && !s.camera.target.empty()) names.push_back(s.camera.target);
    for (const std::string& n : names) {
      if (L.set.index_of(n) < 0)
        c.fail(step_nodes[i], "organ '" + n + "' is not in the organ set " + L.organ_set_path + " (it has: " + available + ")");
      if (std::find(in_view.begin(), in_view.end(), n) == in_view.end())
        c.fail(step_nodes[i], "organ '" + n + "' is not in this lesson's scene (add it to scene.organs or scene.context)");
      if (s.kind == StepKind::pull && std::find(L.organs.begin(), L.organs.end(), n) == L.organs.end())
        c.fail(step_nodes[i], "pull needs a simulated organ: '" + n + "' must be in scene.organs, not context");
    }
  }
  return L;
}

}  // namespace softatlas::app
