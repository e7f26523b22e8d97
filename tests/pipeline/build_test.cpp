// The whole build through the command entry (cli_main) on the chest CTA crop: the organ set is
// read back by io, re-checked independently, exported to glTF and read back with assimp.
#include <assimp/Importer.hpp>
#include <assimp/material.h>
#include <assimp/scene.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <nlohmann/json.hpp>

#include "softatlas/io/organ_set.hpp"
#include "softatlas/pipeline/build.hpp"
#include "softatlas/pipeline/cli.hpp"
#include "softatlas/pipeline/topology.hpp"
#include "softatlas/sim/error.hpp"
#include "softatlas/sim/geometry.hpp"
#include "test_util.hpp"

namespace softatlas::pipeline {
namespace {
using test::abdomen;
using test::chest;
namespace fs = std::filesystem;

TEST(Build, ChestCropHeartAndPulmonaryArteryThroughTheCommand) {
  test::Scratch tmp;
  const std::string set_dir = tmp("set");
  ASSERT_EQ(
      cli_main({"build", chest("ct_heart_crop.nii.gz"), "--labels",
                "heart=" + chest("heart_on_ct_heart_crop_grid.nii.gz"), "--labels",
                "pulmonary_artery=" + chest("pulmonary_artery.nii.gz"), "--budget", "heart=1200", "-q", "-o", set_dir}),
      0);
  const io::OrganSet set = io::read_organ_set(set_dir);
  EXPECT_EQ(set.space, "RAS");
  EXPECT_EQ(set.units, "mm");
  ASSERT_EQ(set.organs.size(), 2u);
  EXPECT_TRUE(fs::exists(set_dir + "/organs/heart.ply"));
  EXPECT_TRUE(fs::exists(set_dir + "/organs/pulmonary_artery.ply"));
  const io::OrganEntry* heart = set.find("heart");
  ASSERT_NE(heart, nullptr);
  EXPECT_EQ(heart->label, 51);
  EXPECT_EQ(heart->face_budget, 1200);
  // Mask volumes counted here, independently of the pipeline.
  const Volume hm = read_volume(chest("heart_on_ct_heart_crop_grid.nii.gz"));
  size_t n = 0;
  for (float x : hm.values) n += x != 0;
  for (const auto& e : set.organs) {
    const SurfaceReport r = inspect_surface(e.mesh);
    EXPECT_TRUE(r.closed()) << e.name;
    EXPECT_TRUE(r.oriented()) << e.name;
    EXPECT_GT(r.signed_volume_mm3, 0) << e.name;
    EXPECT_NEAR(static_cast<double>(r.faces), e.face_budget, 0.02 * e.face_budget) << e.name;
    EXPECT_GE(r.share_angle_ge_20, 0.99) << e.name;
  }
  EXPECT_NEAR(softatlas::sim::enclosed_volume(heart->mesh.vertices, heart->mesh.faces) / (n * 3.375), 1.0, 0.15);
  // Anchors: 6 vertices per organ on its posterior side (RAS -y), at least 15 mm apart.
  for (const auto& e : set.organs) {
    ASSERT_EQ(e.fixed_vertices.size(), 6u) << e.name;
    double ymin = 1e300, ymax = -1e300;
    for (size_t v = 0; v < e.mesh.vertex_count(); ++v)
      ymin = std::min(ymin, e.mesh.vertices[3 * v + 1]), ymax = std::max(ymax, e.mesh.vertices[3 * v + 1]);
    for (size_t a = 0; a < e.fixed_vertices.size(); ++a) {
      const double* p = &e.mesh.vertices[3 * static_cast<size_t>(e.fixed_vertices[a])];
      EXPECT_LE(p[1], ymin + 0.25 * (ymax - ymin)) << e.name;
      for (size_t b = 0; b < a; ++b) {
        const double* q = &e.mesh.vertices[3 * static_cast<size_t>(e.fixed_vertices[b])];
        EXPECT_GE(std::hypot(p[0] - q[0], p[1] - q[1], p[2] - q[2]), 15.0) << e.name;
      }
    }
  }
  // The heart and the pulmonary artery touch: springs, each between existing vertices.
  EXPECT_GT(set.connections.size(), 10u);
  for (const auto& c : set.connections) {
    const io::OrganEntry* a = set.find(c.organ_a);
    const io::OrganEntry* b = set.find(c.organ_b);
    ASSERT_TRUE(a && b);
    const double* p = &a->mesh.vertices[3 * c.vertex_a];
    const double* q = &b->mesh.vertices[3 * c.vertex_b];
    const double d =
        std::sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) + (p[2] - q[2]) * (p[2] - q[2]));
    EXPECT_NEAR(d, c.rest_length_mm, 1e-6);
    EXPECT_LE(d, 4.0 + 1e-9);
  }
  const auto q = nlohmann::json::parse(io::read_text_file(set_dir + "/quality.json"));
  EXPECT_EQ(q["organs"]["heart"]["faces_within_2pct"], true);
  EXPECT_EQ(q["organs"]["heart"]["closed"], true);
  EXPECT_TRUE(q["organs"]["heart"].contains("hausdorff_mm"));
  EXPECT_EQ(set.provenance.at("ct_sha256").substr(0, 16), "4da078fe43c9aa4d");  // README checksum
  // The set records its CT: ct.nii.gz, int16 HU cropped to the organs + 20 mm, soft-tissue
  // window. Read back by the pipeline's own (VTK) reader, every voxel is the source CT's value at
  // the same world point (the sform carries the crop's offset), and the organs lie inside it.
  ASSERT_TRUE(set.ct.has_value());
  EXPECT_EQ(set.ct->file, "ct.nii.gz");
  EXPECT_DOUBLE_EQ(set.ct->window_width_hu, 400);
  EXPECT_DOUBLE_EQ(set.ct->window_level_hu, 40);
  {
    const Volume src = read_volume(chest("ct_heart_crop.nii.gz"));
    const Volume crop = read_volume(set_dir + "/ct.nii.gz");
    EXPECT_LT(fs::file_size(set_dir + "/ct.nii.gz"), 4u << 20);
    EXPECT_LE(crop.voxel_count(), src.voxel_count());
    const auto b = crop.world_bounds();
    const auto sb = src.world_bounds();
    double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
    for (const auto& e : set.organs)
      for (size_t i = 0; i < e.mesh.vertices.size(); ++i) {
        lo[i % 3] = std::min(lo[i % 3], e.mesh.vertices[i]);
        hi[i % 3] = std::max(hi[i % 3], e.mesh.vertices[i]);
      }
    for (int d = 0; d < 3; ++d) {  // the organs + >= 10 mm, or up to the source CT's edge
      EXPECT_LE(b[d], std::max(lo[d] - 10.0, sb[d]) + 1e-3) << d;
      EXPECT_GE(b[d + 3], std::min(hi[d] + 10.0, sb[d + 3]) - 1e-3) << d;
    }
    size_t checked = 0;
    for (size_t n = 0; n < crop.voxel_count(); n += 997, ++checked) {
      const int i = static_cast<int>(n % crop.dims[0]), j = static_cast<int>((n / crop.dims[0]) % crop.dims[1]),
                k = static_cast<int>(n / (static_cast<size_t>(crop.dims[0]) * crop.dims[1]));
      const auto v = src.voxel(crop.world(i, j, k));
      const int si = static_cast<int>(std::lround(v[0])), sj = static_cast<int>(std::lround(v[1])),
                sk = static_cast<int>(std::lround(v[2]));
      EXPECT_NEAR(v[0], si, 1e-3);
      EXPECT_NEAR(v[2], sk, 1e-3);
      ASSERT_TRUE(si >= 0 && sj >= 0 && sk >= 0 && si < src.dims[0] && sj < src.dims[1] && sk < src.dims[2]);
      EXPECT_NEAR(crop.values[n], std::round(src.values[src.index(si, sj, sk)]), 0.5);
    }
    EXPECT_GT(checked, 100u);
  }

  std::string report;
  EXPECT_TRUE(check_organ_set(set_dir, &report));
  EXPECT_EQ(cli_main({"check", set_dir}), 0);

  const std::string glb = tmp("atlas.glb");
  ASSERT_EQ(cli_main({"export", set_dir, "-o", glb}), 0);
  std::ifstream f(glb, std::ios::binary);
  char magic[4];
  f.read(magic, 4);
  EXPECT_EQ(std::string(magic, 4), "glTF");
  Assimp::Importer importer;
  const aiScene* scene = importer.ReadFile(glb, 0);
  ASSERT_NE(scene, nullptr) << importer.GetErrorString();
  ASSERT_EQ(scene->mNumMeshes, 2u);
  bool found_heart = false;
  for (unsigned i = 0; i < scene->mNumMeshes; ++i) {
    const aiMesh* m = scene->mMeshes[i];
    const std::string name = m->mName.C_Str();
    const io::OrganEntry* e = set.find(name);
    ASSERT_NE(e, nullptr) << name;
    EXPECT_EQ(m->mNumFaces, e->mesh.face_count());
    aiColor4D c;
    ASSERT_EQ(scene->mMaterials[m->mMaterialIndex]->Get(AI_MATKEY_BASE_COLOR, c), AI_SUCCESS);
    EXPECT_NEAR(c.r, e->color[0], 1e-3);
    EXPECT_NEAR(c.g, e->color[1], 1e-3);
    found_heart |= name == "heart";
  }
  EXPECT_TRUE(found_heart);
}

// Adds a Caret/CIFTI XML label table (as TotalSegmentator writes) as a NIfTI header extension
// to an uncompressed .nii written by write_label_nifti (352-byte header, no extension yet).
void add_caret_label_table(const std::string& path, const std::map<int, std::string>& names) {
  std::ifstream in(path, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  in.close();
  std::string xml = "<?xml version=\"1.0\" encoding=\"UTF-8\"?> <CaretExtension> <LabelTable>\n";
  for (const auto& [k, n] : names)
    xml += "<Label Key=\"" + std::to_string(k) + "\" Red=\"1\" Green=\"0\" Blue=\"0\" Alpha=\"1\"><![CDATA[" + n +
           "]]></Label>\n";
  xml += "</LabelTable> </CaretExtension>";
  const int32_t esize = static_cast<int32_t>((8 + xml.size() + 15) / 16 * 16), ecode = 0;
  xml.resize(static_cast<size_t>(esize - 8), '\0');
  const float vox_offset = static_cast<float>(352 + esize);
  std::memcpy(&bytes[108], &vox_offset, 4);
  bytes[348] = 1;
  std::string ext(8, '\0');
  std::memcpy(&ext[0], &esize, 4);
  std::memcpy(&ext[4], &ecode, 4);
  bytes.insert(352, ext + xml);
  std::ofstream(path, std::ios::binary) << bytes;
}

// A label map with its own table: value 7 is the heart there (the pancreas in TotalSegmentator's
// numbering), and `--organs heart` finds it by name.
// A 0/1 mask given without a name would build TotalSegmentator's label 1 (spleen): an error that
// says how to name it, and nothing written.
// Bones go into the organ set as rigid context (issue 14): `--organs liver,bones` on the abdomen
// slab writes the vertebrae with material {model: rigid}, no anchors of their own, the liver
// solid and anchored; connection springs tie the liver to bone only where they touch.
TEST(Build, BonesAreRigidContext) {
  const std::string out = (fs::temp_directory_path() / "softatlas-build-bones").string();
  fs::remove_all(out);
  ASSERT_EQ(cli_main({"build", abdomen("ct_from_dicom.nii.gz"), "--labels", abdomen("example_seg_dicom.nii.gz"),
                      "--organs", "liver,bones", "-q", "-o", out}),
            0);
  const io::OrganSet set = io::read_organ_set(out);
  int bones = 0;
  for (const io::OrganEntry& e : set.organs) {
    if (e.name == "liver") {
      EXPECT_EQ(e.material.model, "solid");
      EXPECT_FALSE(e.fixed_vertices.empty());
      continue;
    }
    ++bones;
    EXPECT_EQ(e.material.model, "rigid") << e.name;
    EXPECT_TRUE(e.fixed_vertices.empty()) << e.name;
  }
  EXPECT_GE(bones, 3);
  fs::remove_all(out);
}

// Every file of the two sets, byte for byte (quality.json without its timings).
void expect_same_sets(const std::string& a, const std::string& b) {
  size_t files = 0;
  for (const auto& e : fs::recursive_directory_iterator(a)) {
    if (!e.is_regular_file()) continue;
    ++files;
    const fs::path rel = fs::relative(e.path(), a);
    std::ifstream fa(e.path(), std::ios::binary), fb(fs::path(b) / rel, std::ios::binary);
    ASSERT_TRUE(fb.good()) << rel;
    std::string x((std::istreambuf_iterator<char>(fa)), {}), y((std::istreambuf_iterator<char>(fb)), {});
    if (rel == "quality.json") {
      auto qx = nlohmann::json::parse(x), qy = nlohmann::json::parse(y);
      for (const char* k : {"stage_seconds", "organ_seconds"}) qx.erase(k), qy.erase(k);
      x = qx.dump(), y = qy.dump();
    }
    EXPECT_TRUE(x == y) << rel << " differs between the serial and the parallel build";
  }
  EXPECT_GT(files, 5u);
}

// Organs are built on several threads (issue 14, speed): the set must not depend on how many.
// Seven structures of the slab of different cost (the vertebrae with their crossing repair,
// thin ribs, vessels), serial against 2 and 3 jobs (more threads than this machine's cores).
TEST(Build, ParallelBuildEqualsTheSerialOneByteForByte) {
  test::Scratch tmp;
  const std::string organs =
      "pancreas,vertebrae_T11,vertebrae_T12,rib_left_10,aorta,inferior_vena_cava,portal_vein_and_splenic_vein";
  for (const char* jobs : {"1", "2", "3"})
    ASSERT_EQ(cli_main({"build", abdomen("ct_from_dicom.nii.gz"), "--labels", abdomen("example_seg_dicom.nii.gz"),
                        "--organs", organs, "--jobs", jobs, "-q", "-o", tmp(std::string("set") + jobs)}),
              0);
  expect_same_sets(tmp("set1"), tmp("set2"));
  expect_same_sets(tmp("set1"), tmp("set3"));
  // The thin vertebra (processes a few mm apart, cut by the slab) keeps its label volume too
  // (issue 14, item 4): volume counted from its voxels here, not taken from quality.json.
  const Volume labels = read_volume(abdomen("example_seg_dicom.nii.gz"));
  size_t voxels = 0;
  for (float x : labels.values) voxels += std::lround(x) == 33;  // TotalSegmentator: vertebrae_T11
  const io::OrganSet set = io::read_organ_set(tmp("set2"));
  const io::OrganEntry* t11 = set.find("vertebrae_T11");
  ASSERT_NE(t11, nullptr);
  ASSERT_GT(voxels, 0u);
  EXPECT_NEAR(
      softatlas::sim::enclosed_volume(t11->mesh.vertices, t11->mesh.faces) / (voxels * labels.voxel_volume_mm3()), 1.0,
      0.10);
}

TEST(Build, BareMaskWithoutANameIsAnError) {
  const std::string out = (fs::temp_directory_path() / "softatlas-test-bare-mask-set").string();
  fs::remove_all(out);
  try {
    cli_main({"build", chest("ct_heart_crop.nii.gz"), "--labels", chest("heart_on_ct_heart_crop_grid.nii.gz"), "-q",
              "-o", out});
    FAIL() << "a bare mask was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("--labels NAME="), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(out));
}

TEST(Build, LabelMapWithItsOwnTableIsReadByName) {
  test::Scratch tmp;
  Volume m = read_volume(chest("heart_on_ct_heart_crop_grid.nii.gz"));
  for (float& x : m.values) x = x != 0 ? 7.0f : 0.0f;
  write_label_nifti(m, tmp("own.nii"));
  add_caret_label_table(tmp("own.nii"), {{7, "heart"}, {9, "spleen"}});
  const Volume own = read_volume(tmp("own.nii"));
  EXPECT_EQ(own.values, m.values);  // the extension moved the data, the reader followed vox_offset
  ASSERT_EQ(own.label_names.size(), 2u);
  EXPECT_EQ(own.label_names.at(7), "heart");
  ASSERT_EQ(cli_main({"build", chest("ct_heart_crop.nii.gz"), "--labels", tmp("own.nii"), "--organs", "heart",
                      "--budget", "heart=800", "-q", "-o", tmp("set")}),
            0);
  const io::OrganSet set = io::read_organ_set(tmp("set"));
  ASSERT_EQ(set.organs.size(), 1u);
  EXPECT_EQ(set.organs[0].name, "heart");
  EXPECT_EQ(set.organs[0].label, 51);
  // Without the table, 7 is the pancreas and the heart is absent.
  write_label_nifti(m, tmp("plain.nii"));
  EXPECT_THROW(cli_main({"build", chest("ct_heart_crop.nii.gz"), "--labels", tmp("plain.nii"), "--organs", "heart",
                         "-q", "-o", tmp("set2")}),
               InputError);
  EXPECT_FALSE(fs::exists(tmp("set2")));
}

TEST(Build, ConfigFileAndBudgetsFromYaml) {
  test::Scratch tmp;
  std::ofstream(tmp("build.yaml")) << "organs: [pulmonary_artery]\nbudget: {pulmonary_artery: 700}\n"
                                      "smoothing_iterations: 15\n";
  ASSERT_EQ(cli_main({"build", chest("ct_heart_crop.nii.gz"), "--labels",
                      "pulmonary_artery=" + chest("pulmonary_artery.nii.gz"), "--config", tmp("build.yaml"), "-q", "-o",
                      tmp("set")}),
            0);
  const io::OrganSet set = io::read_organ_set(tmp("set"));
  ASSERT_EQ(set.organs.size(), 1u);
  EXPECT_NEAR(static_cast<double>(set.organs[0].mesh.face_count()), 700, 14);
  std::ofstream(tmp("bad.yaml")) << "organs: [pulmonary_artery]\nsmothing: 3\n";
  try {
    build_organ_set([&] {
      BuildOptions o;
      apply_build_config(tmp("bad.yaml"), &o);
      return o;
    }());
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.yaml:2:1"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace softatlas::pipeline
