// Organ set (mm) -> SceneDesc (SI).
#include "softatlas/io/scene.hpp"

#include "softatlas/sim/error.hpp"

namespace softatlas::io {

sim::Material to_sim_material(const MaterialSpec& spec, const std::string& where) {
  sim::Material m;
  if (!sim::parse_model_kind(spec.model, m.model))
    throw InputError(where, "unknown model '" + spec.model + "' (expected tmsm, cmsm, nmsm, flexion, solid or rigid)");
  m.young_modulus_pa = spec.young_modulus_pa;
  m.thickness_m = spec.thickness_m;
  m.density_kg_m3 = spec.density_kg_m3;
  m.damping_scale = spec.damping_scale;
  m.elastica_a = spec.elastica_a;
  m.elastica_b = spec.elastica_b;
  m.elastica_p = spec.elastica_p;
  m.curvature_unit_m = 1e-3;  // organ sets are in mm: b is the paper's b with kappa in 1/mm
  m.tau_s = spec.tau_s;
  m.tau_c = spec.tau_c;
  m.flexion_stiffness = spec.flexion_stiffness;
  m.volume_stiffness = spec.volume_stiffness;
  m.poisson_ratio = spec.poisson_ratio;
  m.damping_ratio = spec.damping_ratio;
  m.solid_nodes = spec.solid_nodes;
  return m;
}

sim::SceneDesc scene_from_organ_set(const OrganSet& set, const SceneOptions& options) {
  const std::string where = set.folder.empty() ? std::string("organ set") : set.folder;
  for (const std::string& name : options.shown)
    if (!set.find(name)) {
      std::string names;
      for (const OrganEntry& o : set.organs) names += (names.empty() ? "" : ", ") + o.name;
      throw InputError(where, "organ '" + name + "' is not in this organ set (it has: " + names + ")");
    }
  sim::SceneDesc scene;
  scene.integrator = options.integrator;
  scene.dt_s = options.dt_s;
  scene.gravity = options.gravity;
  scene.guard = options.guard;
  scene.cg_iterations = options.cg_iterations;
  for (const OrganEntry& o : set.organs) {
    sim::OrganDesc d;
    d.name = o.name;
    d.vertices.resize(o.mesh.vertices.size());
    for (size_t i = 0; i < o.mesh.vertices.size(); ++i) d.vertices[i] = 1e-3 * o.mesh.vertices[i];
    d.faces = o.mesh.faces;
    d.fixed = o.fixed_vertices;
    MaterialSpec spec = o.material;
    // an override swaps the soft tissue model; rigid context (bone) stays rigid
    if (!options.model_override.empty() && spec.model != "rigid") spec.model = options.model_override;
    d.material = to_sim_material(spec, where + ": organ '" + o.name + "' material");
    d.shown = options.shown.empty();
    for (const std::string& name : options.shown) d.shown = d.shown || name == o.name;
    scene.organs.push_back(std::move(d));
  }
  for (const Connection& c : set.connections) {
    sim::ConnectionDesc cd;
    cd.organ_a = set.index_of(c.organ_a);
    cd.organ_b = set.index_of(c.organ_b);
    if (cd.organ_a < 0 || cd.organ_b < 0) continue;  // read_organ_set already rejects these
    cd.vertex_a = c.vertex_a;
    cd.vertex_b = c.vertex_b;
    cd.rest_length_m = 1e-3 * c.rest_length_mm;
    cd.stiffness = c.stiffness;
    scene.connections.push_back(cd);
  }
  return scene;
}

}  // namespace softatlas::io
