#include "softatlas/app/scene.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>

#include "softatlas/io/scene.hpp"
#include "softatlas/sim/error.hpp"

namespace softatlas::app {
namespace {

// The organ's material through the io mapping (io::to_sim_material, which also knows the
// units of the set), then the lesson's overrides.
sim::Material material_from_spec(const io::MaterialSpec& spec, const PhysicsSettings& physics,
                                 const std::string& where) {
  io::MaterialSpec s = spec;
  if (!physics.model.empty() && s.model != "rigid") s.model = physics.model;  // bone stays rigid
  sim::Material m = io::to_sim_material(s, where);
  if (physics.young_modulus_pa > 0) m.young_modulus_pa = physics.young_modulus_pa;
  if (physics.damping_scale >= 0) m.damping_scale = physics.damping_scale;
  if (physics.elastica_b >= 0) m.elastica_b = physics.elastica_b;
  return m;
}

}  // namespace

sim::SceneDesc scene_from_organ_set(const io::OrganSet& set, const std::vector<std::string>& shown,
                                    const std::vector<std::string>& context, const PhysicsSettings& physics) {
  const std::string where = (set.folder.empty() ? std::string("organ set") : set.folder + "/atlas.yaml");
  for (const auto* list : {&shown, &context})
    for (const std::string& n : *list)
      if (set.index_of(n) < 0) {
        std::string names;
        for (const auto& o : set.organs) names += (names.empty() ? "" : ", ") + o.name;
        throw InputError(where, "organ '" + n + "' is not in the organ set (it has: " + names + ")");
      }
  const double mm = set.units == "m" ? 1.0 : 1e-3;  // organ sets are mm unless they say m
  sim::SceneDesc d;
  d.integrator = physics.integrator;
  d.dt_s = physics.dt_s;
  d.gravity = physics.gravity;
  d.max_tool_force_N = physics.max_tool_force_N;
  std::vector<int> desc_index(set.organs.size(), -1);
  for (size_t i = 0; i < set.organs.size(); ++i) {
    const io::OrganEntry& o = set.organs[i];
    const bool is_shown = std::find(shown.begin(), shown.end(), o.name) != shown.end();
    const bool is_context = std::find(context.begin(), context.end(), o.name) != context.end();
    if (!is_shown && !is_context) continue;
    sim::OrganDesc od;
    od.name = o.name;
    od.vertices.resize(o.mesh.vertices.size());
    for (size_t k = 0; k < od.vertices.size(); ++k) od.vertices[k] = o.mesh.vertices[k] * mm;
    od.faces = o.mesh.faces;
    od.fixed = o.fixed_vertices;
    od.material = material_from_spec(o.material, physics, where + ": organs." + o.name + ".material");
    od.shown = is_shown;
    desc_index[i] = static_cast<int>(d.organs.size());
    d.organs.push_back(std::move(od));
  }
  for (const io::Connection& c : set.connections) {
    const int a = set.index_of(c.organ_a), b = set.index_of(c.organ_b);
    if (a < 0 || b < 0 || desc_index[static_cast<size_t>(a)] < 0 || desc_index[static_cast<size_t>(b)] < 0)
      continue;  // a connection to an organ outside the view has nothing to pull on
    sim::ConnectionDesc cd;
    cd.organ_a = desc_index[static_cast<size_t>(a)];
    cd.vertex_a = c.vertex_a;
    cd.organ_b = desc_index[static_cast<size_t>(b)];
    cd.vertex_b = c.vertex_b;
    cd.rest_length_m = c.rest_length_mm * mm;
    cd.stiffness = c.stiffness;
    d.connections.push_back(cd);
  }
  return d;
}

AtlasScene::AtlasScene(io::OrganSet set, std::vector<std::string> shown, std::vector<std::string> context,
                       const PhysicsSettings& physics)
    : set_(std::move(set)) {
  if (shown.empty())
    for (const auto& o : set_.organs) shown.push_back(o.name);
  const sim::SceneDesc desc = scene_from_organ_set(set_, shown, context, physics);
  model = sim::compile(desc);
  state = sim::make_state(model);
  work = sim::make_work(model);
  for (size_t i = 0; i < set_.organs.size(); ++i) {
    const std::string& n = set_.organs[i].name;
    const bool s = std::find(shown.begin(), shown.end(), n) != shown.end();
    const bool c = std::find(context.begin(), context.end(), n) != context.end();
    if (!s && !c) continue;
    view_organs_.push_back(static_cast<int>(i));
    context_.push_back(!s);
    const int mo = sim::find_organ(model, n);
    model_organ_.push_back(mo);
    std::vector<int32_t> l2g(set_.organs[i].mesh.vertex_count(), -1);
    if (mo >= 0) {
      const sim::OrganRange& r = model.organs[static_cast<size_t>(mo)];
      for (int32_t g = r.vert_begin; g < r.vert_end; ++g)
        l2g[static_cast<size_t>(model.vert_source[static_cast<size_t>(g)])] = g;
    }
    local_to_global_.push_back(std::move(l2g));
  }
}

OrganInfo organ_info(const std::string& n) {
  // TotalSegmentator class names (ct/totalsegmentator_label_table.tsv) -> FMA preferred English
  // names and the system an anatomy atlas files them under. The organs of the demo atlases and
  // of the sample CTs, plus their close neighbours.
  static const std::pair<const char*, OrganInfo> table[] = {
      {"liver", {"Liver", "digestive"}},
      {"stomach", {"Stomach", "digestive"}},
      {"pancreas", {"Pancreas", "digestive"}},
      {"gallbladder", {"Gallbladder", "digestive"}},
      {"esophagus", {"Esophagus", "digestive"}},
      {"duodenum", {"Duodenum", "digestive"}},
      {"colon", {"Colon", "digestive"}},
      {"small_bowel", {"Small intestine", "digestive"}},
      {"spleen", {"Spleen", "lymphatic"}},
      {"kidney_right", {"Right kidney", "urinary"}},
      {"kidney_left", {"Left kidney", "urinary"}},
      {"urinary_bladder", {"Urinary bladder", "urinary"}},
      {"adrenal_gland_right", {"Right suprarenal gland", "endocrine"}},
      {"adrenal_gland_left", {"Left suprarenal gland", "endocrine"}},
      {"trachea", {"Trachea", "respiratory"}},
      {"heart", {"Heart", "cardiovascular"}},
      {"aorta", {"Aorta", "cardiovascular"}},
      {"pulmonary_artery", {"Pulmonary trunk", "cardiovascular"}},
      {"inferior_vena_cava", {"Inferior vena cava", "cardiovascular"}},
      {"portal_vein_and_splenic_vein", {"Portal and splenic vein", "cardiovascular"}},
      {"spinal_cord", {"Spinal cord", "nervous"}},
      {"vertebrae_L5", {"Fifth lumbar vertebra", "skeletal"}},
      {"vertebrae_L1", {"First lumbar vertebra", "skeletal"}},
      {"sacrum", {"Sacrum", "skeletal"}},
      {"hip_left", {"Left hip bone", "skeletal"}},
      {"hip_right", {"Right hip bone", "skeletal"}},
      {"coccyx", {"Coccyx", "skeletal"}},
      {"pelvis", {"Bony pelvis", "skeletal"}},
  };
  for (const auto& [key, info] : table)
    if (n == key) return info;
  std::string d = n;
  std::replace(d.begin(), d.end(), '_', ' ');
  if (!d.empty()) d[0] = static_cast<char>(std::toupper(static_cast<unsigned char>(d[0])));
  return {d, "other"};
}

std::string AtlasScene::display_name(int v) const { return organ_info(name(v)).display; }
std::string AtlasScene::system(int v) const { return organ_info(name(v)).system; }

const std::string& AtlasScene::name(int v) const {
  return set_.organs[static_cast<size_t>(view_organs_[static_cast<size_t>(v)])].name;
}

int AtlasScene::view_index(const std::string& organ) const {
  for (size_t v = 0; v < view_organs_.size(); ++v)
    if (name(static_cast<int>(v)) == organ) return static_cast<int>(v);
  return -1;
}

bool AtlasScene::is_rigid(int view_index) const {
  return set_.organs[static_cast<size_t>(view_organs_[static_cast<size_t>(view_index)])].material.model == "rigid";
}

void AtlasScene::positions_mm(int v, std::vector<float>& out) const {
  const io::OrganEntry& o = set_.organs[static_cast<size_t>(view_organs_[static_cast<size_t>(v)])];
  const size_t n = o.mesh.vertex_count();
  out.resize(n * 3);
  const std::vector<int32_t>& l2g = local_to_global_[static_cast<size_t>(v)];
  const double to_set = set_.units == "m" ? 1.0 : 1e3;  // core metres -> the set's units
  for (size_t i = 0; i < n; ++i) {
    const int32_t g = l2g[i];
    if (g >= 0) {
      out[3 * i] = static_cast<float>(state.x[static_cast<size_t>(g)] * to_set);
      out[3 * i + 1] = static_cast<float>(state.y[static_cast<size_t>(g)] * to_set);
      out[3 * i + 2] = static_cast<float>(state.z[static_cast<size_t>(g)] * to_set);
    } else {
      for (int k = 0; k < 3; ++k) out[3 * i + k] = static_cast<float>(o.mesh.vertices[3 * i + k]);
    }
  }
}

void AtlasScene::bounds_mm(Eigen::Vector3f& lo, Eigen::Vector3f& hi) const {
  lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
  hi = -lo;
  for (int idx : view_organs_) {
    const auto& v = set_.organs[static_cast<size_t>(idx)].mesh.vertices;
    for (size_t i = 0; i + 2 < v.size(); i += 3) {
      const Eigen::Vector3f p(static_cast<float>(v[i]), static_cast<float>(v[i + 1]), static_cast<float>(v[i + 2]));
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
  }
}

std::vector<int32_t> AtlasScene::global_vertices(int v, const std::vector<int32_t>& local) const {
  std::vector<int32_t> out;
  const auto& l2g = local_to_global_[static_cast<size_t>(v)];
  for (int32_t l : local)
    if (l >= 0 && static_cast<size_t>(l) < l2g.size() && l2g[static_cast<size_t>(l)] >= 0)
      out.push_back(l2g[static_cast<size_t>(l)]);
  return out;
}

namespace {
std::vector<int32_t> within(const std::vector<double>& V, const Eigen::Vector3d& c, double r) {
  std::vector<int32_t> out;
  for (size_t i = 0; i < V.size() / 3; ++i)
    if ((Eigen::Vector3d(V[3 * i], V[3 * i + 1], V[3 * i + 2]) - c).norm() <= r) out.push_back(static_cast<int32_t>(i));
  return out;
}
}  // namespace

std::vector<int32_t> AtlasScene::region_vertices(int v, const std::string& region, double radius_mm) const {
  const auto& V = set_.organs[static_cast<size_t>(view_organs_[static_cast<size_t>(v)])].mesh.vertices;
  Eigen::Vector3d dir;
  if (region == "anterior")
    dir = {0, 1, 0};
  else if (region == "posterior")
    dir = {0, -1, 0};
  else if (region == "superior")
    dir = {0, 0, 1};
  else if (region == "inferior")
    dir = {0, 0, -1};
  else if (region == "right")
    dir = {1, 0, 0};  // RAS: +x is the patient's right
  else if (region == "left")
    dir = {-1, 0, 0};
  else
    return {};
  double best = -std::numeric_limits<double>::max();
  size_t bi = 0;
  for (size_t i = 0; i < V.size() / 3; ++i) {
    const double s = dir.dot(Eigen::Vector3d(V[3 * i], V[3 * i + 1], V[3 * i + 2]));
    if (s > best) {
      best = s;
      bi = i;
    }
  }
  return within(V, Eigen::Vector3d(V[3 * bi], V[3 * bi + 1], V[3 * bi + 2]), radius_mm);
}

std::vector<int32_t> AtlasScene::landmark_vertices(int v, const Eigen::Vector3d& p, double radius_mm) const {
  const auto& V = set_.organs[static_cast<size_t>(view_organs_[static_cast<size_t>(v)])].mesh.vertices;
  double best = std::numeric_limits<double>::max();
  size_t bi = 0;
  for (size_t i = 0; i < V.size() / 3; ++i) {
    const double d = (Eigen::Vector3d(V[3 * i], V[3 * i + 1], V[3 * i + 2]) - p).norm();
    if (d < best) {
      best = d;
      bi = i;
    }
  }
  return within(V, Eigen::Vector3d(V[3 * bi], V[3 * bi + 1], V[3 * bi + 2]), radius_mm);
}

double AtlasScene::mean_displacement_mm(const std::vector<int32_t>& g) const {
  if (g.empty()) return 0.0;
  Eigen::Vector3d sum(0, 0, 0);
  for (int32_t i : g) {
    const size_t k = static_cast<size_t>(i);
    sum += Eigen::Vector3d(state.x[k] - model.vert_rest_x[k], state.y[k] - model.vert_rest_y[k],
                           state.z[k] - model.vert_rest_z[k]);
  }
  return (sum / static_cast<double>(g.size())).norm() * 1e3;  // core metres -> mm
}

}  // namespace softatlas::app
