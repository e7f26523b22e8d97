// The whole pipeline: read -> segment/import -> surface -> repair+remesh -> connect -> write.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "softatlas/pipeline/connect.hpp"
#include "softatlas/pipeline/remesh.hpp"
#include "softatlas/pipeline/segment.hpp"
#include "softatlas/pipeline/surface.hpp"

namespace softatlas::pipeline {

// One label source: a multi-label map with TotalSegmentator ids (organ empty), or a binary mask
// of one organ (organ = its name; every non-zero voxel belongs to it).
struct LabelSource {
  std::string path;
  std::string organ;
};

struct MeshSource {
  std::string path;
  std::string organ;  // empty: taken from the file name (BodyParts3D FMA id or organ name)
};

struct BuildOptions {
  std::string ct_path;
  std::vector<LabelSource> labels;
  std::string seeds_path;
  std::vector<MeshSource> meshes;
  std::vector<std::string> organs;     // empty: every soft organ present
  std::map<std::string, int> budgets;  // overrides of the Table IV defaults
  std::string output;
  bool overwrite = false;
  SurfaceOptions surface;
  RemeshOptions remesh;  // face_budget is set per organ
  ConnectOptions connect;
  SegmentOptions segment;
  bool quiet = false;  // no progress on stderr
  // Organs built at once (surface + repair + remesh, one thread each); 0 = one per hardware
  // thread. The output does not depend on it (tested byte for byte).
  int jobs = 0;
};

// Seconds per stage. "surface" and "remesh" are summed over organs (thread time, as if built one
// after the other); "organs_wall" is the wall time of building all organs on the jobs' threads.
struct StageTimes {
  std::vector<std::pair<std::string, double>> seconds;  // in order: read, segment, organs_wall, surface, ...
  void add(const std::string& stage, double s);
};

struct BuildResult {
  std::string output;
  std::string quality_json;
  StageTimes times;
  struct OrganSeconds {
    std::string organ;
    double surface_s, remesh_s;  // wall
    double cpu_s;                // CPU time of its thread (surface + remesh)
  };
  std::vector<OrganSeconds> organ_seconds;  // in organ order
  size_t jobs = 1;                          // threads the organs were built on
  size_t organs = 0;
  size_t connections = 0;
};

// Validates every input first, then builds; writes nothing unless everything succeeded.
BuildResult build_organ_set(const BuildOptions& options);

// Reads `--config build.yaml` keys into options (command-line values given later override).
void apply_build_config(const std::string& path, BuildOptions* options);

// `softatlas check SET`: reads the set (io), re-inspects every surface; returns the report text
// (JSON) and whether everything holds.
bool check_organ_set(const std::string& folder, std::string* report_json);

// `softatlas export SET -o atlas.glb`: glTF 2.0 binary (assimp), one node per organ with its
// name and colour. Atomic write.
void export_gltf(const std::string& set_folder, const std::string& glb_path);

}  // namespace softatlas::pipeline
