// `softatlas export SET --web DIR`: a static folder any web server can serve. The physics scene
// is the one io::scene_from_organ_set() builds for the native programs, written as JSON with
// round-trip doubles, so the page's WebAssembly build of sim/ compiles exactly the same model.
#include "softatlas/pipeline/export_web.hpp"

#include <yaml-cpp/yaml.h>

#include <cstdlib>
#include <filesystem>
#include <algorithm>
#include <fstream>
#include <nlohmann/json.hpp>

#include "softatlas/io/organ_set.hpp"
#include "softatlas/io/scene.hpp"
#include "softatlas/pipeline/build.hpp"
#include "softatlas/sim/error.hpp"

#ifndef SOFTATLAS_WEB_DIST
#define SOFTATLAS_WEB_DIST ""
#endif

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace softatlas::pipeline {
namespace {

const char* const kPageFiles[] = {"index.html", "app.js", "worker.js", "softatlas_sim.mjs", "softatlas_sim.wasm"};

json material_json(const sim::Material& m) {
  return {{"model", sim::to_string(m.model)},
          {"elastica_p", m.elastica_p},
          {"young_modulus_pa", m.young_modulus_pa},
          {"thickness_m", m.thickness_m},
          {"total_mass_kg", m.total_mass_kg},
          {"density_kg_m3", m.density_kg_m3},
          {"stiffness", m.stiffness},
          {"damping", m.damping},
          {"damping_scale", m.damping_scale},
          {"vertex_mass_kg", m.vertex_mass_kg},
          {"elastica_a", m.elastica_a},
          {"elastica_b", m.elastica_b},
          {"curvature_unit_m", m.curvature_unit_m},
          {"elastica_cap", m.elastica_cap},
          {"tau_s", m.tau_s},
          {"tau_c", m.tau_c},
          {"flexion_stiffness", m.flexion_stiffness},
          {"volume_stiffness", m.volume_stiffness}};
}

json scene_json(const io::OrganSet& set, const sim::SceneDesc& d) {
  json organs = json::array();
  for (size_t i = 0; i < d.organs.size(); ++i) {
    const sim::OrganDesc& o = d.organs[i];
    const io::OrganEntry& e = set.organs[i];  // scene_from_organ_set keeps the set's order
    organs.push_back({{"name", o.name},
                      {"label", e.label},
                      {"fma", e.fma},
                      {"color", {e.color[0], e.color[1], e.color[2]}},
                      {"shown", o.shown},
                      {"vertices", o.vertices},
                      {"faces", o.faces},
                      {"fixed", o.fixed},
                      {"material", material_json(o.material)}});
  }
  json connections = json::array();
  for (const sim::ConnectionDesc& c : d.connections)
    connections.push_back({{"organ_a", c.organ_a},
                           {"vertex_a", c.vertex_a},
                           {"organ_b", c.organ_b},
                           {"vertex_b", c.vertex_b},
                           {"rest_length_m", c.rest_length_m},
                           {"stiffness", c.stiffness}});
  return {{"softatlas_web_scene", 1},
          {"units", "m"},
          {"space", set.space},
          {"settings",
           {{"integrator", sim::to_string(d.integrator)},
            {"dt_s", d.dt_s},
            {"gravity", d.gravity},
            {"gravity_m_s2", d.gravity_m_s2},
            {"cg_iterations", d.cg_iterations},
            {"cg_tolerance", d.cg_tolerance},
            {"guard", d.guard},
            {"max_tool_force_N", d.max_tool_force_N},
            {"max_substeps", d.max_substeps},
            {"allow_sleep", d.allow_sleep},
            {"sleep_speed_m_s", d.sleep_speed_m_s},
            {"sleep_steps", d.sleep_steps}}},
          {"organs", organs},
          {"connections", connections}};
}

// YAML -> JSON: maps and sequences as they are; scalars as booleans or numbers when they parse
// as such (plain style), else strings.
json yaml_to_json(const YAML::Node& n) {
  switch (n.Type()) {
    case YAML::NodeType::Map: {
      json out = json::object();
      for (const auto& kv : n) out[kv.first.as<std::string>()] = yaml_to_json(kv.second);
      return out;
    }
    case YAML::NodeType::Sequence: {
      json out = json::array();
      for (const auto& item : n) out.push_back(yaml_to_json(item));
      return out;
    }
    case YAML::NodeType::Scalar: {
      if (n.Tag() != "!") {  // plain (unquoted) scalars may be numbers or booleans
        bool b;
        if (YAML::convert<bool>::decode(n, b)) return b;
        long long i;
        if (YAML::convert<long long>::decode(n, i)) return i;
        double v;
        if (YAML::convert<double>::decode(n, v)) return v;
      }
      return n.Scalar();
    }
    default:
      return nullptr;
  }
}

// Lessons (SET/lessons/*.yaml, SET/../lessons/*.yaml) whose organ_set names SET.
json lessons_json(const fs::path& set) {
  json lessons = json::array();
  const fs::path canon = fs::weakly_canonical(set);
  for (const fs::path& dir : {set / "lessons", set.parent_path() / "lessons"}) {
    std::error_code ec;
    if (!fs::is_directory(dir, ec)) continue;
    std::vector<fs::path> files;
    for (const auto& f : fs::directory_iterator(dir))
      if (f.path().extension() == ".yaml") files.push_back(f.path());
    std::sort(files.begin(), files.end());
    for (const fs::path& f : files) {
      YAML::Node doc;
      try {
        doc = YAML::LoadFile(f.string());
      } catch (const YAML::Exception& e) {
        throw InputError(f.string() + ":" + std::to_string(e.mark.line + 1), "not valid YAML: " + e.msg);
      }
      if (!doc.IsMap() || !doc["organ_set"] || !doc["organ_set"].IsScalar()) continue;  // not a lesson
      if (fs::weakly_canonical(f.parent_path() / doc["organ_set"].Scalar()) != canon) continue;
      json l = yaml_to_json(doc);
      l["file"] = f.filename().string();
      lessons.push_back(std::move(l));
    }
  }
  return lessons;
}

void write_text(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  if (!out.flush()) throw InputError(path.string(), "cannot write the file");
}

}  // namespace

std::string web_dist_folder() {
  const char* env = std::getenv("SOFTATLAS_WEB_DIST");
  for (const std::string& dir : {std::string(env ? env : ""), std::string(SOFTATLAS_WEB_DIST)})
    if (!dir.empty() && fs::exists(fs::path(dir) / "index.html")) return dir;
  return "";
}

void export_web(const std::string& set_folder, const std::string& out_folder, const std::string& dist) {
  if (dist.empty())
    throw InputError("--web",
                     "the web page is not built (run scripts/build-web, or set SOFTATLAS_WEB_DIST to its "
                     "dist folder)");
  for (const char* f : kPageFiles)
    if (!fs::exists(fs::path(dist) / f))
      throw InputError(dist, std::string("the built page lacks ") + f + " (run scripts/build-web)");
  const fs::path out = fs::path(out_folder).lexically_normal();
  if (fs::exists(out) && !(fs::is_directory(out) && fs::exists(out / "scene.json")))
    throw InputError(out_folder, "exists and is not a previous web export (no scene.json): choose a new folder");

  const io::OrganSet set = io::read_organ_set(set_folder);
  const sim::SceneDesc scene = io::scene_from_organ_set(set, io::SceneOptions{});
  const json lessons = lessons_json(fs::path(set_folder));

  const fs::path tmp = out.string() + ".tmp-web";
  std::error_code ec;
  fs::remove_all(tmp, ec);
  try {
    fs::create_directories(tmp);
    for (const char* f : kPageFiles) fs::copy_file(fs::path(dist) / f, tmp / f);
    export_gltf(set_folder, (tmp / "atlas.glb").string());
    write_text(tmp / "scene.json", scene_json(set, scene).dump());
    write_text(tmp / "lessons.json", lessons.dump(1));
    fs::remove_all(out, ec);
    fs::rename(tmp, out);
  } catch (const fs::filesystem_error& e) {  // a full disk, a read-only folder: one line, nothing left
    fs::remove_all(tmp, ec);
    throw InputError(out_folder, "cannot write the web page: " + e.code().message());
  } catch (...) {
    fs::remove_all(tmp, ec);
    throw;
  }
}

}  // namespace softatlas::pipeline
