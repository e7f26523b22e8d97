// `softatlas export SET -o atlas.glb|atlas.gltf`: glTF 2.0 that other engines take as is.
//
// Written directly (JSON + one binary buffer) rather than through assimp's exporter, so the file
// carries what an anatomy scene needs and nothing has to be fixed by hand after import:
//  - glTF's frame: metres, +Y up = superior, +Z front = anterior, hence +X = the patient's left
//    (RAS (x, y, z) mm -> glTF (-x, z, y) / 1000, a proper rotation: winding and normals keep);
//  - the scene centred at the origin: the centre of the organs' bounding box is subtracted; the
//    root node's `extras` give that offset and the formula back to patient coordinates;
//  - one node per organ whose `extras` hold name, label (TotalSegmentator id), fma, the material
//    model and whether it is rigid context (all organs, rigid ones included, are exported);
//  - one mesh (POSITION, NORMAL, uint32 indices) and one PBR material (the organ's colour) each.
// `.glb` is the binary container (12-byte header, JSON chunk, BIN chunk); `.gltf` is JSON with
// its buffer in NAME.bin beside it. Both are written to temporary files and renamed.
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "softatlas/io/organ_set.hpp"
#include "softatlas/io/output_folder.hpp"
#include "softatlas/pipeline/build.hpp"
#include "softatlas/sim/error.hpp"

namespace softatlas::pipeline {
namespace {

// RAS mm, relative to the centre -> glTF metres.
std::array<float, 3> to_gltf(const double* p, const std::array<double, 3>& centre) {
  return {static_cast<float>(-(p[0] - centre[0]) * 1e-3), static_cast<float>((p[2] - centre[2]) * 1e-3),
          static_cast<float>((p[1] - centre[1]) * 1e-3)};
}

void append(std::vector<uint8_t>& bin, const void* data, size_t bytes) {
  const auto* b = static_cast<const uint8_t*>(data);
  bin.insert(bin.end(), b, b + bytes);
  while (bin.size() % 4) bin.push_back(0);  // every view starts 4-byte aligned
}

// Whole or not at all (temp file + rename): a full disk or a read-only folder leaves nothing.
void write_file(const std::string& path, const std::string& a, const std::vector<uint8_t>& b = {}) {
  std::string bytes = a;
  bytes.append(reinterpret_cast<const char*>(b.data()), b.size());
  io::write_file_atomic(path, bytes);
}

}  // namespace

void export_gltf(const std::string& set_folder, const std::string& out_path) {
  namespace fs = std::filesystem;
  const std::string ext = fs::path(out_path).extension().string();
  if (ext != ".glb" && ext != ".gltf")
    throw InputError(out_path, "expected an output name ending in .glb (binary glTF) or .gltf (JSON + .bin)");
  const io::OrganSet set = io::read_organ_set(set_folder);
  if (set.organs.empty()) throw InputError(set_folder, "the organ set has no organs to export");

  std::array<double, 3> lo{std::numeric_limits<double>::max(), std::numeric_limits<double>::max(),
                           std::numeric_limits<double>::max()};
  std::array<double, 3> hi{-lo[0], -lo[1], -lo[2]};
  for (const io::OrganEntry& e : set.organs)
    for (size_t v = 0; v < e.mesh.vertex_count(); ++v)
      for (int k = 0; k < 3; ++k) {
        lo[k] = std::min(lo[k], e.mesh.vertices[3 * v + k]);
        hi[k] = std::max(hi[k], e.mesh.vertices[3 * v + k]);
      }
  const std::array<double, 3> centre{0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])};

  using nlohmann::json;
  std::vector<uint8_t> bin;
  json views = json::array(), accessors = json::array(), meshes = json::array(), materials = json::array(),
       nodes = json::array(), children = json::array();
  auto view = [&](const void* data, size_t bytes, int target) {
    const size_t offset = bin.size();
    append(bin, data, bytes);
    views.push_back({{"buffer", 0}, {"byteOffset", offset}, {"byteLength", bytes}, {"target", target}});
    return static_cast<int>(views.size()) - 1;
  };
  for (const io::OrganEntry& e : set.organs) {
    const size_t nv = e.mesh.vertex_count(), nf = e.mesh.face_count();
    std::vector<float> pos(3 * nv), nrm(3 * nv, 0.0f);
    std::array<float, 3> pmin{1e30f, 1e30f, 1e30f}, pmax{-1e30f, -1e30f, -1e30f};
    for (size_t v = 0; v < nv; ++v) {
      const auto p = to_gltf(&e.mesh.vertices[3 * v], centre);
      for (int k = 0; k < 3; ++k) {
        pos[3 * v + k] = p[k];
        pmin[k] = std::min(pmin[k], p[k]);
        pmax[k] = std::max(pmax[k], p[k]);
      }
    }
    std::vector<uint32_t> idx(3 * nf);
    for (size_t f = 0; f < nf; ++f) {
      for (int c = 0; c < 3; ++c) idx[3 * f + c] = static_cast<uint32_t>(e.mesh.faces[3 * f + c]);
      // Area-weighted vertex normals (the cross product's length is twice the area).
      const float* a = &pos[3 * idx[3 * f]];
      const float* b = &pos[3 * idx[3 * f + 1]];
      const float* c = &pos[3 * idx[3 * f + 2]];
      const float u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
      const float n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
      for (int k = 0; k < 3; ++k)
        for (int d = 0; d < 3; ++d) nrm[3 * idx[3 * f + k] + d] += n[d];
    }
    for (size_t v = 0; v < nv; ++v) {
      float* n = &nrm[3 * v];
      const float len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
      if (len > 0)
        for (int d = 0; d < 3; ++d) n[d] /= len;
      else
        n[1] = 1.0f;  // an unused vertex: any unit normal keeps validators quiet
    }
    const int vp = view(pos.data(), pos.size() * sizeof(float), 34962);
    const int vn = view(nrm.data(), nrm.size() * sizeof(float), 34962);
    const int vi = view(idx.data(), idx.size() * sizeof(uint32_t), 34963);
    const int base = static_cast<int>(accessors.size());
    accessors.push_back(
        {{"bufferView", vp}, {"componentType", 5126}, {"count", nv}, {"type", "VEC3"}, {"min", pmin}, {"max", pmax}});
    accessors.push_back({{"bufferView", vn}, {"componentType", 5126}, {"count", nv}, {"type", "VEC3"}});
    accessors.push_back({{"bufferView", vi}, {"componentType", 5125}, {"count", 3 * nf}, {"type", "SCALAR"}});
    const int m = static_cast<int>(materials.size());
    const bool rigid = e.material.model == "rigid" || (nv > 0 && e.fixed_vertices.size() == nv);
    materials.push_back({{"name", e.name},
                         {"pbrMetallicRoughness",
                          {{"baseColorFactor", {e.color[0], e.color[1], e.color[2], 1.0}},
                           {"metallicFactor", 0.0},
                           {"roughnessFactor", 0.6}}},
                         {"doubleSided", false}});
    meshes.push_back({{"name", e.name},
                      {"primitives", json::array({{{"attributes", {{"POSITION", base}, {"NORMAL", base + 1}}},
                                                   {"indices", base + 2},
                                                   {"material", m},
                                                   {"mode", 4}}})}});
    children.push_back(static_cast<int>(nodes.size()) + 1);  // node 0 is the root
    nodes.push_back({{"name", e.name},
                     {"mesh", static_cast<int>(meshes.size()) - 1},
                     {"extras",
                      {{"name", e.name},
                       {"label", e.label},
                       {"fma", e.fma},
                       {"model", e.material.model},
                       {"rigid", rigid},
                       {"vertices", nv},
                       {"faces", nf}}}});
  }
  json root_node = {{"name", "softatlas_organ_set"},
                    {"children", children},
                    {"extras",
                     {{"patient_offset_mm", centre},
                      {"patient_space", set.space},
                      {"to_patient", "RAS_mm = (-X, Z, Y) * 1000 + patient_offset_mm"},
                      {"bounds_mm", {{"min", lo}, {"max", hi}}},
                      {"source", set.provenance.count("source") ? set.provenance.at("source") : ""},
                      {"license", set.provenance.count("license") ? set.provenance.at("license") : ""}}}};
  nodes.insert(nodes.begin(), root_node);

  const bool glb = ext == ".glb";
  const fs::path bin_path = fs::path(out_path).replace_extension(".bin");
  json buffer = {{"byteLength", bin.size()}};
  if (!glb) buffer["uri"] = bin_path.filename().string();
  json doc = {{"asset",
               {{"version", "2.0"},
                {"generator", "SoftAtlas export (pipeline/src/export_gltf.cpp)"},
                {"copyright", set.provenance.count("license") ? set.provenance.at("license") : ""}}},
              {"scene", 0},
              {"scenes", json::array({{{"name", "organ set"}, {"nodes", {0}}}})},
              {"nodes", nodes},
              {"meshes", meshes},
              {"materials", materials},
              {"accessors", accessors},
              {"bufferViews", views},
              {"buffers", json::array({buffer})}};
  std::string text = doc.dump(glb ? -1 : 1);

  if (glb) {
    while (text.size() % 4) text.push_back(' ');  // JSON chunk padded with spaces
    const uint32_t total = 12 + 8 + static_cast<uint32_t>(text.size()) + 8 + static_cast<uint32_t>(bin.size());
    std::string head(28, '\0');
    const uint32_t words[7] = {0x46546C67u, 2u, total, static_cast<uint32_t>(text.size()), 0x4E4F534Au, 0, 0};
    std::memcpy(head.data(), words, 20);
    std::string bin_head(8, '\0');
    const uint32_t bw[2] = {static_cast<uint32_t>(bin.size()), 0x004E4942u};
    std::memcpy(bin_head.data(), bw, 8);
    write_file(out_path, head.substr(0, 20) + text + bin_head, bin);
    return;
  }
  // .gltf and its .bin: both written beside their targets first, moved into place together; an
  // error names the file asked for, not the staging one.
  const std::string tmp = out_path + ".partial", bin_tmp = bin_path.string() + ".partial";
  auto remove_partials = [&] {
    std::error_code ec;
    fs::remove(tmp, ec);
    fs::remove(bin_tmp, ec);
  };
  try {
    write_file(bin_tmp, "", bin);
    write_file(tmp, text + "\n");
    fs::rename(bin_tmp, bin_path);
    fs::rename(tmp, out_path);
  } catch (const fs::filesystem_error& e) {
    remove_partials();
    throw InputError(out_path, "cannot write: " + e.code().message());
  } catch (const InputError& e) {
    remove_partials();
    throw InputError("", io::name_target(io::name_target(e.what(), bin_tmp, bin_path.string()), tmp, out_path));
  }
}

}  // namespace softatlas::pipeline
