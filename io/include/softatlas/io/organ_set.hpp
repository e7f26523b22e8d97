// The organ set: the pipeline's product and the viewer's input (see docs/organ-set.md).
//
//   SET/atlas.yaml       manifest: units, space, organs (name, label, fma, colour, mesh,
//                        face budget, material, fixed vertices), connections file, provenance
//   SET/organs/NAME.ply  one closed, manifold, outward-oriented surface per organ (mm, RAS)
//   SET/connections.csv  organ_a,vertex_a,organ_b,vertex_b,rest_length_mm,stiffness
//   SET/quality.json     the pipeline's quality report (optional for readers)
#pragma once

#include <array>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "softatlas/io/mesh_io.hpp"

namespace softatlas::io {

// Material of one organ as written in atlas.yaml (`material:` map). Units in the names.
// Any field not given keeps the default below. See docs/physics.md for each parameter's paper.
struct MaterialSpec {
  std::string model = "solid";  // solid | rigid | nmsm | tmsm | cmsm | flexion (solid: the evidence, docs/physics.md)
  double young_modulus_pa = 4000.0;  // E in eq 9 of paper 000 (liver: a few kPa)
  double thickness_m = 1e-3;         // t in eq 9 (paper 000 uses 1e-3 m)
  double density_kg_m3 = 1060.0;     // organ mass = density * enclosed volume, spread by eq 8
  double damping_scale = 1.0;        // multiplies eq 10
  double elastica_a = 1.0;           // a in eq 5
  double elastica_b = 0.1;           // b in eq 5 (paper 000 section IV uses 0.1)
  int elastica_p = 1;                // p in eq 5 (1 or 2)
  double tau_s = -1.0;               // over-stretch ratio (CMSM, NMSM of Table III); <0 = off.
                                     // Off by default: on a surface mesh, projecting stretched
                                     // springs back with compression unbounded crumples the organ
                                     // inward (docs/physics.md)
  double tau_c = -1.0;               // over-compress ratio (CMSM); <0 = off
  double flexion_stiffness = 0.0;    // dihedral springs (paper 003), N*m per radian; 0 = off
  double volume_stiffness = 0.5;     // volume constraint (paper 003 eq 25), 0..1; 0 = off. On by
                                     // default: surface springs alone do not hold the volume
  // solid model (sim/solid.hpp): written only for model: solid
  double poisson_ratio = 0.49;
  double damping_ratio = -1.0;  // < 0: the model's default (sim::Material::damping_ratio)
  int solid_nodes = 0;          // lattice node budget; 0 = the core's default
};

struct OrganEntry {
  std::string name;                               // TotalSegmentator name: liver, kidney_left, ...
  int label = 0;                                  // TotalSegmentator id (0 if unknown)
  std::string fma;                                // ontology id, e.g. FMA7197 ("" if unknown)
  std::array<float, 3> color{0.8f, 0.5f, 0.45f};  // RGB in 0..1
  std::string mesh_file;                          // relative to the set folder: organs/NAME.ply
  int face_budget = 0;                            // 0 if none was set
  MaterialSpec material;
  std::vector<int32_t> fixed_vertices;  // held in place (anchored to the body wall)
  // Named regions (landmarks): name -> a point on or near the organ (mm, RAS), in file order,
  // e.g. gastric_impression of the liver. Lessons grasp there with `region: NAME`.
  std::vector<std::pair<std::string, std::array<double, 3>>> regions;
  const std::array<double, 3>* find_region(const std::string& region) const {
    for (const auto& [n, p] : regions)
      if (n == region) return &p;
    return nullptr;
  }
  TriMesh mesh;  // loaded by read_organ_set (mm, RAS)
};

struct Connection {
  std::string organ_a;
  int32_t vertex_a = 0;
  std::string organ_b;
  int32_t vertex_b = 0;
  double rest_length_mm = 0.0;
  double stiffness = 0.0;  // N/m
};

// The CT the set was built from (`ct:` in atlas.yaml; absent for sets built from meshes): a NIfTI
// file in the set (SET/ct.nii.gz, int16 HU, cropped to the organs) and the display window the
// viewer maps to grey levels on the slice plane (level +- width/2 -> black..white).
struct CtRecord {
  std::string file = "ct.nii.gz";  // relative to the set folder
  double window_width_hu = 400.0;  // soft tissue
  double window_level_hu = 40.0;
};

struct OrganSet {
  std::string folder;  // where it was read from (empty when built in memory)
  std::string units = "mm";
  std::string space = "RAS";
  std::vector<OrganEntry> organs;
  std::vector<Connection> connections;
  std::string connections_file = "connections.csv";
  // Free-form provenance written as a YAML map of strings (input hashes, parameters, version).
  std::map<std::string, std::string> provenance;
  std::optional<CtRecord> ct;  // the set's CT, if it records one

  // folder / ct->file, or "" when the set records no CT.
  std::string ct_path() const;

  const OrganEntry* find(const std::string& name) const;
  int index_of(const std::string& name) const;  // -1 if absent
};

// Reads SET/atlas.yaml, every organ mesh and connections.csv. Validates everything once:
// unknown keys, wrong types, missing files, bad meshes, connections naming absent organs or
// out-of-range vertices. Errors are InputError with file:line:column or file + field.
OrganSet read_organ_set(const std::string& folder);

// Writes an organ set into `folder` atomically: everything goes into a temporary sibling folder
// which is renamed at the end. Fails (InputError) if `folder` exists unless overwrite is true.
// Meshes are written as organs/NAME.ply; `extra_files` (relative path -> content, e.g.
// quality.json) are written too. A set with `ct` needs its CT file among extra_files (the
// pipeline's encoded bytes) or in set.folder (a set read and written again keeps its CT).
void write_organ_set(const OrganSet& set, const std::string& folder,
                     const std::map<std::string, std::string>& extra_files = {}, bool overwrite = false);

// Default colour for an organ name (anatomy-atlas palette), grey for unknown names.
std::array<float, 3> default_organ_color(const std::string& name);

// connections.csv text <-> records (header line first).
std::string format_connections_csv(const std::vector<Connection>& connections);
std::vector<Connection> parse_connections_csv(const std::string& text, const std::string& path);

}  // namespace softatlas::io
