// `softatlas bench segment`: the fair evaluation of the seeded segmentation. Each draw places 5
// random interior seeds per organ and 10 random background points (no correction clicks) and
// scores the result against the TotalSegmentator reference: Dice and volume ratio per organ,
// mean and worst over 10 fixed draws, on the shared CTs and on stress variants of them.
#include "softatlas/pipeline/bench_segment.hpp"

#include <CLI/CLI.hpp>

#include "softatlas/io/cli.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <queue>
#include <random>

#include "softatlas/pipeline/label_table.hpp"
#include "softatlas/sim/error.hpp"
#include "grid.hpp"

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace softatlas::pipeline {
namespace {

// Unenhanced HU of the organs whose contrast the "unenhanced" variant removes (typical
// non-contrast CT values; kidneys and adrenals for CTs that have them).
const std::map<std::string, double>& unenhanced_hu() {
  static const std::map<std::string, double> m = {{"liver", 50},
                                                  {"spleen", 45},
                                                  {"pancreas", 40},
                                                  {"aorta", 40},
                                                  {"inferior_vena_cava", 40},
                                                  {"portal_vein_and_splenic_vein", 40},
                                                  {"heart", 40},
                                                  {"pulmonary_vein", 40},
                                                  {"superior_vena_cava", 40},
                                                  {"kidney_left", 30},
                                                  {"kidney_right", 30},
                                                  {"adrenal_gland_left", 30},
                                                  {"adrenal_gland_right", 30}};
  return m;
}

EvalCase unenhance(const EvalCase& c) {
  EvalCase out = c;
  const auto sp = spacing_mm(c.ct);
  const double one_mm[3] = {1.0 / sp[0], 1.0 / sp[1], 1.0 / sp[2]};
  const std::vector<float> smooth = gaussian(c.ct.values, c.ct.dims, one_mm);
  const size_t n = c.ct.values.size();
  // target(p): unenhanced HU of p's organ, alpha(p): the organ indicator blurred over a voxel
  // so that the organ's edge blends into its surroundings as a partial-volume edge does.
  std::vector<float> target(n, 0.0f), inside(n, 0.0f);
  for (size_t id = 0; id < n; ++id) {
    const int l = static_cast<int>(std::lround(c.ref.values[id]));
    if (l == 0) continue;
    const auto it = unenhanced_hu().find(label_name(l));
    if (it == unenhanced_hu().end()) continue;
    target[id] = static_cast<float>(it->second);
    inside[id] = 1.0f;
  }
  const double half_voxel[3] = {0.5, 0.5, 0.5};
  const std::vector<float> alpha = gaussian(inside, c.ct.dims, half_voxel);
  const std::vector<float> weighted = gaussian(target, c.ct.dims, half_voxel);
  for (size_t id = 0; id < n; ++id) {
    if (alpha[id] <= 1e-3f) continue;
    const float t = weighted[id] / alpha[id];  // the blended organs' unenhanced value
    const float noise = c.ct.values[id] - smooth[id];
    out.ct.values[id] = (1 - alpha[id]) * c.ct.values[id] + alpha[id] * (t + noise);
  }
  return out;
}

EvalCase to_3mm(const EvalCase& c) {
  EvalCase out = c;
  const auto sp = spacing_mm(c.ct);
  std::array<int, 3> to{};
  double blur[3];
  for (int a = 0; a < 3; ++a) {
    to[a] = std::max(1, static_cast<int>(std::lround(c.ct.dims[a] * sp[a] / 3.0)));
    // Slice profile: a Gaussian whose FWHM makes up the difference to 3 mm.
    blur[a] = std::sqrt(std::max(0.0, 9.0 - sp[a] * sp[a])) / 2.3548 / sp[a];
  }
  Volume blurred = c.ct;
  blurred.values = gaussian(c.ct.values, c.ct.dims, blur);
  out.ct = resample(blurred, to, false);
  out.ref = resample(c.ref, to, true);
  return out;
}

EvalCase add_noise(const EvalCase& c) {
  EvalCase out = c;
  std::mt19937_64 rng(20261201);
  // Box-Muller on the generator's raw output (portable across standard libraries).
  auto uniform = [&] { return (static_cast<double>(rng() >> 11) + 0.5) / 9007199254740992.0; };
  for (float& v : out.ct.values) {
    const double u1 = uniform(), u2 = uniform();
    v += static_cast<float>(40.0 * std::sqrt(-2.0 * std::log(u1)) * std::cos(2 * M_PI * u2));
  }
  return out;
}

// Distance (mm, along face-neighbour paths) from each voxel of label `id` to the nearest voxel
// outside it; the grid's border counts as outside. Other voxels get 0.
std::vector<float> depth_mm(const Volume& ref, int id) {
  const auto& d = ref.dims;
  const auto sp = spacing_mm(ref);
  const size_t n = ref.values.size();
  std::vector<float> dist(n, std::numeric_limits<float>::infinity());
  using Item = std::pair<float, size_t>;
  std::priority_queue<Item, std::vector<Item>, std::greater<Item>> heap;
  for (size_t v = 0; v < n; ++v) {
    if (std::lround(ref.values[v]) != id) {
      dist[v] = 0;
      continue;
    }
    const int i = static_cast<int>(v % d[0]), j = static_cast<int>((v / d[0]) % d[1]),
              k = static_cast<int>(v / (static_cast<size_t>(d[0]) * d[1]));
    float edge = std::numeric_limits<float>::infinity();
    if (i == 0 || i == d[0] - 1) edge = std::min(edge, static_cast<float>(sp[0]));
    if (j == 0 || j == d[1] - 1) edge = std::min(edge, static_cast<float>(sp[1]));
    if (k == 0 || k == d[2] - 1) edge = std::min(edge, static_cast<float>(sp[2]));
    for_each_face_neighbour(d, v, [&](size_t q, int axis) {
      if (std::lround(ref.values[q]) != id) edge = std::min(edge, static_cast<float>(sp[axis]));
    });
    if (std::isfinite(edge)) dist[v] = edge, heap.push({edge, v});
  }
  while (!heap.empty()) {
    const auto [c, v] = heap.top();
    heap.pop();
    if (c > dist[v]) continue;
    for_each_face_neighbour(d, v, [&, c = c](size_t q, int axis) {
      const float nc = c + static_cast<float>(sp[axis]);
      if (nc < dist[q]) dist[q] = nc, heap.push({nc, q});
    });
  }
  return dist;
}

uint64_t pick(std::mt19937_64& rng, size_t n) { return rng() % n; }

}  // namespace

Volume masks_on_grid(const Volume& grid, const std::vector<std::pair<std::string, int>>& masks) {
  Volume out;
  out.dims = grid.dims;
  out.ijk_to_ras = grid.ijk_to_ras;
  out.format = "nifti";
  out.values.assign(grid.values.size(), 0.0f);
  for (const auto& [path, id] : masks) {
    const Volume m = read_volume(path);
    for (int k = 0; k < grid.dims[2]; ++k)
      for (int j = 0; j < grid.dims[1]; ++j)
        for (int i = 0; i < grid.dims[0]; ++i) {
          const auto v = m.voxel(grid.world(i, j, k));
          const long a = std::lround(v[0]), b = std::lround(v[1]), c = std::lround(v[2]);
          if (a < 0 || b < 0 || c < 0 || a >= m.dims[0] || b >= m.dims[1] || c >= m.dims[2]) continue;
          if (m.values[m.index(int(a), int(b), int(c))] != 0 && out.values[out.index(i, j, k)] == 0)
            out.values[out.index(i, j, k)] = static_cast<float>(id);
        }
  }
  return out;
}

Volume resample(const Volume& v, const std::array<int, 3>& to, bool nearest) {
  Volume out;
  out.dims = to;
  out.path = v.path;
  out.format = v.format;
  out.label_names = v.label_names;
  double scale[3];
  for (int d = 0; d < 3; ++d) scale[d] = static_cast<double>(v.dims[d]) / to[d];
  // New voxel centre c maps to old continuous index (c + 0.5) * scale - 0.5.
  out.ijk_to_ras = v.ijk_to_ras;
  for (int r = 0; r < 3; ++r) {
    double shift = 0;
    for (int c = 0; c < 3; ++c) {
      out.ijk_to_ras[r * 4 + c] = v.ijk_to_ras[r * 4 + c] * scale[c];
      shift += v.ijk_to_ras[r * 4 + c] * (0.5 * scale[c] - 0.5);
    }
    out.ijk_to_ras[r * 4 + 3] = v.ijk_to_ras[r * 4 + 3] + shift;
  }
  out.values.resize(static_cast<size_t>(to[0]) * to[1] * to[2]);
  auto at = [&](int i, int j, int k) {
    i = std::clamp(i, 0, v.dims[0] - 1), j = std::clamp(j, 0, v.dims[1] - 1), k = std::clamp(k, 0, v.dims[2] - 1);
    return v.values[v.index(i, j, k)];
  };
  for (int k = 0; k < to[2]; ++k)
    for (int j = 0; j < to[1]; ++j)
      for (int i = 0; i < to[0]; ++i) {
        const double x = (i + 0.5) * scale[0] - 0.5, y = (j + 0.5) * scale[1] - 0.5, z = (k + 0.5) * scale[2] - 0.5;
        float val;
        if (nearest) {
          val =
              at(static_cast<int>(std::lround(x)), static_cast<int>(std::lround(y)), static_cast<int>(std::lround(z)));
        } else {
          const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y)),
                    z0 = static_cast<int>(std::floor(z));
          const double fx = x - x0, fy = y - y0, fz = z - z0;
          double acc = 0;
          for (int c = 0; c < 8; ++c) {
            const double w = ((c & 1) ? fx : 1 - fx) * ((c & 2) ? fy : 1 - fy) * ((c & 4) ? fz : 1 - fz);
            acc += w * at(x0 + (c & 1), y0 + ((c >> 1) & 1), z0 + ((c >> 2) & 1));
          }
          val = static_cast<float>(std::lround(acc));
        }
        out.values[out.index(i, j, k)] = val;
      }
  return out;
}

EvalCase load_eval_case(const std::string& data_dir, const std::string& name) {
  EvalCase c;
  c.name = name;
  c.variant = "original";
  const std::string chest = data_dir + "/ct/chest_cta_crops/", slab = data_dir + "/ct/abdomen_dicom_slab/";
  if (name == "slab") {
    c.ct = read_volume(slab + "ct_from_dicom.nii.gz");
    c.ref = read_volume(slab + "example_seg_dicom.nii.gz");
    if (c.ref.dims != c.ct.dims) throw InputError(slab + "example_seg_dicom.nii.gz", "expected the CT's grid");
    c.organs = {{"liver", 5}, {"spleen", 1}, {"stomach", 6}, {"pancreas", 7}, {"aorta", 52}};
  } else if (name == "heart_crop") {
    // The reference heart holds the pulmonary trunk (docs/pipeline.md).
    c.ct = read_volume(chest + "ct_heart_crop.nii.gz");
    c.ref = masks_on_grid(c.ct, {{chest + "heart_on_ct_heart_crop_grid.nii.gz", 51}, {chest + "aorta.nii.gz", 52}});
    c.organs = {{"heart", 51}, {"aorta", 52}};
  } else if (name == "aorta_crop") {
    c.ct = read_volume(chest + "ct_aorta_crop.nii.gz");
    c.ref = masks_on_grid(c.ct, {{chest + "aorta.nii.gz", 52}, {chest + "heart.nii.gz", 51}});
    c.organs = {{"aorta", 52}, {"heart", 51}};
  } else {
    throw InputError("--cases", "unknown case '" + name + "' (expected slab, heart_crop, aorta_crop)");
  }
  c.ref.path = name + " reference";
  return c;
}

const std::vector<std::string>& stress_variants() {
  static const std::vector<std::string> v = {"original", "3mm", "unenhanced", "noise", "unenhanced_3mm"};
  return v;
}

EvalCase make_variant(const EvalCase& c, const std::string& variant) {
  EvalCase out;
  if (variant == "original")
    out = c;
  else if (variant == "3mm")
    out = to_3mm(c);
  else if (variant == "unenhanced")
    out = unenhance(c);
  else if (variant == "noise")
    out = add_noise(c);
  else if (variant == "unenhanced_3mm")
    out = to_3mm(unenhance(c));
  else
    throw InputError("--variants",
                     "unknown variant '" + variant + "' (expected original, 3mm, unenhanced, noise, unenhanced_3mm)");
  out.variant = variant;
  return out;
}

uint64_t draw_seed(int draw) { return 0x50f7a71a5ull + 7919ull * static_cast<uint64_t>(draw); }

Seeds draw_seeds(const EvalCase& c, uint64_t seed, int per_organ, int background) {
  std::mt19937_64 rng(seed);
  const auto& d = c.ct.dims;
  const size_t n = c.ct.values.size();
  Seeds s;
  auto world = [&](size_t v) {
    const int i = static_cast<int>(v % d[0]), j = static_cast<int>((v / d[0]) % d[1]),
              k = static_cast<int>(v / (static_cast<size_t>(d[0]) * d[1]));
    return c.ct.world(i, j, k);
  };
  std::vector<char> organ(n, 0);
  for (const auto& o : c.organs) {
    const std::vector<float> depth = depth_mm(c.ref, o.id);
    float deepest = 0;
    for (float x : depth) deepest = std::max(deepest, x);
    if (deepest <= 0) throw InputError(c.name + " " + c.variant, "organ " + o.name + " is not in the reference");
    const float need = std::min(3.0f, 0.5f * deepest);
    std::vector<size_t> cand;
    for (size_t v = 0; v < n; ++v) {
      if (depth[v] >= need) cand.push_back(v);
      if (depth[v] > 0) organ[v] = 1;
    }
    auto& pts = s.organs[o.name];
    for (int t = 0; t < per_organ && !cand.empty(); ++t) {  // without replacement
      const size_t at = pick(rng, cand.size());
      pts.push_back(world(cand[at]));
      cand[at] = cand.back();
      cand.pop_back();
    }
  }
  // Background: rejection sampling over the whole grid.
  for (long tries = 0; static_cast<int>(s.background.size()) < background && tries < 10'000'000; ++tries) {
    const size_t v = pick(rng, n);
    if (std::lround(c.ref.values[v]) != 0 || c.ct.values[v] < -500 || c.ct.values[v] > 300) continue;
    const int i = static_cast<int>(v % d[0]), j = static_cast<int>((v / d[0]) % d[1]),
              k = static_cast<int>(v / (static_cast<size_t>(d[0]) * d[1]));
    bool near = false;
    for (int z = -2; z <= 2 && !near; ++z)
      for (int y = -2; y <= 2 && !near; ++y)
        for (int x = -2; x <= 2 && !near; ++x) {
          if (x * x + y * y + z * z >= 9) continue;
          const int a = i + x, b = j + y, e = k + z;
          if (a < 0 || b < 0 || e < 0 || a >= d[0] || b >= d[1] || e >= d[2]) continue;
          near = organ[c.ct.index(a, b, e)];
        }
    if (!near) s.background.push_back(world(v));
  }
  return s;
}

EvalRun run_draw(const EvalCase& c, uint64_t seed, const SegmentOptions& options) {
  const Seeds s = draw_seeds(c, seed);
  const auto t0 = std::chrono::steady_clock::now();
  const Volume seg = segment_seeded(c.ct, s, options, c.name + " " + c.variant + " draw");
  EvalRun r;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  for (const auto& o : c.organs) {
    size_t ns = 0, nr = 0, both = 0;
    for (size_t v = 0; v < seg.values.size(); ++v) {
      const bool x = std::lround(seg.values[v]) == o.id, y = std::lround(c.ref.values[v]) == o.id;
      ns += x, nr += y, both += x && y;
    }
    r.dice.push_back(ns + nr ? 2.0 * static_cast<double>(both) / static_cast<double>(ns + nr) : 1.0);
    r.volume_ratio.push_back(nr ? static_cast<double>(ns) / static_cast<double>(nr) : 0.0);
  }
  return r;
}

namespace {
struct BenchSegmentArgs {
  std::string data = "../shared/data", write_dir;
  std::vector<std::string> cases = {"slab", "heart_crop", "aorta_crop"}, variants = stress_variants();
  int draws = 10;
  bool as_json = false;
  SegmentOptions options;
  bool no_tubes = false, no_walls = false;
};

int run_bench_segment(BenchSegmentArgs a) {
  auto& [data, write_dir, cases, variants, draws, as_json, options, no_tubes, no_walls] = a;
  if (no_tubes) options.tubes.clear();
  if (no_walls) options.walls.clear();
  if (draws < 1) throw InputError("--draws", "expected at least 1 draw");
  if (!write_dir.empty()) {
    fs::create_directories(write_dir);
    for (const auto& name : cases) {
      const EvalCase base = load_eval_case(data, name);
      for (const auto& v : variants) {
        const EvalCase c = make_variant(base, v);
        const std::string stem = write_dir + "/" + name + "_" + v;
        Volume ct = c.ct;
        write_label_nifti(ct, stem + "_ct.nii.gz");
        write_label_nifti(c.ref, stem + "_ref.nii.gz");
        for (int k = 0; k < draws; ++k) {
          const Seeds s = draw_seeds(c, draw_seed(k));
          std::FILE* f = std::fopen((stem + "_seeds" + std::to_string(k) + ".yaml").c_str(), "w");
          if (!f) throw InputError(write_dir, "cannot write the seed files");
          std::fprintf(f, "organs:\n");
          for (const auto& [organ, pts] : s.organs) {
            std::fprintf(f, "  %s:\n", organ.c_str());
            for (const auto& p : pts) std::fprintf(f, "    - [%.2f, %.2f, %.2f]\n", p[0], p[1], p[2]);
          }
          std::fprintf(f, "background:\n");
          for (const auto& p : s.background) std::fprintf(f, "  - [%.2f, %.2f, %.2f]\n", p[0], p[1], p[2]);
          std::fclose(f);
        }
        std::fprintf(stderr, "[softatlas bench segment] wrote %s_{ct,ref}.nii.gz and %d seed files\n", stem.c_str(),
                     draws);
      }
    }
    return 0;
  }
  json out;
  out["bench"] = "segment";
  out["method"] = options.method;
  out["draws"] = draws;
  out["seeds_per_organ"] = 5;
  out["background_points"] = 10;
  out["results"] = json::array();
  std::string table =
      "| case | variant | organ | Dice mean | Dice worst | volume ratio mean | volume ratio max |\n"
      "| --- | --- | --- | --- | --- | --- | --- |\n";
  for (const auto& name : cases) {
    const EvalCase base = load_eval_case(data, name);
    for (const auto& v : variants) {
      const EvalCase c = make_variant(base, v);
      std::vector<EvalRun> runs;
      double seconds = 0;
      for (int k = 0; k < draws; ++k) {
        runs.push_back(run_draw(c, draw_seed(k), options));
        seconds += runs.back().seconds;
      }
      json r;
      r["case"] = name;
      r["variant"] = v;
      r["seconds_mean"] = seconds / draws;
      r["organs"] = json::object();
      for (size_t o = 0; o < c.organs.size(); ++o) {
        std::vector<double> dc, vr;
        for (const auto& run : runs) dc.push_back(run.dice[o]), vr.push_back(run.volume_ratio[o]);
        double mean = 0, vmean = 0;
        for (size_t k = 0; k < dc.size(); ++k) mean += dc[k] / dc.size(), vmean += vr[k] / vr.size();
        const double worst = *std::min_element(dc.begin(), dc.end()), vmax = *std::max_element(vr.begin(), vr.end());
        r["organs"][c.organs[o].name] = {
            {"dice_mean", mean},        {"dice_worst", worst}, {"volume_ratio_mean", vmean},
            {"volume_ratio_max", vmax}, {"dice", dc},          {"volume_ratio", vr}};
        char line[256];
        std::snprintf(line, sizeof line, "| %s | %s | %s | %.3f | %.3f | %.2f | %.2f |\n", name.c_str(), v.c_str(),
                      c.organs[o].name.c_str(), mean, worst, vmean, vmax);
        table += line;
        std::fprintf(stderr, "[softatlas bench segment] %s", line);
      }
      out["results"].push_back(r);
    }
  }
  if (as_json)
    std::cout << out.dump(2) << "\n";
  else
    std::cout << table;
  return 0;
}

}  // namespace

void add_bench_segment(CLI::App& bench, cli::Status* status) {
  CLI::App* app =
      bench.add_subcommand("segment", "seeded segmentation, random seed draws on the shared CTs and stress variants");
  auto a = std::make_shared<BenchSegmentArgs>();
  app->add_option("--data", a->data, "shared data folder (holds ct/)");
  app->add_option("--cases", a->cases, "slab, heart_crop, aorta_crop (comma-separated)")->delimiter(',');
  app->add_option("--variants", a->variants, "original, 3mm, unenhanced, noise, unenhanced_3mm")->delimiter(',');
  app->add_option("--draws", a->draws, "random draws per case and variant (fixed seeds; default 10)");
  app->add_option("--write-variants", a->write_dir,
                  "write each variant's CT and reference (CASE_VARIANT_ct.nii.gz, _ref.nii.gz) and the seed "
                  "files of the draws to this folder, then stop");
  app->add_option("--method", a->options.method, "graph_cut (default) or growth (the earlier region growing)");
  app->add_option("--smoothness", a->options.cut_smoothness_mm, "graph cut: boundary weight, mm");
  app->add_option("--distance-weight", a->options.cut_distance_weight, "graph cut: distance prior, nats per radius");
  app->add_flag("--no-tubes", a->no_tubes, "no tube model for the aorta");
  app->add_flag("--no-walls", a->no_walls, "no wall model for the heart");
  app->add_option("--background-model", a->options.cut_background, "graph cut: image (whole image) or box");
  app->add_option("--window-weight", a->options.cut_window_weight, "graph cut: share of the seeds' window");
  app->add_option("--radius-scale", a->options.cut_radius_scale, "graph cut: scale of the organs' radius priors");
  app->add_flag("--json", a->as_json, "machine-readable result on stdout");
  cli::on_run(app, status, [a] { return run_bench_segment(*a); });
}

}  // namespace softatlas::pipeline
