// atlas.yaml + organs/*.ply + connections.csv (docs/organ-set.md).
#include "softatlas/io/organ_set.hpp"
#include "softatlas/io/output_folder.hpp"
#include "softatlas/io/ct_image.hpp"

#include <yaml-cpp/yaml.h>
#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <set>
#include <sstream>

#include "softatlas/sim/error.hpp"

namespace softatlas::io {
namespace fs = std::filesystem;

namespace {

std::string at(const std::string& file, const YAML::Node& node) {
  const YAML::Mark mk = node.Mark();
  if (mk.line < 0) return file;
  return file + ":" + std::to_string(mk.line + 1) + ":" + std::to_string(mk.column + 1);
}

void check_keys(const std::string& file, const YAML::Node& map, const std::set<std::string>& allowed,
                const std::string& what) {
  if (!map.IsMap()) throw InputError(at(file, map), what + ": expected a map");
  for (const auto& kv : map) {
    if (!kv.first.IsScalar())
      throw InputError(at(file, kv.first), "a key in " + what + " is a list or a map; expected a name");
    const std::string key = kv.first.as<std::string>();
    if (!allowed.count(key)) {
      std::string list;
      for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
      throw InputError(at(file, kv.first),
                       "unknown key '" + printable_text(key) + "' in " + what + " (expected one of: " + list + ")");
    }
  }
}

template <typename T>
T get(const std::string& file, const YAML::Node& node, const char* expected) {
  try {
    return node.as<T>();
  } catch (const YAML::Exception&) {
    throw InputError(at(file, node), std::string("expected ") + expected);
  }
}

double get_number(const std::string& file, const YAML::Node& node, const std::string& field) {
  const double v = get<double>(file, node, ("a number for '" + field + "'").c_str());
  if (!std::isfinite(v)) throw InputError(at(file, node), "'" + field + "' must be finite");
  return v;
}

void read_material(const std::string& file, const YAML::Node& node, MaterialSpec& m) {
  check_keys(file, node,
             {"model", "young_modulus_pa", "thickness_m", "density_kg_m3", "damping_scale", "elastica_a", "elastica_b",
              "elastica_p", "tau_s", "tau_c", "flexion_stiffness", "volume_stiffness", "poisson_ratio", "damping_ratio",
              "solid_nodes"},
             "material");
  if (node["model"]) {
    m.model = get<std::string>(file, node["model"], "a model name");
    if (m.model != "tmsm" && m.model != "cmsm" && m.model != "nmsm" && m.model != "flexion" && m.model != "solid" &&
        m.model != "rigid")
      throw InputError(at(file, node["model"]), "unknown model '" + printable_text(m.model) +
                                                    "' (expected tmsm, cmsm, nmsm, flexion, solid or rigid)");
  }
  auto num = [&](const char* key, double& out, double lo, bool strict) {
    if (!node[key]) return;
    out = get_number(file, node[key], key);
    if (strict ? !(out > lo) : !(out >= lo))
      throw InputError(at(file, node[key]),
                       std::string("'") + key + "' must be " + (strict ? "> " : ">= ") + std::to_string(lo));
  };
  num("young_modulus_pa", m.young_modulus_pa, 0.0, false);
  num("thickness_m", m.thickness_m, 0.0, true);
  num("density_kg_m3", m.density_kg_m3, 0.0, true);
  num("damping_scale", m.damping_scale, 0.0, false);
  num("elastica_a", m.elastica_a, 0.0, true);
  num("elastica_b", m.elastica_b, 0.0, false);
  num("tau_s", m.tau_s, -1.0, false);
  num("tau_c", m.tau_c, -1.0, false);
  num("flexion_stiffness", m.flexion_stiffness, 0.0, false);
  num("volume_stiffness", m.volume_stiffness, 0.0, false);
  num("damping_ratio", m.damping_ratio, 0.0, false);
  if (node["poisson_ratio"]) {
    m.poisson_ratio = get_number(file, node["poisson_ratio"], "poisson_ratio");
    if (!(m.poisson_ratio > -1.0 && m.poisson_ratio < 0.5))
      throw InputError(at(file, node["poisson_ratio"]), "'poisson_ratio' must lie in (-1, 0.5)");
  }
  if (node["solid_nodes"]) {
    m.solid_nodes = get<int>(file, node["solid_nodes"], "an integer node budget");
    if (m.solid_nodes < 0) throw InputError(at(file, node["solid_nodes"]), "'solid_nodes' must be >= 0");
  }
  if (node["elastica_p"]) {
    m.elastica_p = get<int>(file, node["elastica_p"], "an integer p (1 or 2)");
    if (m.elastica_p != 1 && m.elastica_p != 2)
      throw InputError(at(file, node["elastica_p"]), "elastica_p must be 1 or 2");
  }
}

std::string yaml_escape(const std::string& s) {
  YAML::Emitter e;
  e << s;
  return e.c_str();
}

}  // namespace

const OrganEntry* OrganSet::find(const std::string& name) const {
  for (const OrganEntry& o : organs)
    if (o.name == name) return &o;
  return nullptr;
}

std::string OrganSet::ct_path() const {
  if (!ct) return "";
  return (fs::path(folder) / ct->file).string();
}

int OrganSet::index_of(const std::string& name) const {
  for (size_t i = 0; i < organs.size(); ++i)
    if (organs[i].name == name) return static_cast<int>(i);
  return -1;
}

std::array<float, 3> default_organ_color(const std::string& name) {
  struct Entry {
    const char* key;
    std::array<float, 3> rgb;
  };
  static const Entry table[] = {
      {"liver", {0.62f, 0.24f, 0.19f}},     {"spleen", {0.55f, 0.18f, 0.32f}},
      {"kidney", {0.72f, 0.38f, 0.27f}},    {"gallbladder", {0.35f, 0.55f, 0.25f}},
      {"stomach", {0.88f, 0.66f, 0.55f}},   {"pancreas", {0.93f, 0.78f, 0.45f}},
      {"lung", {0.95f, 0.72f, 0.72f}},      {"heart", {0.78f, 0.16f, 0.16f}},
      {"aorta", {0.86f, 0.12f, 0.12f}},     {"pulmonary_artery", {0.30f, 0.35f, 0.80f}},
      {"vena_cava", {0.25f, 0.35f, 0.78f}}, {"portal_vein", {0.35f, 0.40f, 0.85f}},
      {"trachea", {0.75f, 0.85f, 0.90f}},   {"diaphragm", {0.80f, 0.55f, 0.50f}},
      {"colon", {0.80f, 0.62f, 0.45f}},     {"esophagus", {0.85f, 0.60f, 0.55f}},
      {"adrenal", {0.90f, 0.70f, 0.30f}},   {"duodenum", {0.85f, 0.62f, 0.48f}},
      {"bladder", {0.85f, 0.80f, 0.45f}},   {"vertebra", {0.92f, 0.90f, 0.82f}},
      {"rib", {0.92f, 0.90f, 0.82f}},
  };
  for (const Entry& e : table)
    if (name.find(e.key) != std::string::npos) return e.rgb;
  return {0.7f, 0.7f, 0.7f};
}

std::string format_connections_csv(const std::vector<Connection>& connections) {
  std::ostringstream os;
  os.precision(17);
  os << "organ_a,vertex_a,organ_b,vertex_b,rest_length_mm,stiffness\n";
  for (const Connection& c : connections)
    os << c.organ_a << ',' << c.vertex_a << ',' << c.organ_b << ',' << c.vertex_b << ',' << c.rest_length_mm << ','
       << c.stiffness << '\n';
  return os.str();
}

namespace {

// A whole decimal integer token in int range ("12abc", "1e999", " 3", "" are not).
bool strict_int(const std::string& t, int* out) {
  if (t.empty() || t.size() > 11) return false;
  char* end = nullptr;
  errno = 0;
  const long v = std::strtol(t.c_str(), &end, 10);
  if (end != t.c_str() + t.size() || errno == ERANGE || v < INT32_MIN || v > INT32_MAX ||
      std::isspace(static_cast<unsigned char>(t[0])))
    return false;
  *out = static_cast<int>(v);
  return true;
}

// A whole finite number token.
bool strict_double(const std::string& t, double* out) {
  if (t.empty() || std::isspace(static_cast<unsigned char>(t[0]))) return false;
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(t.c_str(), &end);
  if (end != t.c_str() + t.size() || !std::isfinite(v)) return false;
  *out = v;
  return true;
}

}  // namespace

std::vector<Connection> parse_connections_csv(const std::string& raw, const std::string& path) {
  // Line endings: LF, CRLF and CR-only (old Mac editors) are all line breaks.
  std::string text;
  text.reserve(raw.size());
  for (size_t i = 0; i < raw.size(); ++i) {
    if (raw[i] == '\r') {
      text += '\n';
      if (i + 1 < raw.size() && raw[i + 1] == '\n') ++i;
    } else {
      text += raw[i];
    }
  }
  std::vector<Connection> out;
  std::istringstream in(text);
  std::string line;
  long line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (line_no == 1) {
      if (line.rfind("organ_a", 0) != 0)
        throw InputError(path + ":1",
                         "expected the header 'organ_a,vertex_a,organ_b,vertex_b,rest_length_mm,stiffness'");
      continue;
    }
    if (line.empty()) continue;
    std::vector<std::string> f;
    size_t start = 0;
    while (true) {
      const size_t comma = line.find(',', start);
      f.push_back(line.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
      if (comma == std::string::npos) break;
      start = comma + 1;
    }
    const std::string where = path + ":" + std::to_string(line_no);
    if (f.size() != 6) throw InputError(where, "expected 6 comma-separated fields, got " + std::to_string(f.size()));
    Connection c;
    c.organ_a = f[0];
    c.organ_b = f[2];
    static const char* kField[] = {"organ_a", "vertex_a", "organ_b", "vertex_b", "rest_length_mm", "stiffness"};
    for (int k : {1, 3})
      if (!strict_int(f[k], k == 1 ? &c.vertex_a : &c.vertex_b))
        throw InputError(where, std::string(kField[k]) + ": expected a whole integer vertex index, got '" +
                                    printable_text(f[k]) + "'");
    for (int k : {4, 5})
      if (!strict_double(f[k], k == 4 ? &c.rest_length_mm : &c.stiffness))
        throw InputError(where,
                         std::string(kField[k]) + ": expected a finite number, got '" + printable_text(f[k]) + "'");
    if (c.rest_length_mm < 0) throw InputError(where, "rest_length_mm must be a finite value >= 0");
    if (c.stiffness < 0) throw InputError(where, "stiffness must be a finite value >= 0");
    out.push_back(c);
  }
  if (line_no == 0) throw InputError(path, "empty file: expected a header line");
  return out;
}

OrganSet read_organ_set(const std::string& folder) {
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) throw InputError(folder, "not an organ-set folder");
  const std::string file = (fs::path(folder) / "atlas.yaml").string();
  if (!fs::exists(file, ec)) throw InputError(file, "missing: an organ set needs atlas.yaml");
  YAML::Node root;
  try {
    root = YAML::LoadFile(file);
  } catch (const YAML::ParserException& e) {
    throw InputError(file + ":" + std::to_string(e.mark.line + 1) + ":" + std::to_string(e.mark.column + 1),
                     printable_text(e.msg, 200));
  } catch (const YAML::Exception& e) {
    throw InputError(file, printable_text(e.what(), 200));
  }
  check_keys(file, root,
             {"softatlas_organ_set", "units", "space", "organs", "connections", "provenance", "quality", "ct"},
             "atlas.yaml");
  // The format version: this reader knows version 1 (docs/organ-set.md).
  if (!root["softatlas_organ_set"]) throw InputError(file, "missing 'softatlas_organ_set: 1' (the format version)");
  {
    const YAML::Node& vn = root["softatlas_organ_set"];
    int version = 0;
    if (!vn.IsScalar() || !strict_int(vn.Scalar(), &version))
      throw InputError(at(file, vn), "softatlas_organ_set: expected the format version 1");
    if (version != 1)
      throw InputError(at(file, vn), "softatlas_organ_set: format version " + std::to_string(version) +
                                         " is not supported (this softatlas reads version 1)");
  }
  OrganSet set;
  set.folder = folder;
  if (root["units"]) {
    set.units = get<std::string>(file, root["units"], "a unit name");
    if (set.units != "mm") throw InputError(at(file, root["units"]), "units must be 'mm'");
  }
  if (root["space"]) set.space = get<std::string>(file, root["space"], "a space name (RAS)");
  if (!root["organs"] || !root["organs"].IsSequence() || root["organs"].size() == 0)
    throw InputError(at(file, root), "'organs' must be a non-empty list");
  for (const YAML::Node& on : root["organs"]) {
    check_keys(file, on,
               {"name", "label", "fma", "color", "mesh", "face_budget", "material", "fixed_vertices", "regions"},
               "organ");
    OrganEntry o;
    if (!on["name"]) throw InputError(at(file, on), "organ without 'name'");
    o.name = get<std::string>(file, on["name"], "an organ name");
    if (set.find(o.name)) throw InputError(at(file, on["name"]), "duplicate organ '" + printable_text(o.name) + "'");
    if (on["label"]) o.label = get<int>(file, on["label"], "an integer label id");
    if (on["fma"]) o.fma = get<std::string>(file, on["fma"], "an FMA id");
    o.color = default_organ_color(o.name);
    if (on["color"]) {
      const YAML::Node& c = on["color"];
      if (!c.IsSequence() || c.size() != 3) throw InputError(at(file, c), "color: expected [r, g, b] in 0..1");
      for (int k = 0; k < 3; ++k) {
        o.color[k] = static_cast<float>(get_number(file, c[k], "color"));
        if (o.color[k] < 0 || o.color[k] > 1) throw InputError(at(file, c[k]), "color components must be in 0..1");
      }
    }
    if (!on["mesh"]) throw InputError(at(file, on), "organ '" + printable_text(o.name) + "' has no 'mesh'");
    o.mesh_file = get<std::string>(file, on["mesh"], "a mesh path");
    if (on["face_budget"]) o.face_budget = get<int>(file, on["face_budget"], "an integer face budget");
    if (on["material"]) read_material(file, on["material"], o.material);
    const std::string mesh_path = (fs::path(folder) / o.mesh_file).string();
    o.mesh = read_mesh(mesh_path);
    if (on["fixed_vertices"]) {
      const YAML::Node& fv = on["fixed_vertices"];
      if (!fv.IsSequence()) throw InputError(at(file, fv), "fixed_vertices: expected a list of vertex indices");
      for (const YAML::Node& v : fv) {
        const int idx = get<int>(file, v, "an integer vertex index");
        if (idx < 0 || static_cast<size_t>(idx) >= o.mesh.vertex_count())
          throw InputError(at(file, v), "fixed vertex " + std::to_string(idx) + " outside 0.." +
                                            std::to_string(o.mesh.vertex_count() - 1) + " of " + mesh_path);
        o.fixed_vertices.push_back(idx);
      }
    }
    if (on["regions"]) {  // name: [x, y, z] (mm)
      const YAML::Node& rn = on["regions"];
      if (!rn.IsMap()) throw InputError(at(file, rn), "regions: expected a map of region names to [x, y, z] (mm)");
      for (const auto& kv : rn) {
        const std::string name = get<std::string>(file, kv.first, "a region name");
        const YAML::Node& p = kv.second;
        if (!p.IsSequence() || p.size() != 3)
          throw InputError(at(file, p), "region '" + printable_text(name) + "': expected [x, y, z] (mm)");
        std::array<double, 3> q{};
        for (int k = 0; k < 3; ++k) {
          q[k] = get_number(file, p[k], "a coordinate (mm)");
          if (!(std::abs(q[k]) <= 1e4))
            throw InputError(at(file, p[k]), "region coordinates must be within 1e4 mm of the origin");
        }
        if (o.find_region(name))
          throw InputError(at(file, kv.first), "duplicate region '" + printable_text(name) + "'");
        o.regions.push_back({name, q});
      }
    }
    set.organs.push_back(std::move(o));
  }
  if (root["connections"]) {
    set.connections_file = get<std::string>(file, root["connections"], "a file name");
    const std::string cpath = (fs::path(folder) / set.connections_file).string();
    set.connections = parse_connections_csv(read_text_file(cpath), cpath);
    long row = 1;
    for (const Connection& c : set.connections) {
      ++row;
      const std::string where = cpath + ":" + std::to_string(row);
      const OrganEntry* a = set.find(c.organ_a);
      const OrganEntry* b = set.find(c.organ_b);
      if (!a) throw InputError(where, "organ '" + printable_text(c.organ_a) + "' is not in atlas.yaml");
      if (!b) throw InputError(where, "organ '" + printable_text(c.organ_b) + "' is not in atlas.yaml");
      if (c.vertex_a < 0 || static_cast<size_t>(c.vertex_a) >= a->mesh.vertex_count())
        throw InputError(
            where, "vertex_a " + std::to_string(c.vertex_a) + " outside organ '" + printable_text(c.organ_a) + "'");
      if (c.vertex_b < 0 || static_cast<size_t>(c.vertex_b) >= b->mesh.vertex_count())
        throw InputError(
            where, "vertex_b " + std::to_string(c.vertex_b) + " outside organ '" + printable_text(c.organ_b) + "'");
    }
  }
  if (root["ct"]) {  // ct: {file: ct.nii.gz, window_width_hu: 400, window_level_hu: 40}
    const YAML::Node& cn = root["ct"];
    check_keys(file, cn, {"file", "window_width_hu", "window_level_hu"}, "ct");
    CtRecord ct;
    if (!cn["file"]) throw InputError(at(file, cn), "ct: missing 'file' (the CT in the set, e.g. ct.nii.gz)");
    ct.file = get<std::string>(file, cn["file"], "a file name for 'file'");
    const fs::path rel(ct.file);
    bool up = false;
    for (const auto& part : rel) up |= part == "..";
    if (ct.file.empty() || rel.is_absolute() || up)
      throw InputError(at(file, cn["file"]),
                       "ct: 'file' must be a path inside the set folder, got '" + printable_text(ct.file) + "'");
    if (cn["window_width_hu"]) {
      ct.window_width_hu = get_number(file, cn["window_width_hu"], "window_width_hu");
      if (!(ct.window_width_hu >= 1 && ct.window_width_hu <= 10000))
        throw InputError(at(file, cn["window_width_hu"]), "'window_width_hu' must be in 1..10000 HU");
    }
    if (cn["window_level_hu"]) {
      ct.window_level_hu = get_number(file, cn["window_level_hu"], "window_level_hu");
      if (!(ct.window_level_hu >= -2000 && ct.window_level_hu <= 5000))
        throw InputError(at(file, cn["window_level_hu"]), "'window_level_hu' must be in -2000..5000 HU");
    }
    const std::string ct_file = (fs::path(folder) / ct.file).string();
    if (!fs::is_regular_file(ct_file, ec))
      throw InputError(at(file, cn["file"]), "ct: file '" + printable_text(ct.file) + "' not found in the set");
    try {
      read_ct_nifti(ct_file, true);  // the header and the length; the viewer reads the voxels
    } catch (const InputError& e) {
      throw InputError(at(file, cn["file"]), std::string("ct: ") + e.what());
    }
    set.ct = ct;
  }
  if (root["provenance"] && root["provenance"].IsMap())
    for (const auto& kv : root["provenance"])
      set.provenance[kv.first.as<std::string>()] =
          kv.second.IsScalar() ? kv.second.as<std::string>() : YAML::Dump(kv.second);
  return set;
}

void write_organ_set(const OrganSet& set, const std::string& folder,
                     const std::map<std::string, std::string>& extra_files, bool overwrite) {
  std::error_code ec;
  const fs::path target = fs::absolute(folder);
  if (fs::exists(target, ec) && !overwrite)
    throw InputError(folder, "output folder exists (refusing to overwrite; remove it or choose another)");
  const fs::path parent = target.parent_path();
  if (!fs::is_directory(parent, ec)) fs::create_directories(parent, ec);
  const std::string stem = "." + target.filename().string() + ".partial.";
  // Folders left by writers that were killed (SIGKILL, power loss): their process is gone.
  remove_stale_partials(parent, stem);
  ec.clear();
  const fs::path tmp = parent / (stem + std::to_string(::getpid()));
  fs::remove_all(tmp, ec);
  try {
    fs::create_directories(tmp / "organs");
    std::ostringstream y;
    y << "# SoftAtlas organ set (docs/organ-set.md)\n";
    y << "softatlas_organ_set: 1\nunits: " << set.units << "\nspace: " << set.space << "\n";
    y << "organs:\n";
    for (const OrganEntry& o : set.organs) {
      const std::string mesh_file = o.mesh_file.empty() ? "organs/" + o.name + ".ply" : o.mesh_file;
      y << "  - name: " << yaml_escape(o.name) << "\n";
      if (o.label) y << "    label: " << o.label << "\n";
      if (!o.fma.empty()) y << "    fma: " << yaml_escape(o.fma) << "\n";
      y << "    color: [" << o.color[0] << ", " << o.color[1] << ", " << o.color[2] << "]\n";
      y << "    mesh: " << yaml_escape(mesh_file) << "\n";
      if (o.face_budget) y << "    face_budget: " << o.face_budget << "\n";
      const MaterialSpec& m = o.material;
      if (m.model == "rigid") {  // fixed context: only the density (its mass, for reports) matters
        y << "    material: {model: rigid, density_kg_m3: " << m.density_kg_m3 << "}\n";
      } else {
        y << "    material: {model: " << m.model << ", young_modulus_pa: " << m.young_modulus_pa
          << ", thickness_m: " << m.thickness_m << ", density_kg_m3: " << m.density_kg_m3
          << ", damping_scale: " << m.damping_scale << ", elastica_a: " << m.elastica_a
          << ", elastica_b: " << m.elastica_b << ", elastica_p: " << m.elastica_p << ", tau_s: " << m.tau_s
          << ", tau_c: " << m.tau_c << ", flexion_stiffness: " << m.flexion_stiffness
          << ", volume_stiffness: " << m.volume_stiffness;
        if (m.model == "solid") y << ", poisson_ratio: " << m.poisson_ratio << ", solid_nodes: " << m.solid_nodes;
        if (m.damping_ratio >= 0) y << ", damping_ratio: " << m.damping_ratio;
        y << "}\n";
      }
      if (!o.fixed_vertices.empty()) {
        y << "    fixed_vertices: [";
        for (size_t i = 0; i < o.fixed_vertices.size(); ++i) y << (i ? ", " : "") << o.fixed_vertices[i];
        y << "]\n";
      }
      if (!o.regions.empty()) {
        y << "    regions:\n";
        for (const auto& [n, q] : o.regions)
          y << "      " << yaml_escape(n) << ": [" << q[0] << ", " << q[1] << ", " << q[2] << "]\n";
      }
      write_ply(o.mesh, (tmp / mesh_file).string());
    }
    y << "connections: " << set.connections_file << "\n";
    if (set.ct) {
      std::ostringstream w;
      w.precision(10);
      w << "ct: {file: " << yaml_escape(set.ct->file) << ", window_width_hu: " << set.ct->window_width_hu
        << ", window_level_hu: " << set.ct->window_level_hu << "}\n";
      y << w.str();
      if (!extra_files.count(set.ct->file)) {  // a set read and written again keeps its CT
        const std::string from = set.ct_path();
        if (set.folder.empty() || !fs::is_regular_file(from, ec))
          throw InputError(folder, "the organ set records a CT (" + set.ct->file + ") but none was given to write");
        fs::create_directories((tmp / set.ct->file).parent_path());
        fs::copy_file(from, tmp / set.ct->file, fs::copy_options::overwrite_existing);
      }
    }
    if (!set.provenance.empty()) {
      y << "provenance:\n";
      for (const auto& [k, v] : set.provenance) y << "  " << yaml_escape(k) << ": " << yaml_escape(v) << "\n";
    }
    write_file_atomic((tmp / "atlas.yaml").string(), y.str());
    write_file_atomic((tmp / set.connections_file).string(), format_connections_csv(set.connections));
    for (const auto& [name, content] : extra_files) {
      fs::create_directories((tmp / name).parent_path());
      write_file_atomic((tmp / name).string(), content);
    }
    if (overwrite && fs::exists(target, ec)) fs::remove_all(target, ec);
    fs::rename(tmp, target);
  } catch (const fs::filesystem_error& e) {
    fs::remove_all(tmp, ec);
    throw InputError(folder, "cannot write the organ set: " + e.code().message());
  } catch (const InputError& e) {  // a full disk: name the folder asked for, not the hidden one
    fs::remove_all(tmp, ec);
    throw InputError("", name_target(e.what(), tmp.string(), target.string()));
  } catch (...) {
    fs::remove_all(tmp, ec);
    throw;
  }
}

}  // namespace softatlas::io
