// From an organ set (mm, the pipeline's product) to the physics core's SceneDesc (SI).
#pragma once

#include <string>
#include <vector>

#include "softatlas/io/organ_set.hpp"
#include "softatlas/sim/model.hpp"

namespace softatlas::io {

struct SceneOptions {
  std::vector<std::string> shown;  // organ names to show; empty = all organs
  std::string model_override;      // "" = each organ's material.model; else tmsm|cmsm|nmsm|flexion
  sim::Integrator integrator = sim::Integrator::semi_implicit;
  double dt_s = 0.0;  // 0: the models' own step (sim::recommended_dt_s)
  bool gravity = false;
  bool guard = true;
  int cg_iterations = 25;
};

// Converts mm to m, MaterialSpec to sim::Material, connections to ConnectionDesc. Organs not in
// `shown` are passed with shown = false (the compiler keeps them only if connected). Unknown
// names in `shown` or an unknown model are InputError naming the organ set folder.
sim::SceneDesc scene_from_organ_set(const OrganSet& set, const SceneOptions& options);

// MaterialSpec (atlas.yaml) to the core's Material; `where` names the source for errors.
sim::Material to_sim_material(const MaterialSpec& spec, const std::string& where);

}  // namespace softatlas::io
