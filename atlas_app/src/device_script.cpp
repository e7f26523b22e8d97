#include <algorithm>

#include "softatlas/app/lesson.hpp"
#include "softatlas/io/mesh_io.hpp"
#include "yaml_check.hpp"

namespace softatlas::app {

using yamlcheck::Ctx;

namespace {

const char* action_name(StepKind k) { return k == StepKind::question ? "answer" : to_string(k); }

void parse_pull(const Ctx& c, const YAML::Node& p, ScriptAction& a) {
  c.keys(p, "pull", {"mode", "timeline"});
  c.guard([&] {
    if (!p["mode"]) return;
    const std::string m = c.str(p["mode"], "mode");
    if (m != "position" && m != "force") c.fail(p["mode"], "mode must be 'position' or 'force', got '" + m + "'");
    a.force_mode = m == "force";
  });
  const YAML::Node tl = c.require(p, "timeline", "pull");
  if (!tl.IsSequence() || tl.size() == 0)
    c.fail(tl, "'timeline' must be a non-empty list of {t_s, offset_mm} or {t_s, force_N}");
  double last_t = -1;
  for (const auto& k : tl) {
    c.guard([&] {
      c.keys(k, "timeline entry", {"t_s", "offset_mm", "force_N"});
      Keyframe kf;
      kf.t_s = c.num(c.require(k, "t_s", "timeline entry"), "t_s", 0, 600);
      if (kf.t_s <= last_t)
        c.fail(k["t_s"], "timeline times must increase, got " + k["t_s"].Scalar() + " after " + Ctx::fmt(last_t));
      last_t = kf.t_s;
      const char* key = a.force_mode ? "force_N" : "offset_mm";
      const char* other = a.force_mode ? "offset_mm" : "force_N";
      if (k[other])
        c.fail(k[other], std::string("'") + other + "' does not fit mode " + (a.force_mode ? "force" : "position") +
                             " (use '" + key + "')");
      const auto v =
          c.vec(c.require(k, key, "timeline entry"), key, 3, a.force_mode ? -100 : -500, a.force_mode ? 100 : 500);
      // offsets are written in mm (the user's unit) and kept in m (the core's)
      const double s = a.force_mode ? 1.0 : 1e-3;
      kf.value = {v[0] * s, v[1] * s, v[2] * s};
      a.keys.push_back(kf);
    });
  }
}

}  // namespace

DeviceScript load_device_script(const std::string& path) {
  DeviceScript d;
  d.file = path;
  const Ctx c{path, {}};
  const YAML::Node root = yamlcheck::load_file(c, io::read_text_file(path));
  if (!c.errors.empty()) c.finish();
  if (!root || root.IsNull()) throw InputError(path, "empty device script (expected device, tasks)");
  c.guard([&] { c.keys(root, "the device script", {"device", "max_force_N", "ramp_s", "tasks"}); });
  if (!root.IsMap()) c.finish();
  c.guard([&] {
    const std::string kind = c.str(c.require(root, "device", "the device script"), "device");
    if (kind != "scripted") c.fail(root["device"], "device must be 'scripted' in a device script, got '" + kind + "'");
  });
  c.guard([&] {
    if (root["max_force_N"]) d.max_force_N = c.num(root["max_force_N"], "max_force_N", 0.01, 100);
  });
  c.guard([&] {
    if (root["ramp_s"]) d.ramp_s = c.num(root["ramp_s"], "ramp_s", 0, 2);
  });
  c.guard([&] {
    const YAML::Node tasks = c.require(root, "tasks", "the device script");
    if (!tasks.IsSequence()) c.fail(tasks, "'tasks' must be a list (one entry per pull, pick, wait or answer task)");
    for (size_t i = 0; i < tasks.size(); ++i) {
      const YAML::Node t = tasks[i];
      const std::string name = "tasks[" + std::to_string(i) + "]";
      ScriptAction a;
      a.where = c.at(t);
      c.guard([&] {
        c.keys(t, name, {"pull", "pick", "wait", "answer"});
        if (t.size() != 1) c.fail(t, name + " must have exactly one of pull, pick, wait, answer");
        if (t["pull"]) {
          a.kind = StepKind::pull;
          parse_pull(c, t["pull"], a);
        } else if (t["pick"]) {
          a.kind = StepKind::pick;
          const YAML::Node p = t["pick"];
          c.keys(p, "pick", {"click_mm", "click_px"});
          if (p["click_mm"]) {
            const auto v = c.vec(p["click_mm"], "click_mm", 3, -1e5, 1e5);
            a.has_click_mm = true;
            a.click_mm = {v[0], v[1], v[2]};
          } else if (p["click_px"]) {
            const auto v = c.vec(p["click_px"], "click_px", 2, 0, 16384);
            a.has_click_px = true;
            a.click_px = {v[0], v[1]};
          } else {
            c.fail(p, "pick needs 'click_mm' (a world point, mm) or 'click_px' (a pixel)");
          }
        } else if (t["answer"]) {
          a.kind = StepKind::question;
          const YAML::Node p = t["answer"];
          c.keys(p, "answer", {"choice"});
          a.choice = c.str(c.require(p, "choice", "answer"), "choice");
        } else if (t["wait"]) {
          a.kind = StepKind::wait;
          if (!t["wait"].IsNull()) c.keys(t["wait"], "wait", {});
        } else {  // an unknown key, reported above (a zombie node would throw)
          throw yamlcheck::Skip{};
        }
      });
      d.actions.push_back(std::move(a));
    }
  });
  c.finish();
  return d;
}

void check_script_matches(const DeviceScript& script, const Lesson& lesson) {
  std::vector<const LessonStep*> tasks;
  for (const LessonStep& s : lesson.steps)
    if (is_task(s.kind)) tasks.push_back(&s);
  // Every mismatch, in the script's file order; each names the script's task and the lesson's.
  std::vector<std::string> problems;
  auto list = [&]() {
    std::string l;
    for (size_t i = 0; i < tasks.size(); ++i)
      l += (i ? ", " : "") + std::to_string(i + 1) + " " + action_name(tasks[i]->kind);
    return l;
  };
  const size_t n = std::min(tasks.size(), script.actions.size());
  for (size_t i = 0; i < n; ++i) {
    const ScriptAction& a = script.actions[i];
    const LessonStep& t = *tasks[i];
    if (t.kind != a.kind) {
      problems.push_back(a.where + ": task " + std::to_string(i + 1) + " is '" + action_name(a.kind) +
                         "' but the lesson's task " + std::to_string(i + 1) + " (" + t.where + ") is '" +
                         action_name(t.kind) + "'");
    } else if (t.kind == StepKind::question &&
               std::find(t.question.choices.begin(), t.question.choices.end(), a.choice) == t.question.choices.end()) {
      std::string choices;
      for (const auto& ch : t.question.choices) choices += (choices.empty() ? "" : ", ") + ch;
      problems.push_back(a.where + ": task " + std::to_string(i + 1) + " answers '" + a.choice +
                         "', not one of the choices of the question at " + t.where + " (" + choices + ")");
    }
  }
  if (tasks.size() != script.actions.size()) {
    const std::string where = script.actions.size() > tasks.size() ? script.actions[tasks.size()].where : script.file;
    problems.push_back(where + ": the script has " + std::to_string(script.actions.size()) + " tasks but lesson " +
                       lesson.file + " has " + std::to_string(tasks.size()) + " (" + list() +
                       "), expected one entry per task in this order");
  }
  if (problems.empty()) return;
  // InputError(where, what): the first problem's location, then every line.
  const std::string& first = problems[0];
  const size_t colon = first.find(": ");
  std::string what = first.substr(colon + 2);
  for (size_t i = 1; i < problems.size(); ++i) what += "\n" + problems[i];
  throw InputError(first.substr(0, colon), what);
}

}  // namespace softatlas::app
