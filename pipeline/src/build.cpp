// The whole pipeline, stage by stage, with progress on stderr:
//   read -> (segment | import labels | read meshes) -> surface -> repair+remesh -> connect -> write
// Every input is validated before anything is written; the organ set is written atomically by
// io::write_organ_set (temporary folder, then rename), so a failed build leaves nothing behind.
#include "softatlas/pipeline/build.hpp"


#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <regex>
#include <set>
#include <sstream>
#include <thread>

#include "softatlas/io/ct_image.hpp"
#include "softatlas/io/organ_set.hpp"
#include "softatlas/io/output_folder.hpp"
#include "grid.hpp"
#include "softatlas/pipeline/label_table.hpp"
#include "softatlas/pipeline/topology.hpp"
#include "softatlas/sim/error.hpp"
#include "softatlas/sim/geometry.hpp"

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace softatlas::pipeline {

void StageTimes::add(const std::string& stage, double s) {
  for (auto& [name, t] : seconds)
    if (name == stage) {
      t += s;
      return;
    }
  seconds.emplace_back(stage, s);
}

namespace {

// The group of a TotalSegmentator name for --organs: organs (the default soft set), vessels,
// bones, muscles, or other.
std::string label_group(const std::string& n) {
  auto has = [&](const char* part) { return n.find(part) != std::string::npos; };
  if (has("vertebra") || has("rib_") || has("humerus") || has("scapula") || has("clavicula") || has("femur") ||
      has("hip_") || n == "sacrum" || n == "sternum" || n == "costal_cartilages" || n == "skull")
    return "bones";
  if (has("autochthon") || has("iliopsoas") || has("gluteus")) return "muscles";
  if (is_default_soft_organ(n)) return "organs";
  if (has("vena") || has("artery") || has("vein") || n == "brachiocephalic_trunk" || n == "aorta" || has("iliac"))
    return "vessels";
  return "other";
}

using Clock = std::chrono::steady_clock;

double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// CPU seconds of the calling thread (user + system): unlike wall time, not inflated when other
// processes share the cores.
double thread_cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

// Progress lines on stderr, or into `buffer` (an organ built on a worker thread: its lines are
// printed in organ order once the organs before it are done, so the output does not depend on
// the number of jobs).
struct Progress {
  bool quiet;
  std::string* buffer = nullptr;
  void operator()(const char* fmt, const std::string& a = "", const std::string& b = "") const {
    if (quiet) return;
    const std::string line = "[softatlas build] " + format(fmt, a, b) + "\n";
    if (buffer)
      *buffer += line;
    else
      std::fputs(line.c_str(), stderr);
  }
  static std::string format(const char* fmt, const std::string& a, const std::string& b) {
    const int n = std::snprintf(nullptr, 0, fmt, a.c_str(), b.c_str());
    std::string out(static_cast<size_t>(std::max(n, 0)) + 1, '\0');
    std::snprintf(out.data(), out.size(), fmt, a.c_str(), b.c_str());
    out.resize(static_cast<size_t>(std::max(n, 0)));
    return out;
  }
};

std::string fmt(double x, int digits = 3) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*g", digits, x);
  return buf;
}

// A loaded label source with the ids present in it.
struct LoadedLabels {
  LabelSource source;
  Volume volume;
  std::map<int, size_t> counts;  // label value -> voxels (0 excluded)
};

// A label map's own table (NIfTI extension) names its values when it has one; otherwise the
// TotalSegmentator table does.
int value_of(const LoadedLabels& l, const std::string& name) {
  if (l.volume.label_names.empty()) return label_id(name);
  for (const auto& [v, n] : l.volume.label_names)
    if (n == name) return v;
  return 0;
}

std::string name_of(const LoadedLabels& l, int value) {
  if (l.volume.label_names.empty()) return label_name(value);
  const auto it = l.volume.label_names.find(value);
  return it == l.volume.label_names.end() ? std::string() : it->second;
}

// The CT cropped to the organs' bounding box plus margin_mm (in voxel index space, so the grid and
// its transform are the CT's own), as int16 HU (rounded, clamped): what the viewer draws on a
// slice plane. The transform is the CT's ijk_to_ras shifted to the crop's first voxel.
io::CtImage crop_ct(const Volume& ct, const std::vector<io::OrganEntry>& organs, double margin_mm) {
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  for (const auto& e : organs)
    for (size_t i = 0; i < e.mesh.vertices.size(); ++i) {
      lo[i % 3] = std::min(lo[i % 3], e.mesh.vertices[i]);
      hi[i % 3] = std::max(hi[i % 3], e.mesh.vertices[i]);
    }
  int i0[3] = {ct.dims[0], ct.dims[1], ct.dims[2]}, i1[3] = {-1, -1, -1};
  for (int c = 0; c < 8; ++c) {
    const std::array<double, 3> p{(c & 1) ? hi[0] + margin_mm : lo[0] - margin_mm,
                                  (c & 2) ? hi[1] + margin_mm : lo[1] - margin_mm,
                                  (c & 4) ? hi[2] + margin_mm : lo[2] - margin_mm};
    const auto v = ct.voxel(p);
    for (int d = 0; d < 3; ++d) {
      i0[d] = std::min(i0[d], static_cast<int>(std::floor(v[d])));
      i1[d] = std::max(i1[d], static_cast<int>(std::ceil(v[d])));
    }
  }
  io::CtImage out;
  for (int d = 0; d < 3; ++d) {
    i0[d] = std::clamp(i0[d], 0, ct.dims[d] - 1);
    i1[d] = std::clamp(i1[d], i0[d], ct.dims[d] - 1);
    out.dims[d] = i1[d] - i0[d] + 1;
  }
  out.ijk_to_ras = ct.ijk_to_ras;
  const auto origin = ct.world(i0[0], i0[1], i0[2]);
  for (int r = 0; r < 3; ++r) out.ijk_to_ras[r * 4 + 3] = origin[r];
  out.hu.reserve(static_cast<size_t>(out.dims[0]) * out.dims[1] * out.dims[2]);
  for (int k = i0[2]; k <= i1[2]; ++k)
    for (int j = i0[1]; j <= i1[1]; ++j)
      for (int i = i0[0]; i <= i1[0]; ++i)
        out.hu.push_back(static_cast<int16_t>(
            std::lround(std::clamp(static_cast<double>(ct.values[ct.index(i, j, k)]), -32768.0, 32767.0))));
  return out;
}

bool boxes_overlap(const std::array<double, 6>& a, const std::array<double, 6>& b, double pad) {
  for (int d = 0; d < 3; ++d)
    if (a[d] > b[d + 3] + pad || b[d] > a[d + 3] + pad) return false;
  return true;
}

// One organ to build and where it comes from.
struct OrganJob {
  std::string name;
  int label = 0;
  int source = -1;          // index into labels (or -1 for meshes/seeds)
  std::vector<int> values;  // label values in that source
  std::string mesh_path;    // mesh mode
  int budget = 0;
};

// What one organ's build produced; filled on a worker thread, read after all have joined.
struct BuiltOrgan {
  json quality;
  io::OrganEntry entry;
  std::string log;                         // its progress lines
  std::string mesh_sha256;                 // mesh mode: the input's hash for the provenance
  double surface_s = 0.0, remesh_s = 0.0;  // wall
  double cpu_s = 0.0;                      // the thread's CPU time for this organ
};

// 0 = one per hardware thread; never more than there are organs.
size_t effective_jobs(int requested, size_t organs) {
  size_t n = requested > 0 ? static_cast<size_t>(requested) : std::max(1u, std::thread::hardware_concurrency());
  return std::max<size_t>(1, std::min(n, organs));
}

// Rough work per organ, for the order in which workers pick organs up (largest first, so that
// the liver does not start last and leave one core idle at the end): voxels of the label, or
// bytes of the mesh file. Only the start order depends on it, never the result.
std::vector<double> organ_cost(const std::vector<OrganJob>& jobs, const std::vector<LoadedLabels>& labels) {
  std::vector<double> cost;
  for (const OrganJob& j : jobs) {
    double c = 0;
    if (j.source >= 0) {
      for (int v : j.values) {
        const auto it = labels[j.source].counts.find(v);
        if (it != labels[j.source].counts.end()) c += static_cast<double>(it->second);
      }
    } else if (!j.mesh_path.empty()) {
      std::error_code ec;
      const auto bytes = fs::file_size(j.mesh_path, ec);
      c = ec ? 0.0 : static_cast<double>(bytes);
    }
    cost.push_back(c + 10.0 * j.budget);
  }
  return cost;
}

// Runs build_one(i, built[i]) for every organ on `jobs` threads (the calling one included),
// largest first. Progress is printed in organ order as soon as the organs before are done. The
// outcome is the serial build's: if organs fail, the first failing organ's error is rethrown
// (organs after it are not started; the ones before it all finish), and only the lines up to it
// are printed.
template <class BuildOne>
void build_in_parallel(size_t n, size_t jobs, const std::vector<double>& cost, BuildOne& build_one,
                       std::vector<BuiltOrgan>& built, bool quiet) {
  std::vector<size_t> order(n);
  for (size_t i = 0; i < n; ++i) order[i] = i;
  if (jobs > 1) std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return cost[a] > cost[b]; });
  std::atomic<size_t> next{0};
  std::mutex mu;  // guards everything below
  std::vector<char> finished(n, 0);
  std::vector<std::exception_ptr> errors(n);
  size_t first_error = n, printed = 0;
  bool printing = true;
  auto work = [&] {
    for (size_t k; (k = next.fetch_add(1)) < n;) {
      const size_t i = order[k];
      bool skip;
      {
        std::lock_guard<std::mutex> lock(mu);
        skip = i > first_error;
      }
      std::exception_ptr error;
      if (!skip) try {
          build_one(i, built[i]);
        } catch (...) {
          error = std::current_exception();
        }
      std::lock_guard<std::mutex> lock(mu);
      finished[i] = 1;
      if (error) errors[i] = error, first_error = std::min(first_error, i);
      for (; printing && printed < n && finished[printed]; ++printed) {
        if (!quiet) std::fputs(built[printed].log.c_str(), stderr);
        if (errors[printed]) printing = false;
      }
    }
  };
  std::vector<std::thread> threads;
  for (size_t t = 1; t < jobs; ++t) threads.emplace_back(work);
  work();
  for (auto& t : threads) t.join();
  if (first_error < n) std::rethrow_exception(errors[first_error]);
}

std::string organ_from_mesh_path(const std::string& path) {
  const std::string stem = fs::path(path).stem().string();
  std::smatch m;
  if (std::regex_search(stem, m, std::regex("FMA_?([0-9]+)"))) {
    const std::string name = name_for_fma("FMA" + m[1].str());
    if (!name.empty()) return name;
  }
  std::string low = stem;
  for (char& c : low) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (label_id(low) > 0) return low;
  throw InputError(path,
                   "cannot tell which organ this mesh is; name it as ORGAN=FILE "
                   "(TotalSegmentator names, e.g. liver=" +
                       fs::path(path).filename().string() + ")");
}

}  // namespace

BuildResult build_organ_set(const BuildOptions& o) {
  const Progress say{o.quiet};
  BuildResult result;
  result.output = o.output;
  if (o.output.empty()) throw InputError("-o", "an output folder is required");
  if (fs::exists(o.output) && !o.overwrite)
    throw InputError(o.output, "the output folder already exists (choose a new folder)");
  io::check_writable(o.output);  // a read-only place fails now, not after the build
  const bool mesh_mode = !o.meshes.empty();
  if (!mesh_mode && o.ct_path.empty()) throw InputError("build", "a CT volume (or --mesh FILE...) is required");
  if (!mesh_mode && o.labels.empty() && o.seeds_path.empty())
    throw InputError(o.ct_path, "give --labels LABELS or --seeds SEEDS.yaml");
  for (const auto& [name, b] : o.budgets)
    if (b < 4)
      throw InputError("--budget " + name, "face budget " + std::to_string(b) +
                                               " is below what a closed surface can have (at least 4 faces)");

  json provenance_params;
  std::map<std::string, std::string> provenance;
  provenance["tool"] = std::string("softatlas ") + SOFTATLAS_VERSION;

  // ---- stage 1: read ----
  auto t0 = Clock::now();
  Volume ct;
  std::vector<LoadedLabels> labels;
  std::vector<OrganJob> jobs;
  if (!mesh_mode) {
    say("read: CT %s", o.ct_path);
    ct = read_volume(o.ct_path);
    provenance["ct"] = o.ct_path;
    provenance["ct_sha256"] = sha256_file(o.ct_path);
    const auto ct_box = ct.world_bounds();
    for (const LabelSource& src : o.labels) {
      say("read: labels %s", src.path);
      LoadedLabels l;
      l.source = src;
      l.volume = read_volume(src.path);
      if (!boxes_overlap(ct_box, l.volume.world_bounds(), 0.5 * std::cbrt(ct.voxel_volume_mm3())))
        throw InputError(src.path,
                         "the label map's grid does not overlap the CT " + o.ct_path + " in world coordinates");
      for (float x : l.volume.values) {
        const long v = std::lround(x);
        if (v != 0) ++l.counts[static_cast<int>(v)];
      }
      if (l.counts.empty()) throw InputError(src.path, "the label map has no labels (every voxel is 0)");
      // A 0/1 mask read as a label map would build TotalSegmentator's label 1 (spleen) silently.
      if (src.organ.empty() && l.volume.label_names.empty() && l.counts.size() == 1 && l.counts.begin()->first == 1)
        throw InputError(src.path,
                         std::string("a 0/1 mask without an organ name (as a label map it would build label 1, ") +
                             "spleen); name it: --labels NAME=" + src.path);
      provenance["labels:" + src.path] = sha256_file(src.path);
      labels.push_back(std::move(l));
    }
  }
  result.times.add("read", since(t0));

  // ---- stage 2: segment (seeds) ----
  if (!mesh_mode && !o.seeds_path.empty()) {
    t0 = Clock::now();
    say("segment: seeded region growing from %s", o.seeds_path);
    const Seeds seeds = read_seeds(o.seeds_path);
    LoadedLabels l;
    l.source = {o.seeds_path, ""};
    l.volume = segment_seeded(ct, seeds, o.segment, o.seeds_path);
    for (float x : l.volume.values) {
      const long v = std::lround(x);
      if (v != 0) ++l.counts[static_cast<int>(v)];
    }
    provenance["seeds:" + o.seeds_path] = sha256_file(o.seeds_path);
    // Every seeded organ must have grown.
    for (const auto& [name, pts] : seeds.organs)
      if (!l.counts.count(label_id(name)))
        throw InputError(o.seeds_path + ": " + name, "the seeded segmentation produced no voxels");
    labels.push_back(std::move(l));
    result.times.add("segment", since(t0));
  }

  // ---- which organs, from where ----
  if (mesh_mode) {
    std::set<std::string> seen;
    for (const MeshSource& m : o.meshes) {
      OrganJob j;
      j.name = m.organ.empty() ? organ_from_mesh_path(m.path) : m.organ;
      if (!seen.insert(j.name).second) throw InputError(m.path, "organ '" + j.name + "' is given twice");
      j.label = label_id(j.name);
      j.mesh_path = m.path;
      jobs.push_back(j);
    }
  } else {
    auto find_job = [&](const std::string& name) -> OrganJob {
      OrganJob j;
      j.name = name;
      j.label = label_id(name);
      for (size_t s = 0; s < labels.size(); ++s) {
        const auto& l = labels[s];
        if (!l.source.organ.empty()) {
          if (l.source.organ == name) {
            j.source = static_cast<int>(s);
            for (const auto& [v, n] : l.counts) j.values.push_back(v);
            return j;
          }
        } else if (const int v = value_of(l, name); v != 0 && l.counts.count(v)) {
          j.source = static_cast<int>(s);
          j.values = {v};
          return j;
        }
      }
      return j;
    };
    // --organs may name groups: all, organs (the default soft set), vessels, bones, muscles, other.
    std::vector<std::string> names;
    std::vector<std::string> groups;
    for (const std::string& nm : o.organs) {
      if (nm == "all" || nm == "organs" || nm == "vessels" || nm == "bones" || nm == "muscles" || nm == "other")
        groups.push_back(nm);
      else if (std::find(names.begin(), names.end(), nm) == names.end())
        names.push_back(nm);
    }
    auto present = [&](auto&& take) {
      for (const auto& l : labels)
        for (const auto& [v, count] : l.counts) {
          const std::string nm = l.source.organ.empty() ? name_of(l, v) : l.source.organ;
          if (!nm.empty() && take(nm) && std::find(names.begin(), names.end(), nm) == names.end()) names.push_back(nm);
        }
    };
    for (const std::string& g : groups)
      present([&](const std::string& nm) { return g == "all" || label_group(nm) == g; });
    if (names.empty() && !groups.empty())
      throw InputError("--organs", "no label of the group(s) given is in the label map");
    if (names.empty()) {
      for (const auto& l : labels) {
        if (!l.source.organ.empty()) {
          names.push_back(l.source.organ);
          continue;
        }
        for (const auto& [v, n] : l.counts) {
          const std::string nm = name_of(l, v);
          if (!nm.empty() && is_default_soft_organ(nm) && std::find(names.begin(), names.end(), nm) == names.end())
            names.push_back(nm);
        }
      }
      if (names.empty())
        throw InputError(labels.front().source.path,
                         "no soft organ in the label map; name the organs to build with --organs");
      // Say what was left out, and why.
      std::map<std::string, std::vector<std::string>> left;
      for (const auto& l : labels)
        for (const auto& [v, count] : l.counts) {
          const std::string nm = l.source.organ.empty() ? name_of(l, v) : l.source.organ;
          if (nm.empty())
            left["no name in the label table"].push_back(std::to_string(v));
          else if (std::find(names.begin(), names.end(), nm) == names.end())
            left[label_group(nm)].push_back(nm);
        }
      for (const auto& [why, list] : left) {
        std::string all_names;
        for (const auto& x : list) all_names += (all_names.empty() ? "" : ", ") + x;
        const std::string add = why.rfind("no name", 0) == 0 ? std::string("--labels NAME=MASK") : "--organs " + why;
        if (!o.quiet)
          std::fprintf(stderr, "[softatlas build] labels: left out %zu (%s; add with %s or --organs all): %s\n",
                       list.size(), why.c_str(), add.c_str(), all_names.c_str());
      }
    }
    for (const std::string& name : names) {
      OrganJob j = find_job(name);
      if (j.source < 0) {
        bool named_mask = false;
        for (const auto& l : labels) named_mask |= l.source.organ == name;
        if (j.label == 0 && !named_mask)
          throw InputError("--organs " + name, "unknown organ '" + name +
                                                   "' (expected a TotalSegmentator name such as liver, "
                                                   "kidney_left; or give its mask as --labels " +
                                                   name + "=FILE)");
        std::string src = labels.front().source.path;
        throw InputError(src,
                         "organ '" + name + "' (label " + std::to_string(j.label) + ") is absent from the label map");
      }
      jobs.push_back(j);
    }
  }
  for (OrganJob& j : jobs) {
    const auto it = o.budgets.find(j.name);
    j.budget = it != o.budgets.end() ? it->second : default_face_budget(j.name);
  }
  for (const auto& [name, b] : o.budgets) {
    bool found = false;
    for (const auto& j : jobs) found |= j.name == name;
    if (!found) throw InputError("--budget " + name, "organ '" + name + "' is not among the organs being built");
  }

  // ---- stages 3 and 4 per organ ----
  io::OrganSet set;
  set.units = "mm";
  set.space = "RAS";
  json quality;
  quality["version"] = SOFTATLAS_VERSION;
  quality["space"] = "RAS";
  quality["units"] = "mm";
  // Each organ's surface -> repair -> remesh chain is independent of the others (its own VTK
  // and CGAL objects; the label volumes are only read), so organs are built on `jobs` threads.
  // Results land in their organ's slot and are gathered in organ order: the set, quality.json
  // and the progress lines are the same for any number of jobs.
  std::vector<BuiltOrgan> built(jobs.size());
  auto build_one = [&](size_t index, BuiltOrgan& out) {
    const OrganJob& j = jobs[index];
    const Progress say{o.quiet, &out.log};
    const double cpu0 = thread_cpu_seconds();
    json q;
    io::TriMesh stage3;
    double reference_volume = 0.0;  // mask volume (labels) or input volume (closed meshes)
    double voxel_mm = 0.0;          // the label's largest voxel spacing (labels only)
    auto t0 = Clock::now();
    if (!j.mesh_path.empty()) {
      say("surface: %s from mesh %s", j.name, j.mesh_path);
      stage3 = io::read_mesh(j.mesh_path);
      const SurfaceReport in = inspect_surface(stage3);
      if (in.nonmanifold_edges > 0)
        throw InputError(j.mesh_path, std::to_string(in.nonmanifold_edges) +
                                          " non-manifold edges (edges shared by 3 or more triangles); "
                                          "expected an edge-manifold surface");
      q["source"] = j.mesh_path;
      q["input_boundary_edges"] = in.boundary_edges;
      q["input_components"] = in.components;
      if (in.closed()) reference_volume = std::abs(in.signed_volume_mm3);
      out.mesh_sha256 = sha256_file(j.mesh_path);
    } else {
      const LoadedLabels& l = labels[j.source];
      const std::string where = l.source.path + ": " + j.name;
      say("surface: %s (flying edges, windowed sinc) from %s", j.name, l.source.path);
      const SurfaceResult s = label_surface(l.volume, j.values, o.surface, where);
      stage3 = s.mesh;
      reference_volume = s.mask_volume_mm3;
      const auto sp = spacing_mm(l.volume);
      voxel_mm = std::max({sp[0], sp[1], sp[2]});
      q["source"] = l.source.path;
      q["mask_voxels"] = s.mask_voxels;
      q["pieces_kept"] = s.pieces_kept;
      q["large_pieces"] = s.large_pieces;
      q["specks_removed"] = s.specks_removed;
      q["specks_volume_mm3"] = s.specks_volume_mm3;
      if (s.large_pieces > 1)
        q["notes"].push_back("the label has " + std::to_string(s.large_pieces) +
                             " large pieces; all are kept as separate closed surfaces");
    }
    out.surface_s = since(t0);

    t0 = Clock::now();
    say("remesh: %s to %s faces (CGAL repair, isotropic remeshing, edge collapse)", j.name, std::to_string(j.budget));
    RemeshOptions ro = o.remesh;
    ro.face_budget = j.budget;
    // Self-contact is expected of label surfaces (split non-manifold vertices) and is remeshed
    // away; a mesh file that intersects itself is broken input and gets wrapped first.
    ro.tolerate_self_contact = j.mesh_path.empty();
    if (voxel_mm > 0) {
      // A label's surface keeps its shape (1.5 voxels: the staircase the surface smooths is one)
      // and its voxel volume (offset by at most one voxel).
      ro.max_hausdorff_mm = 1.5 * voxel_mm;
      ro.target_volume_mm3 = reference_volume;
      ro.max_offset_mm = voxel_mm;
    }
    const RemeshResult r = repair_and_remesh(
        stage3, ro, (j.mesh_path.empty() ? labels[j.source].source.path : j.mesh_path) + ": " + j.name);
    out.remesh_s = since(t0);
    out.cpu_s = thread_cpu_seconds() - cpu0;

    const SurfaceReport rep = inspect_surface(r.mesh);
    const double volume = softatlas::sim::enclosed_volume(r.mesh.vertices, r.mesh.faces);
    q["label"] = j.label;
    q["faces"] = rep.faces;
    q["face_budget"] = j.budget;
    q["faces_within_2pct"] = std::abs(static_cast<double>(rep.faces) - j.budget) <= 0.02 * j.budget;
    q["vertices"] = rep.vertices;
    q["closed"] = rep.closed();
    q["edge_manifold"] = rep.edge_manifold();
    q["consistently_oriented"] = rep.oriented();
    q["outward"] = volume > 0;
    q["self_intersections"] = r.self_intersections;
    q["components"] = rep.components;
    q["genus"] = rep.genus;
    q["hausdorff_mm"] = r.hausdorff_mm;
    q["simplification"] = r.simplification;
    if (voxel_mm > 0) {
      q["voxel_mm"] = voxel_mm;
      q["hausdorff_voxels"] = r.hausdorff_mm / voxel_mm;
      q["isotropic_hausdorff_mm"] = r.isotropic_hausdorff_mm;
      q["volume_offset_mm"] = r.volume_offset_mm;
      q["volume_offset_max_mm"] = r.volume_offset_max_mm;
      q["shape_within_bound"] = r.hausdorff_mm <= ro.max_hausdorff_mm;
      if (r.hausdorff_mm > ro.max_hausdorff_mm) {
        const std::string note = "the surface is " + fmt(r.hausdorff_mm) + " mm (" + fmt(r.hausdorff_mm / voxel_mm) +
                                 " voxels) from the label's at its farthest, more than " +
                                 fmt(ro.max_hausdorff_mm / voxel_mm) +
                                 " voxels: a thin part may be "
                                 "rounded off at this budget (a larger --budget keeps it)";
        q["notes"].push_back(note);
        say("  warning: %s: %s", j.name, note);
      }
    }
    q["mean_distance_mm"] = r.mean_distance_mm;
    q["distance_reference"] = "stage-3 surface (smoothed flying-edges surface of the label, or the input mesh)";
    q["target_edge_mm"] = r.target_edge_mm;
    q["min_angle_deg"] = rep.min_angle_deg;
    q["share_min_angle_ge_20deg"] = rep.share_angle_ge_20;
    q["volume_mm3"] = volume;
    if (reference_volume > 0) {
      q[j.mesh_path.empty() ? "mask_volume_mm3" : "input_volume_mm3"] = reference_volume;
      q["volume_ratio"] = volume / reference_volume;
      q["volume_within_10pct"] = std::abs(volume / reference_volume - 1.0) <= 0.10;
    }
    q["repairs"] = r.repairs;
    say("  %s: %s", j.name,
        std::to_string(rep.faces) + " faces, closed " + (rep.closed() ? "yes" : "NO") + ", volume " +
            fmt(volume / 1000.0) + " mL" +
            (reference_volume > 0 ? " (reference " + fmt(reference_volume / 1000.0) + " mL)" : "") + ", Hausdorff " +
            fmt(r.hausdorff_mm) + " mm");
    out.quality = std::move(q);

    io::OrganEntry e;
    e.name = j.name;
    e.label = j.label;
    e.fma = fma_id(j.name);
    e.color = io::default_organ_color(j.name);
    e.mesh_file = "organs/" + j.name + ".ply";
    e.face_budget = j.budget;
    e.mesh = r.mesh;
    if (label_group(j.name) == "bones") {  // rigid context: drawn, picked, anchors springs
      e.material.model = "rigid";
      e.material.density_kg_m3 = 1900;  // cortical + trabecular bone
    }
    out.entry = std::move(e);
  };
  const Clock::time_point organs_t0 = Clock::now();
  result.jobs = effective_jobs(o.jobs, jobs.size());
  build_in_parallel(jobs.size(), result.jobs, organ_cost(jobs, labels), build_one, built, o.quiet);
  result.times.add("organs_wall", since(organs_t0));
  json qorgans = json::object();
  json organ_seconds = json::object();
  for (size_t i = 0; i < jobs.size(); ++i) {
    BuiltOrgan& b = built[i];
    result.times.add("surface", b.surface_s);
    result.times.add("remesh", b.remesh_s);
    result.organ_seconds.push_back({jobs[i].name, b.surface_s, b.remesh_s, b.cpu_s});
    organ_seconds[jobs[i].name] = {{"surface", b.surface_s}, {"remesh", b.remesh_s}, {"cpu", b.cpu_s}};
    if (!jobs[i].mesh_path.empty()) provenance["mesh:" + jobs[i].mesh_path] = b.mesh_sha256;
    qorgans[jobs[i].name] = std::move(b.quality);
    set.organs.push_back(std::move(b.entry));
  }
  quality["organs"] = qorgans;

  // ---- stage 5: connect ----
  t0 = Clock::now();
  say("connect: proximity springs (threshold %s mm)", fmt(o.connect.distance_mm));
  std::vector<PairReport> pairs;
  set.connections = connect_organs(set.organs, o.connect, &pairs);
  json qpairs = json::array();
  for (const auto& p : pairs)
    qpairs.push_back({{"organ_a", p.organ_a},
                      {"organ_b", p.organ_b},
                      {"closest_mm", p.closest_mm},
                      {"springs", p.springs},
                      {"default_pair", p.default_pair}});
  quality["connections"] = qpairs;
  // Anchors, for organ sets in patient RAS (a CT build; meshes keep their own frame).
  if (!mesh_mode && o.connect.anchor_count > 0) {
    for (auto& e : set.organs) {
      if (e.material.model == "rigid") continue;  // a bone never moves: nothing to anchor
      e.fixed_vertices = io::extreme_vertices(e.mesh, {0, -1, 0}, o.connect.anchor_count, o.connect.anchor_spacing_mm);
      quality["organs"][e.name]["anchors"] = e.fixed_vertices.size();
    }
    say("anchors: %s posterior vertices per organ (body wall)", std::to_string(o.connect.anchor_count));
  }
  result.times.add("connect", since(t0));

  // ---- stage 6: write ----
  t0 = Clock::now();
  provenance_params["organs"] = json::array();
  for (const auto& j : jobs) provenance_params["organs"].push_back(j.name);
  for (const auto& j : jobs) provenance_params["budget"][j.name] = j.budget;
  provenance_params["smoothing_iterations"] = o.surface.smoothing_iterations;
  provenance_params["smoothing_passband"] = o.surface.smoothing_passband;
  provenance_params["speck_share"] = o.surface.speck_share;
  provenance_params["remesh_iterations"] = o.remesh.remesh_iterations;
  provenance_params["wrap_alpha_mm"] = o.remesh.wrap_alpha_mm;
  provenance_params["connect_distance_mm"] = o.connect.distance_mm;
  provenance_params["connect_spacing_mm"] = o.connect.spacing_mm;
  provenance_params["anchor_count"] = o.connect.anchor_count;
  provenance_params["anchor_spacing_mm"] = o.connect.anchor_spacing_mm;
  provenance_params["connect_stiffness"] = o.connect.stiffness;
  provenance["parameters"] = provenance_params.dump();
  set.provenance = provenance;
  quality["provenance"] = provenance;
  json times = json::object();
  for (const auto& [k, v] : result.times.seconds) times[k] = v;
  quality["stage_seconds"] = times;
  quality["organ_seconds"] = organ_seconds;
  result.quality_json = quality.dump(2) + "\n";
  result.organs = set.organs.size();
  result.connections = set.connections.size();
  std::map<std::string, std::string> files{{"quality.json", result.quality_json}};
  if (!mesh_mode) {  // the CT itself, for sectional views (docs/organ-set.md, ct)
    const io::CtImage crop = crop_ct(ct, set.organs, 20.0);
    io::CtRecord rec;  // soft-tissue window: 400 / 40 HU
    set.ct = rec;
    files[rec.file] = io::encode_ct_nifti_gz(crop);
    say("write: CT cropped to the organs + 20 mm: %s voxels, %s MB",
        std::to_string(crop.dims[0]) + "x" + std::to_string(crop.dims[1]) + "x" + std::to_string(crop.dims[2]),
        fmt(files[rec.file].size() / 1e6));
  }
  say("write: %s", o.output);
  io::write_organ_set(set, o.output, files, o.overwrite);
  result.times.add("write", since(t0));
  return result;
}

bool check_organ_set(const std::string& folder, std::string* report_json) {
  const io::OrganSet set = io::read_organ_set(folder);
  json out;
  out["folder"] = folder;
  bool all_ok = true;
  json organs = json::object();
  for (const auto& e : set.organs) {
    const SurfaceReport r = inspect_surface(e.mesh);
    json q;
    q["faces"] = r.faces;
    q["face_budget"] = e.face_budget;
    const bool budget_ok =
        e.face_budget <= 0 || std::abs(static_cast<double>(r.faces) - e.face_budget) <= 0.02 * e.face_budget;
    q["closed"] = r.closed();
    q["edge_manifold"] = r.edge_manifold();
    q["consistently_oriented"] = r.oriented();
    q["outward"] = r.outward();
    q["genus"] = r.genus;
    q["components"] = r.components;
    q["volume_mm3"] = r.signed_volume_mm3;
    q["share_min_angle_ge_20deg"] = r.share_angle_ge_20;
    const bool ok = budget_ok && r.closed() && r.oriented() && r.outward();
    q["ok"] = ok;
    all_ok &= ok;
    organs[e.name] = q;
  }
  out["organs"] = organs;
  out["connections"] = set.connections.size();
  const fs::path qpath = fs::path(folder) / "quality.json";
  if (fs::exists(qpath)) {
    try {
      out["quality"] = json::parse(io::read_text_file(qpath.string()));
    } catch (const json::exception& e) {
      throw InputError(qpath.string(), std::string("not valid JSON: ") + e.what());
    }
  }
  out["ok"] = all_ok;
  *report_json = out.dump(2) + "\n";
  return all_ok;
}

}  // namespace softatlas::pipeline
