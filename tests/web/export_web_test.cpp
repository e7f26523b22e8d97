// `softatlas export SET --web DIR` (pipeline/src/export_web.cpp): the folder's files, scene.json
// carrying the native SceneDesc, lessons.json, and bad input (not an export folder, no built page).
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <unistd.h>
#include <vector>
#include <nlohmann/json.hpp>

#include "softatlas/io/organ_set.hpp"
#include "softatlas/io/scene.hpp"
#include "softatlas/pipeline/export_web.hpp"
#include "softatlas/sim/error.hpp"
#include "softatlas/sim/sim.hpp"

namespace fs = std::filesystem;
using nlohmann::json;
using softatlas::InputError;
namespace pipeline = softatlas::pipeline;

namespace {

const std::string kSet = std::string(SOFTATLAS_SOURCE_DIR) + "/data/atlas";
const std::string kDist = std::string(SOFTATLAS_BINARY_DIR) + "/web/dist";

fs::path fresh(const std::string& name) {
  const fs::path p = fs::temp_directory_path() / ("softatlas_web_test_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(p);
  return p;
}

json read_json(const fs::path& p) {
  std::ifstream in(p);
  return json::parse(in);
}

}  // namespace

TEST(ExportWeb, WritesThePageTheAtlasAndTheNativeScene) {
  const fs::path out = fresh("ok");
  pipeline::export_web(kSet, out.string(), kDist);
  for (const char* f : {"index.html", "app.js", "worker.js", "softatlas_sim.mjs", "softatlas_sim.wasm", "atlas.glb",
                        "scene.json", "lessons.json"})
    EXPECT_TRUE(fs::exists(out / f)) << f;
  EXPECT_FALSE(fs::exists(out.string() + ".tmp-web"));
  const json scene = read_json(out / "scene.json");
  const auto desc = softatlas::io::scene_from_organ_set(softatlas::io::read_organ_set(kSet), {});
  ASSERT_EQ(scene["organs"].size(), desc.organs.size());
  for (size_t i = 0; i < desc.organs.size(); ++i) {
    const json& o = scene["organs"][i];
    EXPECT_EQ(o["name"], desc.organs[i].name);
    // Round-trip doubles: the page compiles exactly the native vertices.
    EXPECT_EQ(o["vertices"].get<std::vector<double>>(), desc.organs[i].vertices);
    EXPECT_EQ(o["faces"].get<std::vector<int32_t>>(), desc.organs[i].faces);
    EXPECT_EQ(o["fixed"].get<std::vector<int32_t>>(), desc.organs[i].fixed);
    EXPECT_EQ(o["material"]["volume_stiffness"].get<double>(), desc.organs[i].material.volume_stiffness);
  }
  EXPECT_EQ(scene["connections"].size(), desc.connections.size());
  EXPECT_EQ(scene["settings"]["dt_s"].get<double>(), desc.dt_s);
  softatlas::sim::Integrator integrator{};
  ASSERT_TRUE(softatlas::sim::parse_integrator(scene["settings"]["integrator"].get<std::string>(), integrator));
  EXPECT_EQ(integrator, desc.integrator);
  const json lessons = read_json(out / "lessons.json");
  // Every lesson of data/lessons is on data/atlas: each must be exported, in file-name order.
  std::vector<std::string> shipped;
  for (const auto& e : fs::directory_iterator(std::string(SOFTATLAS_SOURCE_DIR) + "/data/lessons"))
    if (e.path().extension() == ".yaml") shipped.push_back(e.path().filename().string());
  std::sort(shipped.begin(), shipped.end());
  ASSERT_EQ(lessons.size(), shipped.size());
  for (size_t i = 0; i < shipped.size(); ++i) EXPECT_EQ(lessons[i]["file"], shipped[i]);
  const auto mobility = std::find(shipped.begin(), shipped.end(), "liver_mobility.yaml");
  ASSERT_NE(mobility, shipped.end());
  const json& liver = lessons[static_cast<size_t>(mobility - shipped.begin())];
  EXPECT_EQ(liver["steps"][4]["pull"]["radius_mm"].get<double>(), 12.0);  // liver_mobility.yaml line 23
  // A second export replaces the first.
  pipeline::export_web(kSet, out.string(), kDist);
  EXPECT_TRUE(fs::exists(out / "scene.json"));
  fs::remove_all(out);
}

TEST(ExportWeb, RefusesAFolderThatIsNotAPreviousExport) {
  const fs::path out = fresh("other");
  fs::create_directories(out);
  std::ofstream(out / "notes.txt") << "keep me";
  try {
    pipeline::export_web(kSet, out.string(), kDist);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("not a previous web export"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(fs::exists(out / "notes.txt"));
  EXPECT_FALSE(fs::exists(out.string() + ".tmp-web"));
  fs::remove_all(out);
}

TEST(ExportWeb, SaysHowToBuildThePageWhenItIsMissing) {
  const fs::path out = fresh("nodist");
  try {
    pipeline::export_web(kSet, out.string(), "");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("scripts/build-web"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(out));
}

TEST(ExportWeb, BadOrganSetLeavesNothingBehind) {
  const fs::path out = fresh("badset");
  EXPECT_THROW(pipeline::export_web(kSet + "/no_such_set", out.string(), kDist), InputError);
  EXPECT_FALSE(fs::exists(out));
  EXPECT_FALSE(fs::exists(out.string() + ".tmp-web"));
}
