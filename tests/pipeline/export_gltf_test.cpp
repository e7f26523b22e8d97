// softatlas export: glTF that other engines take as is, read back byte by byte.
// The demo atlas (data/atlas) to .gltf (JSON + .bin) and .glb; checks the JSON, the buffer sizes,
// the node extras, glTF's axes (anterior +Z, superior +Y) and that the scene is centred.
#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "softatlas/io/organ_set.hpp"
#include "softatlas/pipeline/build.hpp"
#include "softatlas/sim/error.hpp"

namespace softatlas::pipeline {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

std::string out_dir() {
  const fs::path p = fs::path(SOFTATLAS_BINARY_DIR) / "test_output" / "pipeline" / "export_gltf";
  fs::create_directories(p);
  return p.string();
}
std::string atlas() { return std::string(SOFTATLAS_SOURCE_DIR) + "/data/atlas"; }

std::vector<uint8_t> read_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::vector<uint8_t>((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

// Position of vertex v of mesh m (glTF metres), from the binary buffer.
std::array<float, 3> position(const json& doc, const std::vector<uint8_t>& bin, int mesh, size_t v) {
  const int acc = doc["meshes"][mesh]["primitives"][0]["attributes"]["POSITION"];
  const json& view = doc["bufferViews"][doc["accessors"][acc]["bufferView"].get<int>()];
  std::array<float, 3> p;
  std::memcpy(p.data(), bin.data() + view["byteOffset"].get<size_t>() + 12 * v, 12);
  return p;
}

// Everything a reader needs, for either container.
void check_document(const json& doc, const std::vector<uint8_t>& bin) {
  const io::OrganSet set = io::read_organ_set(atlas());
  EXPECT_EQ(doc["asset"]["version"], "2.0");
  ASSERT_EQ(doc["buffers"].size(), 1u);
  EXPECT_EQ(doc["buffers"][0]["byteLength"].get<size_t>(), bin.size());
  for (const json& v : doc["bufferViews"]) {
    EXPECT_LE(v["byteOffset"].get<size_t>() + v["byteLength"].get<size_t>(), bin.size());
    EXPECT_EQ(v["byteOffset"].get<size_t>() % 4, 0u);
  }
  // Accessor counts against the organ set; every index in range.
  const json& root = doc["nodes"][0];
  EXPECT_EQ(doc["scenes"][0]["nodes"], json::array({0}));
  ASSERT_EQ(root["children"].size(), set.organs.size());
  std::array<float, 3> lo{1e9f, 1e9f, 1e9f}, hi{-1e9f, -1e9f, -1e9f};
  for (size_t i = 0; i < set.organs.size(); ++i) {
    const io::OrganEntry& e = set.organs[i];
    const json& node = doc["nodes"][root["children"][i].get<int>()];
    EXPECT_EQ(node["name"], e.name);
    EXPECT_EQ(node["extras"]["name"], e.name);
    EXPECT_EQ(node["extras"]["label"], e.label);
    EXPECT_EQ(node["extras"]["fma"], e.fma);
    EXPECT_EQ(node["extras"]["rigid"].get<bool>(), e.material.model == "rigid");
    const int m = node["mesh"];
    const json& prim = doc["meshes"][m]["primitives"][0];
    const json& pos = doc["accessors"][prim["attributes"]["POSITION"].get<int>()];
    const json& idx = doc["accessors"][prim["indices"].get<int>()];
    EXPECT_EQ(pos["count"].get<size_t>(), e.mesh.vertex_count());
    EXPECT_EQ(idx["count"].get<size_t>(), 3 * e.mesh.face_count());
    EXPECT_EQ(doc["bufferViews"][pos["bufferView"].get<int>()]["byteLength"].get<size_t>(), 12 * e.mesh.vertex_count());
    const json& iv = doc["bufferViews"][idx["bufferView"].get<int>()];
    ASSERT_EQ(iv["byteLength"].get<size_t>(), 12 * e.mesh.face_count());
    for (size_t k = 0; k < 3 * e.mesh.face_count(); ++k) {
      uint32_t x;
      std::memcpy(&x, bin.data() + iv["byteOffset"].get<size_t>() + 4 * k, 4);
      ASSERT_LT(x, e.mesh.vertex_count());
    }
    // Axes: vertex 0 in glTF = (-x, z, y) of RAS, minus the centre, in metres.
    const auto off = root["extras"]["patient_offset_mm"];
    const auto p = position(doc, bin, m, 0);
    EXPECT_NEAR(p[0], -(e.mesh.vertices[0] - off[0].get<double>()) * 1e-3, 1e-6);
    EXPECT_NEAR(p[1], (e.mesh.vertices[2] - off[2].get<double>()) * 1e-3, 1e-6);
    EXPECT_NEAR(p[2], (e.mesh.vertices[1] - off[1].get<double>()) * 1e-3, 1e-6);
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], pos["min"][k].get<float>());
      hi[k] = std::max(hi[k], pos["max"][k].get<float>());
    }
    EXPECT_EQ(doc["materials"][prim["material"].get<int>()]["pbrMetallicRoughness"]["baseColorFactor"][0].get<float>(),
              e.color[0]);
  }
  // Centred: the bounding box of the whole scene is symmetric about the origin.
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(lo[k] + hi[k], 0.0f, 1e-5f) << k;
  // Anterior is +Z: the liver (anterior) lies in front of the kidneys (posterior); superior +Y:
  // the liver's top is above the kidneys'; the patient's right (right kidney) is at -X.
  auto centre_of = [&](const std::string& name) {
    for (const json& c : root["children"]) {
      const json& node = doc["nodes"][c.get<int>()];
      if (node["name"] == name) {
        const json& a =
            doc["accessors"]
               [doc["meshes"][node["mesh"].get<int>()]["primitives"][0]["attributes"]["POSITION"].get<int>()];
        return std::array<float, 3>{0.5f * (a["min"][0].get<float>() + a["max"][0].get<float>()),
                                    0.5f * (a["min"][1].get<float>() + a["max"][1].get<float>()),
                                    0.5f * (a["min"][2].get<float>() + a["max"][2].get<float>())};
      }
    }
    ADD_FAILURE() << name << " not exported";
    return std::array<float, 3>{0, 0, 0};
  };
  EXPECT_GT(centre_of("liver")[2], centre_of("kidney_right")[2]);
  EXPECT_GT(centre_of("liver")[1], centre_of("kidney_right")[1]);
  EXPECT_LT(centre_of("kidney_right")[0], 0.0f);
  EXPECT_GT(centre_of("kidney_left")[0], 0.0f);
}

TEST(ExportGltf, JsonWithItsBin) {
  const std::string path = out_dir() + "/atlas.gltf";
  export_gltf(atlas(), path);
  std::ifstream f(path);
  const json doc = json::parse(f);  // JSON text, not GLB bytes
  ASSERT_EQ(doc["buffers"][0]["uri"], "atlas.bin");
  const std::vector<uint8_t> bin = read_bytes(out_dir() + "/atlas.bin");
  check_document(doc, bin);
  EXPECT_FALSE(fs::exists(path + ".tmp"));
}

TEST(ExportGltf, GlbStaysBinary) {
  const std::string path = out_dir() + "/atlas.glb";
  export_gltf(atlas(), path);
  const std::vector<uint8_t> b = read_bytes(path);
  ASSERT_GE(b.size(), 28u);
  uint32_t h[5];
  std::memcpy(h, b.data(), 20);
  EXPECT_EQ(h[0], 0x46546C67u);  // "glTF"
  EXPECT_EQ(h[1], 2u);
  EXPECT_EQ(h[2], b.size());
  EXPECT_EQ(h[4], 0x4E4F534Au);  // "JSON"
  ASSERT_EQ(h[3] % 4, 0u);
  const json doc = json::parse(std::string(b.begin() + 20, b.begin() + 20 + h[3]));
  EXPECT_FALSE(doc["buffers"][0].contains("uri"));
  uint32_t bh[2];
  std::memcpy(bh, b.data() + 20 + h[3], 8);
  EXPECT_EQ(bh[1], 0x004E4942u);  // "BIN"
  ASSERT_EQ(20 + h[3] + 8 + bh[0], b.size());
  check_document(doc, std::vector<uint8_t>(b.begin() + 28 + h[3], b.end()));
}

TEST(ExportGltf, RefusesOtherExtensions) {
  EXPECT_THROW(export_gltf(atlas(), out_dir() + "/atlas.obj"), InputError);
  EXPECT_FALSE(fs::exists(out_dir() + "/atlas.obj"));
}

}  // namespace
}  // namespace softatlas::pipeline
