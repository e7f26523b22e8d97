#include "softatlas/app/lesson.hpp"

#include <algorithm>
#include <filesystem>

#include "softatlas/io/mesh_io.hpp"
#include "yaml_check.hpp"

namespace softatlas::app {

using yamlcheck::Ctx;

const char* to_string(StepKind k) {
  switch (k) {
    case StepKind::say:
      return "say";
    case StepKind::camera:
      return "camera";
    case StepKind::highlight:
      return "highlight";
    case StepKind::hide:
      return "hide";
    case StepKind::show:
      return "show";
    case StepKind::isolate:
      return "isolate";
    case StepKind::label:
      return "label";
    case StepKind::pull:
      return "pull";
    case StepKind::pick:
      return "pick";
    case StepKind::wait:
      return "wait";
    case StepKind::question:
      return "question";
    case StepKind::slice:
      return "slice";
  }
  return "?";
}

int Lesson::task_count() const {
  return static_cast<int>(
      std::count_if(steps.begin(), steps.end(), [](const LessonStep& s) { return is_task(s.kind); }));
}

std::string question_text(const QuestionTask& q, const std::string& chosen) {
  std::string t = q.ask;
  for (size_t i = 0; i < q.choices.size(); ++i)
    t += "\n  " + std::to_string(i + 1) + ") " + q.choices[i] + (q.choices[i] == chosen ? "   <- your answer" : "");
  return t;
}

SlicePlane slice_plane(const SliceSpec& s) {
  SlicePlane p;
  p.axis = s.plane == "sagittal" ? 0 : s.plane == "coronal" ? 1 : s.plane == "axial" ? 2 : -1;
  p.at_mm = static_cast<float>(s.at_mm);
  return p;
}

SlicePlane parse_slice_option(const std::string& text) {
  if (text.empty()) return {};
  const size_t colon = text.find(':');
  SliceSpec spec;
  spec.plane = text.substr(0, colon);
  const std::string mm = colon == std::string::npos ? "" : text.substr(colon + 1);
  const SlicePlane p = slice_plane(spec);
  if (colon == std::string::npos || p.axis < 0 || !yamlcheck::Ctx::is_number(mm))
    throw InputError(
        "--slice", "expected PLANE:MM with PLANE axial, coronal or sagittal and MM a number (e.g. axial:1100), got '" +
                       text + "'");
  spec.at_mm = std::stod(mm);
  return slice_plane(spec);
}

namespace {

const char* kRegions[] = {"anterior", "posterior", "superior", "inferior", "left", "right"};
const char* kViews[] = {"anterior", "posterior", "superior", "inferior", "left", "right"};
const char* kPlanes[] = {"axial", "coronal", "sagittal"};

bool one_of(const std::string& s, const char* const* list, size_t n) {
  for (size_t i = 0; i < n; ++i)
    if (s == list[i]) return true;
  return false;
}

void parse_physics(const Ctx& c, const YAML::Node& n, PhysicsSettings& p) {
  c.keys(n, "scene.physics",
         {"model", "integrator", "dt_s", "gravity", "young_modulus_pa", "elastica_b", "damping_scale",
          "max_tool_force_N"});
  c.guard([&] {
    if (!n["model"]) return;
    p.model = c.str(n["model"], "model");
    sim::ModelKind k;
    if (!sim::parse_model_kind(p.model, k))
      c.fail(n["model"], "unknown model '" + p.model + "' (expected tmsm, cmsm, nmsm or flexion)");
  });
  c.guard([&] {
    if (!n["integrator"]) return;
    const std::string s = c.str(n["integrator"], "integrator");
    if (!sim::parse_integrator(s, p.integrator))
      c.fail(n["integrator"], "unknown integrator '" + s + "' (expected verlet, semi_implicit or implicit)");
  });
  c.guard([&] {
    if (n["dt_s"]) p.dt_s = c.num(n["dt_s"], "dt_s", 1e-5, 0.01);
  });
  c.guard([&] {
    if (n["gravity"]) p.gravity = c.boolean(n["gravity"], "gravity");
  });
  c.guard([&] {
    if (n["young_modulus_pa"]) p.young_modulus_pa = c.num(n["young_modulus_pa"], "young_modulus_pa", 10, 1e7);
  });
  c.guard([&] {
    if (n["elastica_b"]) p.elastica_b = c.num(n["elastica_b"], "elastica_b", 0, 10);
  });
  c.guard([&] {
    if (n["damping_scale"]) p.damping_scale = c.num(n["damping_scale"], "damping_scale", 0, 100);
  });
  c.guard([&] {
    if (n["max_tool_force_N"]) p.max_tool_force_N = c.num(n["max_tool_force_N"], "max_tool_force_N", 0.01, 100);
  });
}

// Reads the optional field `key` of m with f, recording (not throwing) its errors.
template <class F>
void field(const Ctx& c, const YAML::Node& m, const char* key, F&& f) {
  c.guard([&] {
    if (m[key]) f(m[key]);
  });
}

LessonStep parse_step(const Ctx& c, const YAML::Node& n, size_t index) {
  LessonStep s;
  s.where = c.at(n);
  const std::string name = "steps[" + std::to_string(index) + "]";
  c.keys(n, name,
         {"say", "camera", "highlight", "hide", "show", "isolate", "label", "pull", "pick", "wait", "question", "slice",
          "hint", "title"});
  int actions = 0;
  for (const auto& kv : n) {
    const std::string k = kv.first.Scalar();
    if (k != "hint" && k != "title") ++actions;
  }
  if (actions != 1)
    c.fail(n, name +
                  " must have exactly one action (say, camera, highlight, hide, show, isolate, "
                  "label, pull, pick, wait, question or slice), found " +
                  std::to_string(actions));
  field(c, n, "hint", [&](const YAML::Node& v) { s.hint = c.str(v, "hint"); });
  field(c, n, "title", [&](const YAML::Node& v) { s.title = c.str(v, "title"); });
  if (n["say"]) {
    s.kind = StepKind::say;
    s.text = c.str(n["say"], "say");
  } else if (n["camera"]) {
    s.kind = StepKind::camera;
    const YAML::Node m = n["camera"];
    c.keys(m, "camera", {"view", "target", "distance_mm", "yaw_deg", "pitch_deg"});
    field(c, m, "view", [&](const YAML::Node& v) {
      s.camera.view = c.str(v, "view");
      if (!one_of(s.camera.view, kViews, 6))
        c.fail(v, "unknown view '" + s.camera.view +
                      "' (expected anterior, posterior, superior, inferior, left or right)");
    });
    field(c, m, "target", [&](const YAML::Node& v) { s.camera.target = c.str(v, "target"); });
    field(c, m, "distance_mm", [&](const YAML::Node& v) { s.camera.distance_mm = c.num(v, "distance_mm", 10, 10000); });
    field(c, m, "yaw_deg", [&](const YAML::Node& v) { s.camera.yaw_deg = c.num(v, "yaw_deg", -360, 360); });
    field(c, m, "pitch_deg", [&](const YAML::Node& v) { s.camera.pitch_deg = c.num(v, "pitch_deg", -89.9, 89.9); });
  } else if (n["pull"]) {
    s.kind = StepKind::pull;
    const YAML::Node m = n["pull"];
    c.keys(m, "pull",
           {"organ", "region", "landmark_mm", "radius_mm", "min_displacement_mm", "max_force_N", "time_limit_s"});
    c.guard([&] { s.pull.organ = c.str(c.require(m, "organ", "pull"), "organ"); });
    c.guard([&] {
      if (m["region"] && m["landmark_mm"]) c.fail(m, "pull takes either 'region' or 'landmark_mm', not both");
      if (m["region"]) {
        s.pull.region = c.str(m["region"], "region");  // a direction, or a named region (checked below)
      } else if (m["landmark_mm"]) {
        const auto v = c.vec(m["landmark_mm"], "landmark_mm", 3, -1e5, 1e5);
        s.pull.has_landmark = true;
        s.pull.landmark_mm = {v[0], v[1], v[2]};
      } else {
        c.fail(m, "pull needs 'region' (anterior, posterior, superior, inferior, left, right) or 'landmark_mm'");
      }
    });
    field(c, m, "radius_mm", [&](const YAML::Node& v) { s.pull.radius_mm = c.num(v, "radius_mm", 1, 100); });
    c.guard([&] {
      s.pull.min_displacement_mm = c.num(c.require(m, "min_displacement_mm", "pull"), "min_displacement_mm", 0.1, 200);
    });
    c.guard([&] { s.pull.max_force_N = c.num(c.require(m, "max_force_N", "pull"), "max_force_N", 0.001, 50); });
    field(c, m, "time_limit_s", [&](const YAML::Node& v) { s.pull.time_limit_s = c.num(v, "time_limit_s", 0.01, 60); });
    if (!s.pull.organ.empty()) s.organs = {s.pull.organ};
  } else if (n["pick"]) {
    s.kind = StepKind::pick;
    const YAML::Node m = n["pick"];
    c.keys(m, "pick", {"organ"});
    s.organs = {c.str(c.require(m, "organ", "pick"), "organ")};
  } else if (n["wait"]) {
    s.kind = StepKind::wait;
    const YAML::Node m = n["wait"];
    c.keys(m, "wait", {"seconds"});
    s.wait_s =
        c.num(c.require(m, "seconds", "wait"), "seconds", 0, 60);  // a lesson step, not a pause: at most a minute
  } else if (n["question"]) {
    s.kind = StepKind::question;
    const YAML::Node m = n["question"];
    c.keys(m, "question", {"ask", "choices", "answer"});
    c.guard([&] { s.question.ask = c.str(c.require(m, "ask", "question"), "ask"); });
    c.guard([&] {
      const YAML::Node ch = c.require(m, "choices", "question");
      if (!ch.IsSequence() || ch.size() < 2 || ch.size() > 8)
        c.fail(ch, "'choices' must be a list of 2 to 8 answers, e.g. [Liver, Stomach, Spleen]");
      for (const auto& e : ch) {
        const std::string t = c.str(e, "choices");
        if (std::find(s.question.choices.begin(), s.question.choices.end(), t) != s.question.choices.end())
          c.report(e, "choice '" + t + "' is listed twice");
        s.question.choices.push_back(t);
      }
      const YAML::Node a = c.require(m, "answer", "question");
      const std::string t = c.str(a, "answer");
      const auto it = std::find(s.question.choices.begin(), s.question.choices.end(), t);
      if (it == s.question.choices.end()) c.fail(a, "answer '" + t + "' is not one of the choices");
      s.question.answer = static_cast<int>(it - s.question.choices.begin());
    });
  } else if (n["slice"]) {
    s.kind = StepKind::slice;
    const YAML::Node m = n["slice"];
    c.keys(m, "slice", {"plane", "at_mm"});
    c.guard([&] {
      const YAML::Node p = c.require(m, "plane", "slice");
      s.slice.plane = c.str(p, "plane");
      if (!one_of(s.slice.plane, kPlanes, 3))
        c.fail(p, "unknown plane '" + s.slice.plane + "' (expected axial, coronal or sagittal)");
    });
    c.guard([&] { s.slice.at_mm = c.num(c.require(m, "at_mm", "slice"), "at_mm", -1e5, 1e5); });
  } else {
    const std::pair<const char*, StepKind> lists[] = {{"highlight", StepKind::highlight},
                                                      {"hide", StepKind::hide},
                                                      {"show", StepKind::show},
                                                      {"isolate", StepKind::isolate},
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
  const Ctx c{path, {}};
  const YAML::Node root = yamlcheck::load_file(c, io::read_text_file(path));
  if (!c.errors.empty()) c.finish();
  if (!root || root.IsNull()) throw InputError(path, "empty lesson (expected lesson, organ_set, scene, steps)");
  c.guard([&] { c.keys(root, "the lesson", {"lesson", "organ_set", "scene", "steps"}); });
  if (!root.IsMap()) c.finish();  // not a map: nothing else can be read
  c.guard([&] { L.title = c.str(c.require(root, "lesson", "the lesson"), "lesson"); });
  YAML::Node set_node;
  c.guard([&] {
    set_node = c.require(root, "organ_set", "the lesson");
    const std::string set_rel = c.str(set_node, "organ_set");
    fs::path set_path(set_rel);
    if (set_path.is_relative()) set_path = fs::path(path).parent_path() / set_path;
    L.organ_set_path = set_path.lexically_normal().string();
  });

  YAML::Node scene, organs_node;
  c.guard([&] {
    scene = c.require(root, "scene", "the lesson");
    c.keys(scene, "scene", {"organs", "context", "physics"});
    c.guard([&] {
      organs_node = c.require(scene, "organs", "scene");
      L.organs = c.names(organs_node, "organs");
    });
    field(c, scene, "context", [&](const YAML::Node& v) { L.context = c.names(v, "context"); });
    field(c, scene, "physics", [&](const YAML::Node& v) { parse_physics(c, v, L.physics); });
  });

  std::vector<YAML::Node> step_nodes;
  c.guard([&] {
    const YAML::Node steps = c.require(root, "steps", "the lesson");
    if (!steps.IsSequence() || steps.size() == 0) c.fail(steps, "'steps' must be a non-empty list of steps");
    for (size_t i = 0; i < steps.size(); ++i) {
      LessonStep st;
      st.where = c.at(steps[i]);
      c.guard([&] { st = parse_step(c, steps[i], i); });
      L.steps.push_back(st);
      step_nodes.push_back(steps[i]);
    }
  });

  // The organ set, then every organ name against it and against the scene.
  bool have_set = false;
  c.guard([&] {
    if (L.organ_set_path.empty()) return;
    if (!fs::is_directory(L.organ_set_path))
      c.fail(set_node,
             "organ set folder '" + L.organ_set_path + "' does not exist (expected a folder with atlas.yaml)");
    try {
      L.set = io::read_organ_set(L.organ_set_path);
      have_set = true;
    } catch (const InputError& e) {
      c.fail(set_node, "cannot read organ set: " + std::string(e.what()));
    }
  });
  if (!have_set) c.finish();
  if (!have_set) return L;  // organ_set missing: its own error was reported above
  std::string available;
  for (const auto& o : L.set.organs) available += (available.empty() ? "" : ", ") + o.name;
  auto check_in_set = [&](const YAML::Node& list_node, const std::vector<std::string>& names) {
    for (size_t i = 0; i < names.size(); ++i)
      if (L.set.index_of(names[i]) < 0)
        c.report(
            list_node.IsSequence() && i < list_node.size() ? list_node[i] : list_node,
            "organ '" + names[i] + "' is not in the organ set " + L.organ_set_path + " (it has: " + available + ")");
  };
  if (organs_node) check_in_set(organs_node, L.organs);
  if (scene && scene.IsMap() && scene["context"])
    check_in_set(scene["context"], L.context);  // scene: 3 is reported above
  for (const std::string& n : L.context)
    if (std::find(L.organs.begin(), L.organs.end(), n) != L.organs.end())
      c.report(scene["context"], "organ '" + n + "' is listed in both organs and context");
  std::vector<std::string> in_view = L.organs;
  in_view.insert(in_view.end(), L.context.begin(), L.context.end());
  for (size_t i = 0; i < L.steps.size(); ++i) {
    const LessonStep& s = L.steps[i];
    std::vector<std::string> names = s.organs;
    if (s.kind == StepKind::camera && !s.camera.target.empty()) names.push_back(s.camera.target);
    for (const std::string& n : names) {
      if (L.set.index_of(n) < 0) {
        c.report(step_nodes[i],
                 "organ '" + n + "' is not in the organ set " + L.organ_set_path + " (it has: " + available + ")");
        continue;
      }
      if (std::find(in_view.begin(), in_view.end(), n) == in_view.end())
        c.report(step_nodes[i],
                 "organ '" + n + "' is not in this lesson's scene (add it to scene.organs or scene.context)");
      else if (s.kind == StepKind::pull && std::find(L.organs.begin(), L.organs.end(), n) == L.organs.end())
        c.report(step_nodes[i], "pull needs a simulated organ: '" + n + "' must be in scene.organs, not context");
    }
    // A pull's region: one of the six directions, or a named region of its organ (a landmark).
    if (s.kind == StepKind::pull && !s.pull.region.empty() && !one_of(s.pull.region, kRegions, 6)) {
      const YAML::Node where = step_nodes[i]["pull"]["region"];
      const io::OrganEntry* o = L.set.find(s.pull.organ);
      const std::array<double, 3>* p = o ? o->find_region(s.pull.region) : nullptr;
      if (p) {
        LessonStep& w = L.steps[i];
        w.pull.has_landmark = true;
        w.pull.landmark_mm = {(*p)[0], (*p)[1], (*p)[2]};
      } else {
        std::string named;
        if (o)
          for (const auto& [rn, q] : o->regions) named += (named.empty() ? "" : ", ") + rn;
        c.report(
            where,
            "unknown region '" + s.pull.region + "' (expected anterior, posterior, superior, inferior, left or right" +
                (named.empty() ? std::string(")") : ", or a named region of " + s.pull.organ + ": " + named + ")"));
      }
    }
  }
  c.finish();
  return L;
}

}  // namespace softatlas::app
