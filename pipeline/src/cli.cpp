// Subcommands of `softatlas` owned by the pipeline: build, segment, check, export, bench pipeline.
// Options are parsed with CLI11; bad input surfaces as InputError (one line, exit 1 in main).
#include "softatlas/pipeline/cli.hpp"

#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <random>
#include <algorithm>
#include <cmath>

#include "softatlas/io/cli.hpp"
#include "softatlas/io/cli_number.hpp"
#include "softatlas/pipeline/bench_segment.hpp"
#include "softatlas/pipeline/build.hpp"
#include "softatlas/pipeline/export_web.hpp"
#include "softatlas/pipeline/label_table.hpp"
#include "softatlas/sim/error.hpp"

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace softatlas::pipeline {
namespace {

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::string cur;
  for (char c : s) {
    if (c == sep) {
      if (!cur.empty()) out.push_back(cur);
      cur.clear();
    } else {
      cur += c;
    }
  }
  if (!cur.empty()) out.push_back(cur);
  return out;
}

// "NAME=FILE" -> (NAME, FILE); a bare FILE -> ("", FILE). A '=' inside a path after a '/' is part
// of the path.
std::pair<std::string, std::string> name_and_path(const std::string& arg) {
  const auto eq = arg.find('=');
  const auto slash = arg.find('/');
  if (eq == std::string::npos || (slash != std::string::npos && slash < eq)) return {"", arg};
  return {arg.substr(0, eq), arg.substr(eq + 1)};
}

std::map<std::string, int> parse_budgets(const std::vector<std::string>& items) {
  std::map<std::string, int> out;
  for (const std::string& item : items)
    for (const std::string& pair : split(item, ',')) {
      const auto eq = pair.find('=');
      if (eq == std::string::npos || eq == 0)
        throw InputError("--budget", "expected NAME=FACES (e.g. liver=5000), got '" + pair + "'");
      const std::string name = pair.substr(0, eq), value = pair.substr(eq + 1);
      char* end = nullptr;
      const long faces = std::strtol(value.c_str(), &end, 10);
      if (value.empty() || *end != '\0')
        throw InputError("--budget " + name, "expected a whole number of faces, got '" + value + "'");
      out[name] = static_cast<int>(faces);
    }
  return out;
}

struct BuildCli {
  std::string ct, seeds, config, output;
  std::vector<std::string> labels, meshes, organs, budgets;
  double connect_distance = -1, connect_spacing = -1, stiffness = -1;
  bool quiet = false;

  void add_to(CLI::App& app, bool need_output) {
    app.add_option("ct", ct, "CT volume: .nii/.nii.gz, .nrrd, .mha/.mhd, or a DICOM folder/file");
    app.add_option("--labels", labels,
                   "label map with TotalSegmentator ids, or NAME=MASK for a binary mask of one organ "
                   "(repeatable)");
    app.add_option("--seeds", seeds, "seed points in world mm (YAML: organs: {liver: [[x, y, z]]})");
    app.add_option("--mesh", meshes, "organ surface meshes (.obj/.stl/.ply), FILE or NAME=FILE")->expected(1, -1);
    app.add_option("--organs", organs, "organs to build, TotalSegmentator names (comma-separated)")->delimiter(',');
    app.add_option("--budget", budgets, "face budgets, NAME=FACES (comma-separated)");
    app.add_option("--config", config, "build.yaml with the same settings");
    app.add_option("--connect-distance", connect_distance, "connection threshold in mm (default 4)")
        ->check(io::finite_in(0, 1000));
    app.add_option("--connect-spacing", connect_spacing, "one spring per disc of this radius, mm (default 6)")
        ->check(io::finite_in(0, 1000));
    app.add_option("--stiffness", stiffness, "connection spring stiffness, N/m (default 50)")
        ->check(io::finite_in(0, 1e6));
    app.add_flag("-q,--quiet", quiet, "no progress output");
    auto* o = app.add_option("-o,--output", output, "output organ-set folder (must not exist)");
    if (need_output) o->required();
  }

  BuildOptions options() const {
    BuildOptions b;
    if (!config.empty()) apply_build_config(config, &b);
    b.ct_path = ct;
    for (const auto& l : labels) {
      const auto [name, path] = name_and_path(l);
      b.labels.push_back({path, name});
    }
    b.seeds_path = seeds;
    for (const auto& m : meshes) {
      const auto [name, path] = name_and_path(m);
      b.meshes.push_back({path, name});
    }
    if (!b.meshes.empty() && !ct.empty()) {
      // `build --mesh A.obj B.obj` puts the first file in the CT slot if it came first.
      b.meshes.insert(b.meshes.begin(), MeshSource{name_and_path(ct).second, name_and_path(ct).first});
      b.ct_path.clear();
    }
    if (!organs.empty()) b.organs = organs;
    for (const auto& [k, v] : parse_budgets(budgets)) b.budgets[k] = v;
    if (connect_distance >= 0) b.connect.distance_mm = connect_distance;
    if (connect_spacing >= 0) b.connect.spacing_mm = connect_spacing;
    if (stiffness >= 0) b.connect.stiffness = stiffness;
    b.output = output;
    b.quiet = quiet;
    return b;
  }
};

int run_build(const BuildCli& cli) {
  const auto t0 = std::chrono::steady_clock::now();
  const BuildResult r = build_organ_set(cli.options());
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!cli.quiet)
    std::fprintf(stderr, "[softatlas build] done: %zu organs, %zu connections in %.1f s -> %s\n", r.organs,
                 r.connections, s, r.output.c_str());
  return 0;
}

struct SegmentArgs {
  std::string ct, seeds, output, reference;
};

int run_segment(const SegmentArgs& a) {
  const auto& [ct, seeds, output, reference] = a;
  if (fs::exists(output)) throw InputError(output, "the output file already exists");
  const Volume image = read_volume(ct);
  const Seeds s = read_seeds(seeds);
  std::fprintf(stderr, "[softatlas segment] competitive region growing, %zu organs\n", s.organs.size());
  const Volume labels = segment_seeded(image, s, SegmentOptions{}, seeds);
  if (!reference.empty()) {
    const auto [name, path] = name_and_path(reference);
    const Volume ref = read_volume(path);
    json out;
    for (const auto& [organ, pts] : s.organs) {
      if (!name.empty() && name != organ) continue;
      int ref_value = name.empty() ? label_id(organ) : 1;
      if (name.empty() && !ref.label_names.empty()) {  // the reference's own table, if it has one
        ref_value = 0;
        for (const auto& [v, n] : ref.label_names)
          if (n == organ) ref_value = v;
      }
      out[organ] = dice(labels, label_id(organ), ref, ref_value);
    }
    std::cout << out.dump(2) << "\n";
  }
  write_label_nifti(labels, output);
  std::fprintf(stderr, "[softatlas segment] wrote %s\n", output.c_str());
  return 0;
}

int run_check(const std::string& folder) {
  std::string report;
  const bool ok = check_organ_set(folder, &report);
  std::cout << report;
  if (!ok) {
    std::fprintf(stderr, "softatlas: %s: an organ surface fails the checks (see \"ok\": false above)\n",
                 folder.c_str());
    return 1;
  }
  return 0;
}

struct ExportArgs {
  std::string folder, output, web;
};

int run_export(const ExportArgs& a) {
  const auto& [folder, output, web] = a;
  if (output.empty() && web.empty()) throw InputError("softatlas export", "expected -o atlas.glb or --web DIR");
  if (!web.empty()) {
    export_web(folder, web, web_dist_folder());
    std::fprintf(stderr, "[softatlas export] wrote %s (serve it, then open index.html; docs/web.md)\n", web.c_str());
    return 0;
  }
  export_gltf(folder, output);
  std::fprintf(stderr, "[softatlas export] wrote %s\n", output.c_str());
  return 0;
}

struct BenchArgs {
  BuildCli cli;
  bool as_json = false;
  int repeat = 1;
  std::string name;
  std::vector<int> resample_dims;
};

int run_bench(const BenchArgs& a) {
  const auto& [cli, as_json, repeat, name, resample_dims] = a;
  std::mt19937_64 rng(std::random_device{}());
  BuildOptions base = cli.options();
  const fs::path resample_dir = fs::temp_directory_path() / ("softatlas-resample-" + std::to_string(rng()));
  struct Cleanup {
    fs::path p;
    ~Cleanup() {
      std::error_code ec;
      fs::remove_all(p, ec);
    }
  } cleanup{resample_dir};
  json resampled;
  if (!resample_dims.empty()) {
    const std::array<int, 3> to{resample_dims[0], resample_dims[1], resample_dims[2]};
    fs::create_directories(resample_dir);
    const Volume ct = read_volume(base.ct_path);
    base.ct_path = (resample_dir / "ct.nii.gz").string();
    write_label_nifti(resample(ct, to, false), base.ct_path);
    for (size_t i = 0; i < base.labels.size(); ++i) {
      const Volume l = read_volume(base.labels[i].path);
      std::array<int, 3> lto;
      for (int d = 0; d < 3; ++d)
        lto[d] = static_cast<int>(std::lround(static_cast<double>(l.dims[d]) * to[d] / ct.dims[d]));
      base.labels[i].path = (resample_dir / ("labels" + std::to_string(i) + ".nii.gz")).string();
      write_label_nifti(resample(l, lto, true), base.labels[i].path);
    }
    resampled = {to[0], to[1], to[2]};
  }
  json best;
  double best_total = 1e300;
  for (int r = 0; r < std::max(repeat, 1); ++r) {
    const fs::path tmp = fs::temp_directory_path() / ("softatlas-bench-" + std::to_string(rng()));
    BuildOptions o = base;
    o.output = tmp.string();
    o.quiet = cli.quiet || as_json;
    const auto t0 = std::chrono::steady_clock::now();
    BuildResult res;
    try {
      res = build_organ_set(o);
    } catch (...) {
      std::error_code ec;
      fs::remove_all(tmp, ec);
      throw;
    }
    const double total = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::error_code ec;
    fs::remove_all(tmp, ec);
    if (total < best_total) {
      best_total = total;
      best = json::object();
      best["bench"] = "pipeline";
      best["case"] = name.empty() ? (o.ct_path.empty() ? std::string("meshes") : o.ct_path) : name;
      json stages = json::object();
      for (const auto& [k, v] : res.times.seconds) stages[k] = v;
      best["stage_seconds"] = stages;
      best["total_seconds"] = total;
      best["organs"] = res.organs;
      best["connections"] = res.connections;
      if (!resampled.is_null()) best["resampled_to"] = resampled;
      best["quality"] = json::parse(res.quality_json)["organs"];
    }
  }
  best["repeat"] = std::max(repeat, 1);
  if (as_json) {
    std::cout << best.dump(2) << "\n";
  } else {
    std::printf("| stage | seconds |\n|---|---|\n");
    for (auto it = best["stage_seconds"].begin(); it != best["stage_seconds"].end(); ++it)
      std::printf("| %s | %.2f |\n", it.key().c_str(), it.value().get<double>());
    std::printf("| total | %.2f |\n", best_total);
  }
  return 0;
}

// Registration: each command's options live in a shared state its callback reads.
void add_build(CLI::App& root, cli::Status* status) {
  CLI::App* app = root.add_subcommand("build", "CT (+ labels or seeds) or meshes -> organ set");
  auto a = std::make_shared<BuildCli>();
  a->add_to(*app, true);
  cli::on_run(app, status, [a] { return run_build(*a); });
}

void add_segment(CLI::App& root, cli::Status* status) {
  CLI::App* app = root.add_subcommand("segment", "seeded segmentation -> label map (TotalSegmentator ids)");
  auto a = std::make_shared<SegmentArgs>();
  app->add_option("ct", a->ct, "CT volume")->required();
  app->add_option("--seeds", a->seeds, "seed points (YAML)")->required();
  app->add_option("-o,--output", a->output, "label map to write (.nii or .nii.gz)")->required();
  app->add_option("--dice", a->reference,
                  "reference label map (or NAME=MASK) on the CT grid: print Dice per organ as JSON");
  cli::on_run(app, status, [a] { return run_segment(*a); });
}

void add_check(CLI::App& root, cli::Status* status) {
  CLI::App* app = root.add_subcommand("check", "validate an organ set and print its quality report");
  auto folder = std::make_shared<std::string>();
  app->add_option("set", *folder, "organ-set folder")->required();
  cli::on_run(app, status, [folder] { return run_check(*folder); });
}

void add_export(CLI::App& root, cli::Status* status) {
  CLI::App* app =
      root.add_subcommand("export", "organ set -> glTF 2.0 (.glb binary, .gltf JSON + .bin), or a WebXR page (--web)");
  auto a = std::make_shared<ExportArgs>();
  app->add_option("set", a->folder, "organ-set folder")->required();
  auto* glb = app->add_option("-o,--output", a->output, "output .glb or .gltf");
  auto* page = app->add_option("--web", a->web, "output folder: static WebXR page (docs/web.md)");
  glb->excludes(page);
  cli::on_run(app, status, [a] { return run_export(*a); });
}

void add_bench_pipeline(CLI::App& bench, cli::Status* status) {
  CLI::App* app = bench.add_subcommand("pipeline", "time the build stage by stage");
  auto a = std::make_shared<BenchArgs>();
  a->cli.add_to(*app, false);
  app->add_flag("--json", a->as_json, "machine-readable result on stdout");
  app->add_option("--repeat", a->repeat, "runs (the fastest is reported)");
  app->add_option("--name", a->name, "case name in the report");
  app->add_option("--resample", a->resample_dims, "resample CT and labels to NX,NY,NZ first (e.g. 512,512,300)")
      ->delimiter(',')
      ->expected(3);
  cli::on_run(app, status, [a] { return run_bench(*a); });
}

}  // namespace

void add_commands(CLI::App& root, cli::Status* status) {
  add_build(root, status);
  add_segment(root, status);
  add_check(root, status);
  add_export(root, status);
  CLI::App* bench = cli::group(root, "bench", "benchmarks (JSON on stdout)");
  add_bench_pipeline(*bench, status);
  add_bench_segment(*bench, status);
}

int cli_main(const std::vector<std::string>& args) { return cli::run_only(add_commands, args); }

}  // namespace softatlas::pipeline
