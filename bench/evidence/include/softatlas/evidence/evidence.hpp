// The evidence generators behind `softatlas bench accuracy|stability` (issue 7).
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "softatlas/evidence/meshing.hpp"
#include "softatlas/evidence/runner.hpp"
#include "softatlas/evidence/scenario.hpp"

namespace softatlas::evidence {

// Size of a sweep: tiny (tests), quick (CI, < 5 min with stability), full (< 30 min, 2 cores).
enum class Grid { tiny, quick, full };

struct Options {
  Grid grid = Grid::full;
  std::string out_dir;
  std::string data_dir;      // ../shared/data: meshes/sofa/liver-smooth.obj
  bool paper_tables = true;  // accuracy: also reproduce paper 000 Tables I-III and the sphere test
  bool fit = true;           // accuracy: parameter fitting against the FEM reference
};

// Closed-form checks of the FEM reference (compressed block, cantilever under refinement).
nlohmann::json fem_verification(Grid grid);

// Runs the accuracy sweep; returns results.json's content and writes plots into out_dir.
nlohmann::json run_accuracy(const Options& options);
nlohmann::json run_stability(const Options& options);

// Paper 000 Tables I, II, III and the sphere test with the paper's settings.
nlohmann::json paper_tables(const Options& options, const TriMesh& liver_source);

// A run's integrator as tables and plots name it: "implicit", or "implicit, dt 8 ms" when the
// run's step is not the sweep's 1 ms.
std::string integrator_label(const nlohmann::json& run);

// Markdown tables of a results.json (accuracy / stability), written beside it as report.md.
std::string accuracy_markdown(const nlohmann::json& results);
std::string stability_markdown(const nlohmann::json& results);

// Files: written to a temporary name in the same folder, then renamed (never half-written).
void write_file_atomic(const std::string& path, const std::string& content);

// The liver used throughout: liver-smooth.obj normalised to 170 mm.
TriMesh load_liver(const std::string& data_dir);

}  // namespace softatlas::evidence
