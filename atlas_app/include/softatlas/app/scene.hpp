// The app's scene: an organ set, the organs a view or lesson shows, and the compiled physics.
//
// Units: organ sets are in mm; the core works in SI. scene_from_organ_set converts (mm -> m)
// and everything the app shows or reports is converted back to mm.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "softatlas/io/organ_set.hpp"
#include "softatlas/sim/sim.hpp"

namespace softatlas::app {

// Physics settings a lesson (or the viewer panel) may override. Negative / empty: keep the
// organ set's per-organ material.
struct PhysicsSettings {
  std::string model;  // tmsm | cmsm | nmsm | flexion, "" = per organ
  sim::Integrator integrator = sim::Integrator::semi_implicit;
  double dt_s = 0.0;  // 0: the models' own step (sim::recommended_dt_s)
  bool gravity = false;
  double young_modulus_pa = -1.0;
  double elastica_b = -1.0;
  double damping_scale = -1.0;
  double max_tool_force_N = 10.0;
};

// Organ set (mm) -> SceneDesc (m). `shown` organs are simulated; `context` organs are added
// with shown = false, so the core keeps them only if connected to a shown organ. Organs in
// neither list are left out. Unknown names: InputError naming the organ.
// io::scene_from_organ_set passes every organ of the set (unlisted ones with shown = false);
// the app needs a third state (left out entirely) and the lesson's overrides, so it keeps this
// converter and shares the material mapping (io::to_sim_material).
sim::SceneDesc scene_from_organ_set(const io::OrganSet& set, const std::vector<std::string>& shown,
                                    const std::vector<std::string>& context, const PhysicsSettings& physics);

// Display name (English, the FMA preferred name where the organ set gives TotalSegmentator's
// name) and body system of an organ; unknown names: "some_organ" -> "Some organ", system "other".
struct OrganInfo {
  std::string display, system;
};
OrganInfo organ_info(const std::string& totalsegmentator_name);

class AtlasScene {
 public:
  AtlasScene(io::OrganSet set, std::vector<std::string> shown, std::vector<std::string> context,
             const PhysicsSettings& physics);

  const io::OrganSet& set() const { return set_; }
  // Organs drawn (shown + context), in the order of the set; their index is the "view index".
  const std::vector<int>& view_organs() const { return view_organs_; }
  const std::string& name(int view_index) const;
  // What people read: "Right kidney", and the body system the organ panel groups it under.
  std::string display_name(int view_index) const;
  std::string system(int view_index) const;
  int view_index(const std::string& organ) const;  // -1 if not in the view
  bool is_context(int view_index) const { return context_[static_cast<size_t>(view_index)]; }
  // Rigid context (material model rigid, e.g. bone): drawn and picked, never moved by a grasp.
  bool is_rigid(int view_index) const;
  // Compiled organ of a view organ, -1 if the core left it out (then it is drawn at rest).
  int model_organ(int view_index) const { return model_organ_[static_cast<size_t>(view_index)]; }

  // Current positions of a view organ, mm, #V*3 float (rest shape if not simulated).
  void positions_mm(int view_index, std::vector<float>& out) const;
  void bounds_mm(Eigen::Vector3f& lo, Eigen::Vector3f& hi) const;  // rest shapes of the view

  // Global (model) vertex indices of local vertices of a view organ (simulated organs only).
  std::vector<int32_t> global_vertices(int view_index, const std::vector<int32_t>& local) const;
  // Local vertices of a region: the vertex furthest along `region` (anterior, posterior,
  // superior, inferior, left, right) or closest to `landmark_mm`, and every vertex within
  // radius_mm of it (rest shape).
  std::vector<int32_t> region_vertices(int view_index, const std::string& region, double radius_mm) const;
  std::vector<int32_t> landmark_vertices(int view_index, const Eigen::Vector3d& landmark_mm, double radius_mm) const;
  // Mean displacement (mm) of global vertices from their rest positions.
  double mean_displacement_mm(const std::vector<int32_t>& global) const;

  sim::Model model;
  sim::State state;
  sim::Work work;

 private:
  io::OrganSet set_;
  std::vector<int> view_organs_;  // set organ index per view index
  std::vector<bool> context_;
  std::vector<int> model_organ_;
  std::vector<std::vector<int32_t>> local_to_global_;
};

}  // namespace softatlas::app
