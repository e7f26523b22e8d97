// Organ sets: write, read back, validate; scene conversion to SI.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "softatlas/io/ct_image.hpp"
#include "softatlas/io/organ_set.hpp"
#include "softatlas/io/scene.hpp"
#include "softatlas/sim/error.hpp"
#include "softatlas/sim/sim.hpp"

namespace softatlas {
namespace {
namespace fs = std::filesystem;

io::OrganSet small_set() {
  io::OrganSet set;
  io::OrganEntry liver;
  liver.name = "liver";
  liver.label = 5;
  liver.mesh = io::read_mesh(std::string(SOFTATLAS_SOURCE_DIR) + "/data/meshes/liver_1000.obj");
  liver.color = io::default_organ_color("liver");
  liver.fixed_vertices = {1, 2, 3};
  io::OrganEntry gb = liver;
  gb.name = "gallbladder";
  gb.label = 4;
  for (size_t i = 0; i < gb.mesh.vertices.size(); i += 3) gb.mesh.vertices[i] += 200.0;
  set.organs = {liver, gb};
  set.connections = {{"liver", 10, "gallbladder", 20, 12.5, 3.0}};
  set.provenance["tool"] = "softatlas test";
  return set;
}

fs::path fresh(const std::string& name) {
  const fs::path p = fs::temp_directory_path() / name;
  fs::remove_all(p);
  return p;
}

TEST(OrganSet, WriteThenReadBack) {
  const fs::path dir = fresh("softatlas_set_rt");
  io::write_organ_set(small_set(), dir.string(), {{"quality.json", "{}\n"}});
  EXPECT_TRUE(fs::exists(dir / "organs/liver.ply"));
  EXPECT_TRUE(fs::exists(dir / "quality.json"));
  const io::OrganSet set = io::read_organ_set(dir.string());
  ASSERT_EQ(set.organs.size(), 2u);
  EXPECT_EQ(set.organs[0].mesh.vertices, small_set().organs[0].mesh.vertices);
  EXPECT_EQ(set.organs[1].label, 4);
  EXPECT_EQ(set.organs[0].fixed_vertices, (std::vector<int32_t>{1, 2, 3}));
  ASSERT_EQ(set.connections.size(), 1u);
  EXPECT_DOUBLE_EQ(set.connections[0].rest_length_mm, 12.5);
  // an existing folder is not overwritten
  EXPECT_THROW(io::write_organ_set(small_set(), dir.string()), InputError);
}

// model: rigid (bone) reads, writes back as `{model: rigid, density_kg_m3: ...}`, maps to
// sim::ModelKind::rigid, and a model override leaves it rigid.
TEST(OrganSet, RigidOrgansRoundTripAndStayRigidUnderAnOverride) {
  const fs::path dir = fresh("softatlas_set_rigid");
  io::OrganSet in = small_set();
  in.organs[1].name = "sacrum";
  in.organs[1].material.model = "rigid";
  in.organs[1].material.density_kg_m3 = 1900;
  in.organs[1].fixed_vertices.clear();
  in.connections[0].organ_b = "sacrum";
  io::write_organ_set(in, dir.string());
  std::ifstream yaml(dir / "atlas.yaml");
  const std::string text((std::istreambuf_iterator<char>(yaml)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("material: {model: rigid, density_kg_m3: 1900}"), std::string::npos) << text;
  const io::OrganSet set = io::read_organ_set(dir.string());
  EXPECT_EQ(set.organs[1].material.model, "rigid");
  EXPECT_TRUE(set.organs[0].regions.empty());
  EXPECT_EQ(set.organs[1].material.density_kg_m3, 1900);
  io::SceneOptions opt;
  opt.model_override = "tmsm";
  const sim::SceneDesc scene = io::scene_from_organ_set(set, opt);
  EXPECT_EQ(scene.organs[0].material.model, sim::ModelKind::tmsm);
  EXPECT_EQ(scene.organs[1].material.model, sim::ModelKind::rigid);
  const sim::Model m = sim::compile(scene);
  const sim::OrganRange& bone = m.organs[static_cast<size_t>(sim::find_organ(m, "sacrum"))];
  EXPECT_EQ(bone.spring_end, bone.spring_begin);
  // an unknown model names the choices, rigid among them
  std::string bad = text;
  bad.replace(bad.find("model: rigid"), 12, "model: bone");
  std::ofstream(dir / "atlas.yaml") << bad;
  try {
    io::read_organ_set(dir.string());
    FAIL() << "model: bone accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("unknown model 'bone' (expected tmsm, cmsm, nmsm, flexion, solid or rigid)"),
              std::string::npos)
        << e.what();
  }
}

// Named regions (landmarks) round-trip in file order; a bad point names the file and line.
TEST(OrganSet, NamedRegionsRoundTripAndBadOnesAreRejected) {
  const fs::path dir = fresh("softatlas_set_regions");
  io::OrganSet in = small_set();
  in.organs[0].regions = {{"gastric_impression", {-24.5, 69, 388.9}}, {"bare_area", {31.25, -16, 384.5}}};
  io::write_organ_set(in, dir.string());
  const io::OrganSet set = io::read_organ_set(dir.string());
  ASSERT_EQ(set.organs[0].regions.size(), 2u);
  EXPECT_EQ(set.organs[0].regions[0].first, "gastric_impression");
  EXPECT_EQ(set.organs[0].regions[1].second, (std::array<double, 3>{31.25, -16, 384.5}));
  EXPECT_NE(set.organs[0].find_region("bare_area"), nullptr);
  EXPECT_EQ(set.organs[0].find_region("hilum"), nullptr);
  std::ifstream yaml(dir / "atlas.yaml");
  std::string text((std::istreambuf_iterator<char>(yaml)), std::istreambuf_iterator<char>());
  for (const auto& [bad, what] : std::vector<std::pair<std::string, std::string>>{
           {"bare_area: [31.25, -16]", "region 'bare_area': expected [x, y, z] (mm)"},
           {"bare_area: [31.25, -16, 1e9]", "region coordinates must be within 1e4 mm"},
           {"bare_area: [31.25, -16, .nan]", ""},
           {"bare_area: [31.25, -16, 384.5]\n      gastric_impression: [0, 0, 0]", "duplicate"}}) {
    std::string t = text;
    t.replace(t.find("bare_area: [31.25, -16, 384.5]"), 30, bad);
    std::ofstream(dir / "atlas.yaml") << t;
    try {
      io::read_organ_set(dir.string());
      ADD_FAILURE() << bad << " accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("atlas.yaml:"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  }
}

TEST(OrganSet, SceneIsInMetresAndHiddenOrgansStayOutUnlessConnected) {
  const fs::path dir = fresh("softatlas_set_scene");
  io::write_organ_set(small_set(), dir.string());
  const io::OrganSet set = io::read_organ_set(dir.string());
  io::SceneOptions opt;
  opt.shown = {"liver"};
  sim::SceneDesc scene = io::scene_from_organ_set(set, opt);
  EXPECT_DOUBLE_EQ(scene.organs[0].vertices[0], 1e-3 * set.organs[0].mesh.vertices[0]);
  EXPECT_DOUBLE_EQ(scene.connections[0].rest_length_m, 12.5e-3);
  EXPECT_EQ(sim::compile(scene).organs.size(), 2u);  // gallbladder kept: connected
  scene.connections.clear();
  EXPECT_EQ(sim::compile(scene).organs.size(), 1u);
  opt.shown = {"spleen"};
  try {
    io::scene_from_organ_set(set, opt);
    FAIL() << "absent organ accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("organ 'spleen' is not in this organ set"), std::string::npos);
  }
}

TEST(OrganSet, BadManifestsNameFileLineAndColumn) {
  const fs::path dir = fresh("softatlas_set_bad");
  io::write_organ_set(small_set(), dir.string());
  const std::string yaml = (dir / "atlas.yaml").string();
  std::string text;
  {
    std::ifstream in(yaml);
    text.assign(std::istreambuf_iterator<char>(in), {});
  }
  auto expect_error = [&](const std::string& modified, const std::string& needle) {
    std::ofstream(yaml) << modified;
    try {
      io::read_organ_set(dir.string());
      ADD_FAILURE() << "accepted: " << needle;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  expect_error(text + "colour: red\n", "unknown key 'colour'");
  std::string t2 = text;
  t2.replace(t2.find("model: solid"), 12, "model: fem-ish");
  expect_error(t2, "unknown model 'fem-ish'");
  std::string t3 = text;
  t3.replace(t3.find("young_modulus_pa: 4000"), 22, "young_modulus_pa: -4000");
  expect_error(t3, "'young_modulus_pa' must be >= 0");
  std::string t4 = text;
  t4.replace(t4.find("organs/liver.ply"), 16, "organs/lover.ply");
  expect_error(t4, "lover.ply: no such file");
  std::ofstream(yaml) << text;
  std::ofstream(dir / "connections.csv")
      << "organ_a,vertex_a,organ_b,vertex_b,rest_length_mm,stiffness\nliver,10,spleen,2,1,1\n";
  try {
    io::read_organ_set(dir.string());
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("connections.csv:2: organ 'spleen' is not in atlas.yaml"), std::string::npos)
        << e.what();
  }
}

// A small CT: 8 x 6 x 5 voxels of 2 x 2 x 3 mm, HU = 10 i - 1000 (a ramp along x), an oblique-free
// sform with an offset; an encoded file read back has the same voxels and transform.
io::CtImage small_ct() {
  io::CtImage ct;
  ct.dims = {8, 6, 5};
  ct.ijk_to_ras = {2, 0, 0, -10, 0, 2, 0, 20, 0, 0, 3, 300, 0, 0, 0, 1};
  for (int k = 0; k < 5; ++k)
    for (int j = 0; j < 6; ++j)
      for (int i = 0; i < 8; ++i) ct.hu.push_back(static_cast<int16_t>(10 * i - 1000 + j + 100 * k));
  return ct;
}

TEST(OrganSet, CtBlockRoundTripsWithItsFileAndWindow) {
  const fs::path dir = fresh("softatlas_set_ct");
  io::OrganSet set = small_set();
  set.ct = io::CtRecord{"ct.nii.gz", 350, 50};
  io::write_organ_set(set, dir.string(), {{"ct.nii.gz", io::encode_ct_nifti_gz(small_ct())}});
  const io::OrganSet back = io::read_organ_set(dir.string());
  ASSERT_TRUE(back.ct.has_value());
  EXPECT_EQ(back.ct->file, "ct.nii.gz");
  EXPECT_DOUBLE_EQ(back.ct->window_width_hu, 350);
  EXPECT_DOUBLE_EQ(back.ct->window_level_hu, 50);
  const io::CtImage ct = io::read_ct_nifti(back.ct_path());
  EXPECT_EQ(ct.dims, small_ct().dims);
  EXPECT_EQ(ct.hu, small_ct().hu);
  EXPECT_EQ(ct.ijk_to_ras, small_ct().ijk_to_ras);
  // World mapping and trilinear sampling: voxel (3, 2, 1) is at (-4, 24, 303) mm.
  const auto w = ct.world(3, 2, 1);
  EXPECT_DOUBLE_EQ(w[0], -4);
  EXPECT_DOUBLE_EQ(w[1], 24);
  EXPECT_DOUBLE_EQ(w[2], 303);
  float hu = 0;
  ASSERT_TRUE(ct.sample({-3, 24, 303}, &hu));  // half way between i = 3 and 4
  EXPECT_NEAR(hu, 10 * 3.5 - 1000 + 2 + 100, 1e-4);
  EXPECT_FALSE(ct.sample({-30, 24, 303}, &hu));
  // Written again from the folder it was read from, the set keeps its CT.
  const fs::path again = fresh("softatlas_set_ct_again");
  io::write_organ_set(back, again.string());
  EXPECT_EQ(io::read_ct_nifti(io::read_organ_set(again.string()).ct_path()).hu, small_ct().hu);
  // Sets without a CT read as before.
  const fs::path plain = fresh("softatlas_set_no_ct");
  io::write_organ_set(small_set(), plain.string());
  EXPECT_FALSE(io::read_organ_set(plain.string()).ct.has_value());
  // A set that says it has a CT but gives none is not written.
  EXPECT_THROW(io::write_organ_set(set, fresh("softatlas_set_ct_missing").string()), InputError);
}

TEST(OrganSet, BadCtBlocksNameTheLineAndTheField) {
  const fs::path dir = fresh("softatlas_set_ct_bad");
  io::OrganSet set = small_set();
  set.ct = io::CtRecord{};
  io::write_organ_set(set, dir.string(), {{"ct.nii.gz", io::encode_ct_nifti_gz(small_ct())}});
  const std::string yaml = (dir / "atlas.yaml").string();
  std::string text;
  {
    std::ifstream in(yaml);
    text.assign(std::istreambuf_iterator<char>(in), {});
  }
  const std::string good = "ct: {file: ct.nii.gz, window_width_hu: 400, window_level_hu: 40}";
  ASSERT_NE(text.find(good), std::string::npos) << text;
  const size_t line = static_cast<size_t>(std::count(text.begin(), text.begin() + text.find(good), '\n')) + 1;
  auto expect_error = [&](const std::string& block, const std::string& needle) {
    std::string t = text;
    t.replace(t.find(good), good.size(), block);
    std::ofstream(yaml) << t;
    try {
      io::read_organ_set(dir.string());
      ADD_FAILURE() << "accepted: " << block;
    } catch (const InputError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(needle), std::string::npos) << what;
      EXPECT_NE(what.find("atlas.yaml:" + std::to_string(line) + ":"), std::string::npos) << what;
    }
  };
  expect_error("ct: {file: missing.nii.gz}", "ct: file 'missing.nii.gz' not found");
  expect_error("ct: {file: ct.nii.gz, window_width_hu: -5}", "'window_width_hu' must be in 1..10000");
  expect_error("ct: {file: ct.nii.gz, window_width_hu: wide}", "a number for 'window_width_hu'");
  expect_error("ct: {file: ct.nii.gz, window_level_hu: .nan}", "'window_level_hu' must be finite");
  expect_error("ct: {file: ct.nii.gz, window_level_hu: 9000}", "'window_level_hu' must be in -2000..5000");
  expect_error("ct: {file: ../ct.nii.gz}", "inside the set folder");
  expect_error("ct: {window_width_hu: 400}", "missing 'file'");
  expect_error("ct: {file: ct.nii.gz, window: 400}", "unknown key 'window' in ct");
  expect_error("ct: ct.nii.gz", "ct: expected a map");
  // A file that is not a NIfTI CT.
  std::ofstream(dir / "not_ct.nii") << "hello";
  expect_error("ct: {file: not_ct.nii}", "truncated NIfTI header");
}

// connections.csv numbers are whole tokens (12abc and 1e999 were read as 12 and 1), CR-only line
// endings are line breaks, and atlas.yaml's format version is checked (issue 17).
TEST(OrganSet, ConnectionsAreStrictAndTheFormatVersionIsChecked) {
  const std::string header = "organ_a,vertex_a,organ_b,vertex_b,rest_length_mm,stiffness\n";
  auto error_of = [&](const std::string& rows) -> std::string {
    try {
      io::parse_connections_csv(header + rows, "c.csv");
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_NE(error_of("liver,12abc,gb,2,1,1\n").find("c.csv:2: vertex_a: expected a whole integer"), std::string::npos);
  EXPECT_NE(error_of("liver,1e999,gb,2,1,1\n").find("vertex_a"), std::string::npos);
  EXPECT_NE(error_of("liver,1,gb,99999999999,1,1\n").find("vertex_b"), std::string::npos);
  EXPECT_NE(error_of("liver,1,gb, 2,1,1\n").find("vertex_b"), std::string::npos);
  EXPECT_NE(error_of("liver,1,gb,2,1e999,1\n").find("rest_length_mm: expected a finite number"), std::string::npos);
  EXPECT_NE(error_of("liver,1,gb,2,1,nan\n").find("stiffness"), std::string::npos);
  EXPECT_NE(error_of("liver,1,gb,2,1,5x\n").find("stiffness"), std::string::npos);
  EXPECT_NE(error_of("liver,1,gb,2,1,\x01\xfe\n")
                .find("'?"
                      "?'"),
            std::string::npos);
  const auto cr = io::parse_connections_csv(
      "organ_a,vertex_a,organ_b,vertex_b,rest_length_mm,stiffness\rliver,1,gb,2,0.5,3\rliver,4,gb,5,1,3\r", "cr.csv");
  ASSERT_EQ(cr.size(), 2u);
  EXPECT_EQ(cr[1].vertex_b, 5);
  EXPECT_EQ(io::parse_connections_csv(header + "liver,1,gb,2,0.5,3\r\n", "crlf.csv").size(), 1u);

  const fs::path dir = fresh("softatlas_set_version");
  io::write_organ_set(small_set(), dir.string());
  const std::string yaml = (dir / "atlas.yaml").string();
  std::string text;
  {
    std::ifstream in(yaml);
    text.assign(std::istreambuf_iterator<char>(in), {});
  }
  auto manifest_error = [&](const std::string& modified) -> std::string {
    std::ofstream(yaml) << modified;
    try {
      io::read_organ_set(dir.string());
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  };
  std::string v2 = text;
  v2.replace(v2.find("softatlas_organ_set: 1"), 22, "softatlas_organ_set: 2");
  EXPECT_NE(manifest_error(v2).find("format version 2 is not supported"), std::string::npos) << manifest_error(v2);
  std::string none = text;
  none.replace(none.find("softatlas_organ_set: 1"), 22, "");
  EXPECT_NE(manifest_error(none).find("missing 'softatlas_organ_set: 1'"), std::string::npos) << manifest_error(none);
  std::string deep = "softatlas_organ_set: 1\norgans: " + std::string(100000, '[') + "\n";
  EXPECT_FALSE(manifest_error(deep).empty());
  std::ofstream(yaml) << text;
  EXPECT_NO_THROW(io::read_organ_set(dir.string()));
}

// A writer killed before its rename leaves .NAME.partial.PID; the next write removes the folders
// of dead processes (and keeps those of live ones).
TEST(OrganSet, StalePartialFoldersOfDeadWritersAreRemoved) {
  const fs::path dir = fresh("softatlas_set_partial");
  fs::create_directories(dir);
  const fs::path dead = dir / ".set.partial.2147480000", live = dir / ".set.partial.1",
                 other = dir / ".other.partial.2147480001";
  for (const fs::path& p : {dead, live, other}) fs::create_directories(p / "organs");
  io::write_organ_set(small_set(), (dir / "set").string());
  EXPECT_FALSE(fs::exists(dead));
  EXPECT_TRUE(fs::exists(live)) << "pid 1 is alive";
  EXPECT_TRUE(fs::exists(other)) << "another set's folder";
  EXPECT_TRUE(fs::exists(dir / "set" / "atlas.yaml"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace softatlas
