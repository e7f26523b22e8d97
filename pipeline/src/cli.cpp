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
#include <set>
#include <sys/resource.h>

#include "softatlas/io/cli.hpp"
#include "softatlas/io/cli_number.hpp"
#include "softatlas/io/mesh_io.hpp"
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
  int jobs = 0;
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
    app.add_option("-j,--jobs", jobs, "organs built at once, one thread each (default: one per core)")
        ->check(CLI::Range(0, 256));
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
    b.jobs = jobs;
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
  std::vector<int> compare_jobs;  // e.g. 1,2: the same build with each job count, side by side
  int replicate = 1;              // copies of the label map stacked along the slices
};

// CPU time of the whole process so far (user, system; every thread).
std::pair<double, double> process_cpu_seconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  auto s = [](const timeval& t) { return static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_usec); };
  return {s(u.ru_utime), s(u.ru_stime)};
}

// A larger case from the data at hand: `copies` copies of the CT and of each label map stacked
// along the slice axis; the labels of copy c > 0 get TotalSegmentator ids absent from the map (in
// id order), with the face budget of the label they copy. Real shapes, real sizes, `copies` times
// the structures (the slab's 31 labels x 2 = 62, about the ~60 of a whole abdomen).
void replicate_case(BuildOptions* b, int copies, const fs::path& dir, json* report) {
  const Volume ct = read_volume(b->ct_path);
  auto stack = [&](const Volume& v) {
    Volume out = v;
    out.dims[2] = v.dims[2] * copies;
    out.values.clear();
    for (int c = 0; c < copies; ++c) out.values.insert(out.values.end(), v.values.begin(), v.values.end());
    out.label_names.clear();
    return out;
  };
  b->ct_path = (dir / "ct.nii.gz").string();
  write_label_nifti(stack(ct), b->ct_path);
  std::set<int> used;
  std::vector<Volume> maps;
  for (const LabelSource& src : b->labels) {
    Volume l = read_volume(src.path);
    if (l.dims != ct.dims)
      throw InputError(src.path, "--replicate needs label maps on the CT's grid (" + std::to_string(l.dims[0]) + "x" +
                                     std::to_string(l.dims[1]) + "x" + std::to_string(l.dims[2]) + " here)");
    if (!src.organ.empty()) throw InputError(src.path, "--replicate takes multi-label maps, not NAME=MASK");
    // Values as TotalSegmentator ids (a map's own table names them).
    for (float& x : l.values) {
      const int v = static_cast<int>(std::lround(x));
      if (v == 0) continue;
      const int id = l.label_names.empty() ? v : label_id(l.label_names.count(v) ? l.label_names.at(v) : "");
      x = static_cast<float>(id);
      if (id > 0) used.insert(id);
    }
    maps.push_back(std::move(l));
  }
  std::map<int, int> next_id;  // (copy * 1000 + id) -> new id
  int free_id = 1;
  json renamed = json::object();
  for (size_t i = 0; i < maps.size(); ++i) {
    Volume out = stack(maps[i]);
    const size_t per_copy = maps[i].values.size();
    for (int c = 1; c < copies; ++c)
      for (size_t x = 0; x < per_copy; ++x) {
        float& val = out.values[c * per_copy + x];
        const int id = static_cast<int>(std::lround(val));
        if (id <= 0) continue;
        auto [it, fresh] = next_id.try_emplace(c * 1000 + id, 0);
        if (fresh) {
          while (free_id <= label_count() && (used.count(free_id) || label_name(free_id).empty())) ++free_id;
          if (free_id > label_count())
            throw InputError("--replicate", "not enough TotalSegmentator ids left for the copies");
          it->second = free_id;
          used.insert(free_id);
          const std::string from = label_name(id), to = label_name(free_id);
          if (!b->budgets.count(to))
            b->budgets[to] = b->budgets.count(from) ? b->budgets[from] : default_face_budget(from);
          renamed[to] = from;
        }
        val = static_cast<float>(it->second);
      }
    b->labels[i].path = (dir / ("labels" + std::to_string(i) + ".nii.gz")).string();
    write_label_nifti(out, b->labels[i].path);
  }
  (*report)["copies"] = copies;
  (*report)["copied_labels"] = renamed;
}

// Every file of two organ sets equal byte for byte, quality.json apart from its timings.
bool same_organ_sets(const fs::path& a, const fs::path& b, std::string* first_difference) {
  std::vector<fs::path> files;
  for (const auto& e : fs::recursive_directory_iterator(a))
    if (e.is_regular_file()) files.push_back(fs::relative(e.path(), a));
  size_t count_b = 0;
  for (const auto& e : fs::recursive_directory_iterator(b)) count_b += e.is_regular_file();
  if (count_b != files.size()) return *first_difference = "number of files", false;
  for (const fs::path& f : files) {
    std::string x = io::read_text_file((a / f).string()), y = io::read_text_file((b / f).string());
    if (f == "quality.json") {
      json qx = json::parse(x), qy = json::parse(y);
      for (const char* k : {"stage_seconds", "organ_seconds"}) qx.erase(k), qy.erase(k);
      x = qx.dump(), y = qy.dump();
    }
    if (x != y) return *first_difference = f.string(), false;
  }
  return true;
}

int run_bench(const BenchArgs& a) {
  const auto& cli = a.cli;
  std::mt19937_64 rng(std::random_device{}());
  BuildOptions base = cli.options();
  const fs::path work_dir = fs::temp_directory_path() / ("softatlas-bench-" + std::to_string(rng()));
  struct Cleanup {
    fs::path p;
    ~Cleanup() {
      std::error_code ec;
      fs::remove_all(p, ec);
    }
  } cleanup{work_dir};
  fs::create_directories(work_dir);
  json resampled, replicated;
  if (!a.resample_dims.empty()) {
    const std::array<int, 3> to{a.resample_dims[0], a.resample_dims[1], a.resample_dims[2]};
    const Volume ct = read_volume(base.ct_path);
    base.ct_path = (work_dir / "ct.nii.gz").string();
    write_label_nifti(resample(ct, to, false), base.ct_path);
    for (size_t i = 0; i < base.labels.size(); ++i) {
      const Volume l = read_volume(base.labels[i].path);
      std::array<int, 3> lto;
      for (int d = 0; d < 3; ++d)
        lto[d] = static_cast<int>(std::lround(static_cast<double>(l.dims[d]) * to[d] / ct.dims[d]));
      base.labels[i].path = (work_dir / ("labels" + std::to_string(i) + ".nii.gz")).string();
      write_label_nifti(resample(l, lto, true), base.labels[i].path);
    }
    resampled = {to[0], to[1], to[2]};
  }
  if (a.replicate > 1) {
    const fs::path dir = work_dir / "replicated";
    fs::create_directories(dir);
    replicate_case(&base, a.replicate, dir, &replicated);
  }
  std::vector<int> job_counts = a.compare_jobs;
  if (job_counts.empty()) job_counts = {cli.jobs};
  json runs = json::array();
  std::vector<fs::path> outputs;
  for (size_t n = 0; n < job_counts.size(); ++n) {
    json best;
    double best_total = 1e300;
    for (int r = 0; r < std::max(a.repeat, 1); ++r) {
      const fs::path out = work_dir / ("set-" + std::to_string(n) + "-" + std::to_string(r));
      BuildOptions o = base;
      o.output = out.string();
      o.quiet = cli.quiet || a.as_json;
      o.jobs = job_counts[n];
      const auto cpu0 = process_cpu_seconds();
      const auto t0 = std::chrono::steady_clock::now();
      const BuildResult res = build_organ_set(o);
      const double total = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      const auto cpu1 = process_cpu_seconds();
      if (total < best_total) {
        best_total = total;
        best = json::object();
        best["jobs"] = res.jobs;
        best["total_seconds"] = total;
        best["cpu_user_seconds"] = cpu1.first - cpu0.first;
        best["cpu_system_seconds"] = cpu1.second - cpu0.second;
        json stages = json::object();
        for (const auto& [k, v] : res.times.seconds) stages[k] = v;
        best["stage_seconds"] = stages;
        best["organs"] = res.organs;
        best["connections"] = res.connections;
        json per_organ = json::array();
        double organ_cpu = 0, longest = 0;
        for (const auto& s : res.organ_seconds) {
          per_organ.push_back({{"organ", s.organ}, {"surface", s.surface_s}, {"remesh", s.remesh_s}, {"cpu", s.cpu_s}});
          organ_cpu += s.cpu_s, longest = std::max(longest, s.cpu_s);
        }
        best["organ_seconds"] = per_organ;
        // Load-independent view: the organs' CPU time, the longest single organ (no schedule
        // can beat it), and the serial parts (read, connect, write) from the CPU total.
        best["organ_cpu_seconds"] = organ_cpu;
        best["longest_organ_cpu_seconds"] = longest;
        best["quality"] = json::parse(res.quality_json)["organs"];
      }
      if (r == 0) {
        outputs.push_back(out);  // kept for the comparison
      } else {
        std::error_code ec;
        fs::remove_all(out, ec);
      }
    }
    best["repeat"] = std::max(a.repeat, 1);
    runs.push_back(best);
  }
  json report = runs[0];
  report["bench"] = "pipeline";
  report["case"] = a.name.empty() ? (base.ct_path.empty() ? std::string("meshes") : cli.ct) : a.name;
  if (!resampled.is_null()) report["resampled_to"] = resampled;
  if (!replicated.is_null()) report["replicated"] = replicated;
  if (job_counts.size() > 1) {
    json cmp = json::array();
    for (const auto& r : runs) {
      json row = r;
      row.erase("quality");
      row.erase("organ_seconds");
      cmp.push_back(row);
    }
    report["compare_jobs"] = cmp;
    // The first run of each job count against the first of the first: the output must not
    // depend on the number of jobs.
    bool same = true;
    std::string diff;
    for (size_t n = 1; n < outputs.size() && same; ++n) same = same_organ_sets(outputs[0], outputs[n], &diff);
    report["identical_output"] = same;
    if (!same) report["first_difference"] = diff;
  }
  if (a.as_json) {
    std::cout << report.dump(2) << "\n";
  } else {
    for (const auto& r : runs) {
      std::printf("jobs %d: %.2f s wall, %.2f s user, %.2f s system\n", r["jobs"].get<int>(),
                  r["total_seconds"].get<double>(), r["cpu_user_seconds"].get<double>(),
                  r["cpu_system_seconds"].get<double>());
      std::printf("| stage | seconds |\n|---|---|\n");
      for (auto it = r["stage_seconds"].begin(); it != r["stage_seconds"].end(); ++it)
        std::printf("| %s | %.2f |\n", it.key().c_str(), it.value().get<double>());
    }
    if (report.contains("identical_output"))
      std::printf("identical output: %s\n", report["identical_output"].get<bool>() ? "yes" : "NO");
  }
  return report.value("identical_output", true) ? 0 : 1;
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
  app->add_option("--compare-jobs", a->compare_jobs,
                  "build with each job count (e.g. 1,2), report them side by side and check the outputs are "
                  "identical")
      ->delimiter(',')
      ->check(CLI::Range(0, 256));
  app->add_option("--replicate", a->replicate,
                  "stack N copies of the CT and label map (copies get unused TotalSegmentator ids): N x the "
                  "structures")
      ->check(CLI::Range(1, 8));
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
