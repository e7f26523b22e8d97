// Slow pipeline tests (ctest label `slow`): whole-case builds of the abdomen slab (NIfTI and the
// DICOM series), the BodyParts3D trachea wrap, and the Dice floors of the seeded segmentation.
//
// Seeds are placed the way a user would click (segment_like_a_user): 10 points deep inside each
// organ (spread by farthest-point sampling), 10 background points in a ring a few millimetres
// outside the organs, then 5 correction clicks, each in the largest leak of the previous result.
// The reference label map only places the clicks; the segmentation never sees it.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include "softatlas/io/organ_set.hpp"
#include "softatlas/pipeline/bench_segment.hpp"
#include "softatlas/pipeline/build.hpp"
#include "softatlas/pipeline/cli.hpp"
#include "softatlas/pipeline/label_table.hpp"
#include "softatlas/pipeline/topology.hpp"
#include "softatlas/sim/geometry.hpp"
#include "test_util.hpp"

namespace softatlas::pipeline {
namespace {
using test::abdomen;
using test::chest;

// Chamfer-free depth: number of 6-neighbour erosions a voxel survives.
std::vector<int> erosion_depth(const Volume& v, int id) {
  const auto& d = v.dims;
  std::vector<int> depth(v.values.size(), 0);
  std::vector<char> cur(v.values.size());
  for (size_t i = 0; i < cur.size(); ++i) cur[i] = std::lround(v.values[i]) == id;
  for (int level = 1; level < 200; ++level) {
    bool any = false;
    std::vector<char> next(cur.size(), 0);
    for (int k = 1; k + 1 < d[2]; ++k)
      for (int j = 1; j + 1 < d[1]; ++j)
        for (int i = 1; i + 1 < d[0]; ++i) {
          const size_t x = v.index(i, j, k);
          if (!cur[x]) continue;
          const size_t sy = d[0], sz = static_cast<size_t>(d[0]) * d[1];
          if (cur[x - 1] && cur[x + 1] && cur[x - sy] && cur[x + sy] && cur[x - sz] && cur[x + sz])
            next[x] = 1, any = true;
        }
    for (size_t x = 0; x < cur.size(); ++x)
      if (cur[x]) depth[x] = level;
    if (!any) break;
    cur.swap(next);
  }
  return depth;
}

// Farthest-point sampling of up to n voxels among candidates.
std::vector<std::array<double, 3>> spread(const Volume& v, const std::vector<size_t>& cand, int n) {
  std::vector<std::array<double, 3>> pts;
  if (cand.empty()) return pts;
  std::vector<std::array<double, 3>> world(cand.size());
  for (size_t c = 0; c < cand.size(); ++c) {
    const size_t x = cand[c];
    world[c] = v.world(x % v.dims[0], (x / v.dims[0]) % v.dims[1], x / (static_cast<size_t>(v.dims[0]) * v.dims[1]));
  }
  std::vector<double> best(cand.size(), 1e300);
  size_t pick = cand.size() / 2;
  for (int s = 0; s < n; ++s) {
    pts.push_back(world[pick]);
    size_t far = 0;
    for (size_t c = 0; c < cand.size(); ++c) {
      const auto& p = world[c];
      const double dd = (p[0] - world[pick][0]) * (p[0] - world[pick][0]) +
                        (p[1] - world[pick][1]) * (p[1] - world[pick][1]) +
                        (p[2] - world[pick][2]) * (p[2] - world[pick][2]);
      best[c] = std::min(best[c], dd);
      if (best[c] > best[far]) far = c;
    }
    pick = far;
  }
  return pts;
}

// Reference labels of several masks on one CT grid (nearest voxel through world coordinates).
// The simulated user's protocol (deep clicks, ring, corrections) measures the region growing with
// its tube and wall models; the default graph cut is measured by `softatlas bench segment`.
SegmentOptions growth_options() {
  SegmentOptions o;
  o.method = "growth";
  return o;
}

Volume labels_on_grid(const Volume& grid, const std::vector<std::pair<std::string, int>>& masks) {
  return masks_on_grid(grid, masks);
}

// Voxels at least half as deep as the deepest voxel of label `id`, spread to n points.
std::vector<std::array<double, 3>> deep_points(const Volume& ref, int id, int n) {
  const auto depth = erosion_depth(ref, id);
  const int top = *std::max_element(depth.begin(), depth.end());
  std::vector<size_t> cand;
  for (size_t x = 0; x < depth.size(); ++x)
    if (depth[x] >= std::max(1, top / 2)) cand.push_back(x);
  return spread(ref, cand, n);
}

// n points spread over a ring 4-6 voxels outside all `organs` (ids in ref), away from the box
// border (where the erosion depth also counts up, and where a user would not click).
std::vector<std::array<double, 3>> ring_points(const Volume& ref,
                                               const std::vector<std::pair<std::string, int>>& organs, int n) {
  Volume inv = ref;
  for (size_t x = 0; x < inv.values.size(); ++x) {
    bool any = false;
    for (const auto& o : organs) any |= std::lround(ref.values[x]) == o.second;
    inv.values[x] = any ? 0.0f : 1.0f;
  }
  const auto depth = erosion_depth(inv, 1);
  std::vector<size_t> cand;
  const auto& d = ref.dims;
  for (size_t x = 0; x < depth.size(); ++x) {
    const int i = static_cast<int>(x % d[0]), j = static_cast<int>((x / d[0]) % d[1]),
              k = static_cast<int>(x / (static_cast<size_t>(d[0]) * d[1]));
    const int border = std::min({i, j, k, d[0] - 1 - i, d[1] - 1 - j, d[2] - 1 - k});
    if (depth[x] >= 4 && depth[x] <= 6 && border > 8) cand.push_back(x);
  }
  return spread(ref, cand, n);
}

// The voxel deepest inside the largest 6-connected component of `mask` (empty if the largest
// component has fewer than min_voxels).
std::optional<std::array<double, 3>> centre_of_largest(const Volume& grid, const std::vector<char>& mask,
                                                       size_t min_voxels) {
  const auto& d = grid.dims;
  const size_t n = mask.size(), sy = d[0], sz = static_cast<size_t>(d[0]) * d[1];
  std::vector<int> comp(n, -1);
  std::vector<size_t> best, cur;
  for (size_t s = 0; s < n; ++s) {
    if (!mask[s] || comp[s] >= 0) continue;
    cur.assign(1, s);
    comp[s] = static_cast<int>(s);
    for (size_t h = 0; h < cur.size(); ++h) {
      const size_t x = cur[h];
      const int i = static_cast<int>(x % d[0]), j = static_cast<int>((x / d[0]) % d[1]), k = static_cast<int>(x / sz);
      const size_t nb[6] = {x - 1, x + 1, x - sy, x + sy, x - sz, x + sz};
      const bool ok[6] = {i > 0, i + 1 < d[0], j > 0, j + 1 < d[1], k > 0, k + 1 < d[2]};
      for (int q = 0; q < 6; ++q)
        if (ok[q] && mask[nb[q]] && comp[nb[q]] < 0) comp[nb[q]] = static_cast<int>(s), cur.push_back(nb[q]);
    }
    if (cur.size() > best.size()) best.swap(cur);
  }
  if (best.size() < min_voxels) return std::nullopt;
  // Peel the component layer by layer; the last voxel left is the deepest.
  const int id = comp[best[0]];
  std::vector<int> depth(n, 0);
  std::vector<size_t> layer;
  for (size_t x : best) {
    const int i = static_cast<int>(x % d[0]), j = static_cast<int>((x / d[0]) % d[1]), k = static_cast<int>(x / sz);
    const size_t nb[6] = {x - 1, x + 1, x - sy, x + sy, x - sz, x + sz};
    const bool ok[6] = {i > 0, i + 1 < d[0], j > 0, j + 1 < d[1], k > 0, k + 1 < d[2]};
    bool edge = false;
    for (int q = 0; q < 6; ++q) edge |= !ok[q] || comp[nb[q]] != id;
    if (edge) depth[x] = 1, layer.push_back(x);
  }
  size_t deepest = layer.empty() ? best[0] : layer[0];
  for (size_t h = 0; h < layer.size(); ++h) {
    const size_t x = layer[h];
    deepest = x;
    const int i = static_cast<int>(x % d[0]), j = static_cast<int>((x / d[0]) % d[1]), k = static_cast<int>(x / sz);
    const size_t nb[6] = {x - 1, x + 1, x - sy, x + sy, x - sz, x + sz};
    const bool ok[6] = {i > 0, i + 1 < d[0], j > 0, j + 1 < d[1], k > 0, k + 1 < d[2]};
    for (int q = 0; q < 6; ++q)
      if (ok[q] && comp[nb[q]] == id && depth[nb[q]] == 0) depth[nb[q]] = depth[x] + 1, layer.push_back(nb[q]);
  }
  return grid.world(deepest % d[0], (deepest / d[0]) % d[1], deepest / sz);
}

std::string seeds_yaml(const Seeds& s) {
  std::ostringstream out;
  out << "organs:\n";
  for (const auto& [name, pts] : s.organs) {
    out << "  " << name << ":\n";
    for (const auto& p : pts) out << "    - [" << p[0] << ", " << p[1] << ", " << p[2] << "]\n";
  }
  if (!s.background.empty()) out << "background:\n";
  for (const auto& p : s.background) out << "  - [" << p[0] << ", " << p[1] << ", " << p[2] << "]\n";
  return out.str();
}

// The clicks of a simulated user, as interactive segmentation benchmarks place them (Xu et al.,
// "Deep interactive object selection", CVPR 2016): 10 points deep inside each organ, `ring`
// background points around the organs, then up to `corrections` background clicks, each at the
// voxel deepest inside the largest leak (segmented as an organ where the reference has no
// organ), re-segmenting after each. The reference only places the clicks. The seed file is
// written to `path` (and copied to $SOFTATLAS_KEEP_SEEDS when set).
Volume segment_like_a_user(const Volume& ct, const Volume& ref, const std::vector<std::pair<std::string, int>>& organs,
                           const std::string& path, int ring, int corrections) {
  Seeds seeds;
  for (const auto& [name, id] : organs) seeds.organs[name] = deep_points(ref, id, 10);
  seeds.background = ring_points(ref, organs, ring);
  Volume seg = segment_seeded(ct, seeds, growth_options(), path);
  for (int c = 0; c < corrections; ++c) {
    std::vector<char> leak(seg.values.size(), 0);
    for (size_t x = 0; x < leak.size(); ++x) {
      bool organ = false;
      for (const auto& o : organs) organ |= std::lround(ref.values[x]) == o.second;
      leak[x] = seg.values[x] != 0.0f && !organ;
    }
    // A user does not click the same spot twice: a leak the earlier clicks did not remove is
    // passed over (voxels within 3 voxels of a click leave the candidates) for the next one.
    for (const auto& p : seeds.background) {
      const auto v = ct.voxel(p);
      const int c[3] = {static_cast<int>(std::lround(v[0])), static_cast<int>(std::lround(v[1])),
                        static_cast<int>(std::lround(v[2]))};
      for (int k = std::max(0, c[2] - 3); k <= std::min(ct.dims[2] - 1, c[2] + 3); ++k)
        for (int j = std::max(0, c[1] - 3); j <= std::min(ct.dims[1] - 1, c[1] + 3); ++j)
          for (int i = std::max(0, c[0] - 3); i <= std::min(ct.dims[0] - 1, c[0] + 3); ++i) leak[ct.index(i, j, k)] = 0;
    }
    const auto click = centre_of_largest(ct, leak, 50);
    if (!click) break;
    seeds.background.push_back(*click);
    seg = segment_seeded(ct, seeds, growth_options(), path);
    if (std::getenv("SOFTATLAS_VERBOSE"))  // Dice after each click
      for (const auto& [name, id] : organs)
        std::printf("  click %d at (%.1f, %.1f, %.1f): %s %.4f\n", c + 1, (*click)[0], (*click)[1], (*click)[2],
                    name.c_str(), dice(seg, id, ref, id));
  }
  std::ofstream(path) << seeds_yaml(seeds);
  if (const char* keep = std::getenv("SOFTATLAS_KEEP_SEEDS"))
    std::filesystem::copy_file(path, std::filesystem::path(keep) / std::filesystem::path(path).filename(),
                               std::filesystem::copy_options::overwrite_existing);
  return seg;
}

// SOFTATLAS_RING and SOFTATLAS_CORRECTIONS change the click protocol (docs/pipeline.md compares).
int env_int(const char* name, int fallback) {
  const char* v = std::getenv(name);
  return v ? std::atoi(v) : fallback;
}

// The target: Dice >= 0.90 for heart and aorta with at most 10 clicks per organ
// (measured 0.910 and 0.908 with this protocol; docs/pipeline.md).
TEST(SeededSegmentation, DiceFloorsChestCrops) {
  test::Scratch tmp;
  const int ring = env_int("SOFTATLAS_RING", 10), corrections = env_int("SOFTATLAS_CORRECTIONS", 5);
  // Heart crop: heart and aorta seeded (they touch at the aortic root). The pulmonary artery is
  // not marked as background here: this reference heart holds 13,019 of the 14,261 voxels of the
  // pulmonary artery mask (the trunk).
  {
    const Volume ct = read_volume(chest("ct_heart_crop.nii.gz"));
    const Volume ref =
        labels_on_grid(ct, {{chest("heart_on_ct_heart_crop_grid.nii.gz"), 51}, {chest("aorta.nii.gz"), 52}});
    const Volume seg =
        segment_like_a_user(ct, ref, {{"heart", 51}, {"aorta", 52}}, tmp("heart_seeds.yaml"), ring, corrections);
    const double d = dice(seg, 51, ref, 51);
    std::printf("DICE heart %.4f (aorta on the heart crop %.4f)\n", d, dice(seg, 52, ref, 52));
    EXPECT_GE(d, 0.90);
  }
  {
    const Volume ct = read_volume(chest("ct_aorta_crop.nii.gz"));
    const Volume ref = labels_on_grid(ct, {{chest("aorta.nii.gz"), 52}, {chest("heart.nii.gz"), 51}});
    const Volume seg =
        segment_like_a_user(ct, ref, {{"aorta", 52}, {"heart", 51}}, tmp("aorta_seeds.yaml"), ring, corrections);
    const double d = dice(seg, 52, ref, 52);
    size_t ns = 0, nr = 0;
    for (size_t i = 0; i < seg.values.size(); ++i) ns += seg.values[i] == 52, nr += ref.values[i] == 52;
    std::printf("DICE aorta %.4f (voxels %zu segmented, %zu reference)\n", d, ns, nr);
    EXPECT_GE(d, 0.90);
  }
}

TEST(SeededSegmentation, DiceFloorsAbdomenSlab) {
  test::Scratch tmp;
  const int ring = env_int("SOFTATLAS_RING", 10), corrections = env_int("SOFTATLAS_CORRECTIONS", 5);
  const std::vector<std::pair<std::string, int>> organs = {{"liver", 5}, {"spleen", 1}, {"stomach", 6}, {"aorta", 52}};
  const Volume image = read_volume(abdomen("ct_from_dicom.nii.gz"));
  const Volume reference = read_volume(abdomen("example_seg_dicom.nii.gz"));
  const Volume seg = segment_like_a_user(image, reference, organs, tmp("abdomen_seeds.yaml"), ring, corrections);
  for (const auto& [name, id] : organs) {
    const double d = dice(seg, id, reference, id);
    std::printf("DICE %s %.4f\n", name.c_str(), d);
    if (name == "liver" || name == "spleen") {
      EXPECT_GE(d, 0.85) << name;
    }
  }
}

void expect_set_contract(const std::string& dir) {
  const io::OrganSet set = io::read_organ_set(dir);
  const auto q = nlohmann::json::parse(io::read_text_file(dir + "/quality.json"));
  for (const auto& e : set.organs) {
    const SurfaceReport r = inspect_surface(e.mesh);
    EXPECT_TRUE(r.closed()) << e.name;
    EXPECT_TRUE(r.oriented()) << e.name;
    EXPECT_GT(r.signed_volume_mm3, 0) << e.name;
    EXPECT_NEAR(static_cast<double>(r.faces), e.face_budget, 0.02 * e.face_budget) << e.name;
    EXPECT_GE(r.share_angle_ge_20, 0.99) << e.name;
    EXPECT_EQ(q["organs"][e.name]["self_intersections"], false) << e.name;
    if (q["organs"][e.name].contains("volume_ratio")) {
      EXPECT_NEAR(q["organs"][e.name]["volume_ratio"].get<double>(), 1.0, 0.10) << e.name;
    }
  }
}

TEST(SlowBuild, AbdomenSlabFromNiftiAndFromDicomAgree) {
  test::Scratch tmp;
  const std::vector<std::string> organs = {
      "liver", "spleen", "stomach", "pancreas", "aorta", "inferior_vena_cava", "portal_vein_and_splenic_vein"};
  std::string list;
  for (const auto& o : organs) list += (list.empty() ? "" : ",") + o;
  ASSERT_EQ(cli_main({"build", abdomen("ct_from_dicom.nii.gz"), "--labels", abdomen("example_seg_dicom.nii.gz"),
                      "--organs", list, "-q", "-o", tmp("nii")}),
            0);
  ASSERT_EQ(cli_main({"build", abdomen("dicom"), "--labels", abdomen("example_seg_dicom.nii.gz"), "--organs", list,
                      "-q", "-o", tmp("dcm")}),
            0);
  expect_set_contract(tmp("nii"));
  expect_set_contract(tmp("dcm"));
  const io::OrganSet a = io::read_organ_set(tmp("nii")), b = io::read_organ_set(tmp("dcm"));
  ASSERT_EQ(a.organs.size(), organs.size());
  // Same label map, same surfaces: the CT only decides the grid check and provenance.
  for (size_t i = 0; i < a.organs.size(); ++i) EXPECT_EQ(a.organs[i].mesh.vertices, b.organs[i].mesh.vertices);
  EXPECT_NE(a.provenance.at("ct_sha256"), b.provenance.at("ct_sha256"));
}

TEST(SlowBuild, BodyParts3dMeshesIncludingTheWrappedTrachea) {
  test::Scratch tmp;
  const std::string m = test::shared("meshes/bodyparts3d/");
  ASSERT_EQ(cli_main({"build", "--mesh", m + "FMA7197_Liver.obj", m + "FMA7205_Left_Kidney.obj",
                      m + "FMA7394_Trachea.obj", "-q", "-o", tmp("set")}),
            0);
  expect_set_contract(tmp("set"));
  const auto q = nlohmann::json::parse(io::read_text_file(tmp("set") + "/quality.json"));
  bool wrapped = false;
  for (const auto& r : q["organs"]["trachea"]["repairs"]) wrapped |= r.get<std::string>().rfind("alpha_wrap", 0) == 0;
  EXPECT_TRUE(wrapped);
}

}  // namespace
}  // namespace softatlas::pipeline

namespace softatlas::pipeline {
namespace {

// The Snakemake workflow on the embedded sample: builds, checks and exports, then a second run
// has nothing to do (finished cases are skipped).
TEST(SlowWorkflow, SnakemakeBuildsTheSampleAndSkipsItNextTime) {
  if (std::system("snakemake --version > /dev/null 2>&1") != 0) GTEST_SKIP() << "snakemake is not installed";
  test::Scratch tmp;
  const std::string src = SOFTATLAS_SOURCE_DIR;
  std::ofstream(tmp("config.yaml")) << "out: results\ncases:\n  sample:\n    ct: " << src
                                    << "/data/sample/ct_heart_crop.nii.gz\n    labels:\n      - heart=" << src
                                    << "/data/sample/heart_on_ct_heart_crop_grid.nii.gz\n      - pulmonary_artery="
                                    << src << "/data/sample/pulmonary_artery.nii.gz\n";
  const std::string cli = std::string(SOFTATLAS_BINARY_DIR) + "/tests/pipeline/softatlas_pipeline_cli";
  const std::string cmd = "snakemake -s " + src + "/workflows/Snakefile --configfile " + tmp("config.yaml") + " -d " +
                          tmp("") + " --cores 2 -q --config softatlas=" + cli;
  ASSERT_EQ(std::system((cmd + " > " + tmp("run1.log") + " 2>&1").c_str()), 0) << io::read_text_file(tmp("run1.log"));
  EXPECT_TRUE(std::filesystem::exists(tmp("results/sample/atlas.glb")));
  const auto check = nlohmann::json::parse(io::read_text_file(tmp("results/sample/check.json")));
  EXPECT_EQ(check["ok"], true);
  ASSERT_EQ(std::system((cmd + " -n > " + tmp("run2.log") + " 2>&1").c_str()), 0);
  EXPECT_NE(io::read_text_file(tmp("run2.log")).find("Nothing to be done"), std::string::npos)
      << io::read_text_file(tmp("run2.log"));
}

}  // namespace
// The fair protocol, all 10 draws of `softatlas bench segment` on the abdomen slab: floors at the
// measured level of the graph cut (docs/pipeline.md), and no runaway liver or spleen.
TEST(SlowSeeded, FairProtocolTenDrawsOnTheSlab) {
  const EvalCase c = load_eval_case(SOFTATLAS_SHARED_DATA, "slab");
  double liver = 0, spleen = 0;
  for (int k = 0; k < 10; ++k) {
    const EvalRun r = run_draw(c, draw_seed(k));
    liver += r.dice[0] / 10, spleen += r.dice[1] / 10;
    EXPECT_GE(r.dice[0], 0.80) << "draw " << k;
    EXPECT_LE(r.volume_ratio[0], 1.3) << "draw " << k;
    EXPECT_LE(r.volume_ratio[1], 1.3) << "draw " << k;
  }
  std::printf("mean Dice liver %.3f, spleen %.3f\n", liver, spleen);
  EXPECT_GE(liver, 0.85);
  EXPECT_GE(spleen, 0.85);
}

// `--organs all` builds every label of the map (bones, muscles and the rest included).
TEST(SlowBuild, OrgansAllBuildsEveryLabel) {
  const std::string out = (std::filesystem::temp_directory_path() / "softatlas-slow-organs-all").string();
  std::filesystem::remove_all(out);
  ASSERT_EQ(cli_main({"build", abdomen("ct_from_dicom.nii.gz"), "--labels", abdomen("example_seg_dicom.nii.gz"),
                      "--organs", "all", "-q", "-o", out}),
            0);
  size_t organs = 0;
  for (const auto& e : std::filesystem::directory_iterator(out + "/organs")) organs += e.path().extension() == ".ply";
  EXPECT_EQ(organs, 31u);  // the 31 labels of the slab's map
  EXPECT_TRUE(std::filesystem::exists(out + "/organs/vertebrae_T12.ply"));
  // Issue 14, item 4: every organ within 10 % of its label volume, the thin ones included (the
  // vertebrae, ribs, costal cartilages, pancreas, vessels): the mesh's own enclosed volume
  // against the label's voxels counted here.
  const Volume labels = read_volume(abdomen("example_seg_dicom.nii.gz"));
  std::map<int, size_t> voxels;
  for (float x : labels.values) ++voxels[static_cast<int>(std::lround(x))];
  const io::OrganSet set = io::read_organ_set(out);
  for (const io::OrganEntry& e : set.organs) {
    const double label_mm3 = static_cast<double>(voxels[e.label]) * labels.voxel_volume_mm3();
    ASSERT_GT(label_mm3, 0) << e.name;
    EXPECT_NEAR(softatlas::sim::enclosed_volume(e.mesh.vertices, e.mesh.faces) / label_mm3, 1.0, 0.10) << e.name;
  }
  std::filesystem::remove_all(out);
}

}  // namespace softatlas::pipeline
