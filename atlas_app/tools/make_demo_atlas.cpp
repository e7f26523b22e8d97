// make_demo_atlas: builds data/atlas/ (the demo organ set) from the HuBMAP Visible Human Male
// reference organs (one body, CC BY 4.0).
//
//   make_demo_atlas HRA_VH_MALE_DIR OUT_SET [--voxel 1.0]
//
// Each organ of the HRA set is several named sub-meshes, most of them open surface patches
// (only the liver capsule is closed; kidney_l has a non-manifold edge). The project's pipeline
// closes them the way it closes a CT label: the patches are scan-converted into a binary mask
// (every triangle sampled finer than a voxel), closed morphologically (dilate, fill from
// outside, erode), then go through the pipeline's own stages: pipeline::label_surface (flying
// edges, smoothing) and pipeline::repair_and_remesh (CGAL, to the face budget), connections by
// pipeline::connect_organs, anchors by io::extreme_vertices, written by io::write_organ_set.
//
// Frame: HRA glTF is metres, +X patient left, +Y superior, +Z anterior (checked: spinal cord at
// z < 0, behind the pancreas; spleen at x > 0). RAS mm = (-1000 x, 1000 z, 1000 y), a rotation
// (det +1), so windings stay outward.
//
// Soft organs get `model: solid`; the pelvis (hip bones, sacrum with coccyx) is `model: rigid`.
// The sub-mesh names are kept as named regions (landmarks): each organ's `regions` in atlas.yaml
// and LICENSE.md's table (docs/organ-set.md, docs/lessons.md).
#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <deque>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "softatlas/io/mesh_io.hpp"
#include "softatlas/io/organ_set.hpp"
#include "softatlas/pipeline/connect.hpp"
#include "softatlas/pipeline/remesh.hpp"
#include "softatlas/pipeline/surface.hpp"
#include "softatlas/pipeline/topology.hpp"
#include "softatlas/pipeline/volume.hpp"

namespace {

using softatlas::io::TriMesh;

struct Patch {
  std::string name;  // sub-mesh name without the VH_M_ prefix
  TriMesh mesh;      // RAS mm
};

// Every sub-mesh of a GLB (no node transforms in this set: checked, every node is identity).
std::vector<Patch> read_glb(const std::string& path) {
  Assimp::Importer imp;
  const aiScene* sc = imp.ReadFile(path, aiProcess_Triangulate | aiProcess_JoinIdenticalVertices);
  if (!sc || !sc->HasMeshes()) throw std::runtime_error(path + ": " + imp.GetErrorString());
  std::vector<Patch> out;
  for (unsigned i = 0; i < sc->mNumMeshes; ++i) {
    const aiMesh* am = sc->mMeshes[i];
    Patch p;
    p.name = am->mName.C_Str();
    if (p.name.rfind("VH_M_", 0) == 0) p.name = p.name.substr(5);
    for (unsigned v = 0; v < am->mNumVertices; ++v) {
      const aiVector3D& q = am->mVertices[v];
      p.mesh.vertices.insert(p.mesh.vertices.end(), {-1000.0 * q.x, 1000.0 * q.z, 1000.0 * q.y});
    }
    for (unsigned f = 0; f < am->mNumFaces; ++f) {
      if (am->mFaces[f].mNumIndices != 3) continue;
      for (int k = 0; k < 3; ++k) p.mesh.faces.push_back(static_cast<int32_t>(am->mFaces[f].mIndices[k]));
    }
    out.push_back(std::move(p));
  }
  return out;
}

// Scan conversion of surface patches into a closed binary mask on an axis-aligned RAS grid.
softatlas::pipeline::Volume patches_to_mask(const std::vector<const Patch*>& patches, double voxel_mm,
                                            int close_radius) {
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  for (const Patch* p : patches)
    for (size_t i = 0; i < p->mesh.vertices.size(); ++i)
      lo[i % 3] = std::min(lo[i % 3], p->mesh.vertices[i]), hi[i % 3] = std::max(hi[i % 3], p->mesh.vertices[i]);
  const int margin = close_radius + 3;
  softatlas::pipeline::Volume vol;
  for (int c = 0; c < 3; ++c) {
    lo[c] -= margin * voxel_mm;
    vol.dims[c] = static_cast<int>(std::ceil((hi[c] + margin * voxel_mm - lo[c]) / voxel_mm)) + 1;
  }
  vol.ijk_to_ras = {voxel_mm, 0, 0, lo[0], 0, voxel_mm, 0, lo[1], 0, 0, voxel_mm, lo[2], 0, 0, 0, 1};
  vol.format = "nifti";
  const int nx = vol.dims[0], ny = vol.dims[1], nz = vol.dims[2];
  std::vector<uint8_t> m(static_cast<size_t>(nx) * ny * nz, 0);
  auto id = [&](int i, int j, int k) {
    return static_cast<size_t>(i) + static_cast<size_t>(nx) * (j + static_cast<size_t>(ny) * k);
  };
  for (const Patch* p : patches)
    for (size_t f = 0; f < p->mesh.face_count(); ++f) {
      const double* a = &p->mesh.vertices[3 * p->mesh.faces[3 * f]];
      const double* b = &p->mesh.vertices[3 * p->mesh.faces[3 * f + 1]];
      const double* c = &p->mesh.vertices[3 * p->mesh.faces[3 * f + 2]];
      double longest = 0;
      for (int e = 0; e < 3; ++e) {
        const double* u = e == 0 ? a : e == 1 ? b : c;
        const double* w = e == 0 ? b : e == 1 ? c : a;
        longest = std::max(longest, std::sqrt((u[0] - w[0]) * (u[0] - w[0]) + (u[1] - w[1]) * (u[1] - w[1]) +
                                              (u[2] - w[2]) * (u[2] - w[2])));
      }
      const int n = std::max(1, static_cast<int>(std::ceil(longest / (0.4 * voxel_mm))));
      for (int s = 0; s <= n; ++s)
        for (int t = 0; t <= n - s; ++t) {
          const double bs = double(s) / n, bt = double(t) / n, br = 1.0 - bs - bt;
          int q[3];
          for (int k = 0; k < 3; ++k)
            q[k] = static_cast<int>(std::lround((br * a[k] + bs * b[k] + bt * c[k] - lo[k]) / voxel_mm));
          m[id(q[0], q[1], q[2])] = 1;
        }
    }
  auto dilate = [&](std::vector<uint8_t>& g, uint8_t on) {  // 6-neighbour dilation of value `on`
    std::vector<uint8_t> src = g;
    for (int k = 1; k + 1 < nz; ++k)
      for (int j = 1; j + 1 < ny; ++j)
        for (int i = 1; i + 1 < nx; ++i) {
          const size_t x = id(i, j, k);
          if (src[x] == on) continue;
          if (src[x - 1] == on || src[x + 1] == on || src[x - nx] == on || src[x + nx] == on ||
              src[x - static_cast<size_t>(nx) * ny] == on || src[x + static_cast<size_t>(nx) * ny] == on)
            g[x] = on;
        }
  };
  for (int r = 0; r < close_radius; ++r) dilate(m, 1);
  // outside: flood fill from the grid's border through unmarked voxels (value 2)
  std::deque<size_t> queue;
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i)
        if ((i == 0 || j == 0 || k == 0 || i == nx - 1 || j == ny - 1 || k == nz - 1) && !m[id(i, j, k)]) {
          m[id(i, j, k)] = 2;
          queue.push_back(id(i, j, k));
        }
  while (!queue.empty()) {
    const size_t x = queue.front();
    queue.pop_front();
    const int i = static_cast<int>(x % nx), j = static_cast<int>((x / nx) % ny),
              k = static_cast<int>(x / (static_cast<size_t>(nx) * ny));
    const int nb[6][3] = {{i - 1, j, k}, {i + 1, j, k}, {i, j - 1, k}, {i, j + 1, k}, {i, j, k - 1}, {i, j, k + 1}};
    for (const auto& q : nb) {
      if (q[0] < 0 || q[1] < 0 || q[2] < 0 || q[0] >= nx || q[1] >= ny || q[2] >= nz) continue;
      const size_t y = id(q[0], q[1], q[2]);
      if (m[y] == 0) m[y] = 2, queue.push_back(y);
    }
  }
  for (int r = 0; r < close_radius; ++r) dilate(m, 2);  // erode the inside back by the same radius
  vol.values.resize(m.size());
  for (size_t x = 0; x < m.size(); ++x) vol.values[x] = m[x] == 2 ? 0.0f : 1.0f;
  return vol;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: make_demo_atlas HRA_VH_MALE_DIR OUT_SET [--voxel 1.0]\n");
    return 2;
  }
  const std::string src = argv[1], out_dir = argv[2];
  double voxel_mm = 1.0;
  if (argc >= 5 && std::string(argv[3]) == "--voxel") voxel_mm = std::stod(argv[4]);
  try {
    // name, file, sub-mesh filter ("" = all; "_L" / "_R" / "sacrum" select the pelvis parts),
    // TotalSegmentator label, FMA id, face budget, rigid, DOI
    struct In {
      const char* name;
      const char* file;
      const char* part;
      int label;
      const char* fma;
      int faces;
      bool rigid;
      const char* doi;
    };
    const In inputs[] = {
        {"heart", "VH_M_Heart.glb", "", 51, "FMA7088", 2400, false, "10.48539/HBM373.VSTV.568"},
        {"liver", "VH_M_Liver.glb", "", 5, "FMA7197", 3000, false, "10.48539/HBM677.HVRF.764"},
        {"spleen", "VH_M_Spleen.glb", "", 1, "FMA7196", 1200, false, "10.48539/HBM662.GMWC.569"},
        {"pancreas", "VH_M_Pancreas.glb", "", 7, "FMA7198", 1200, false, "10.48539/HBM992.BMVW.775"},
        {"kidney_left", "VH_M_Kidney_L.glb", "", 3, "FMA7205", 1400, false, "10.48539/HBM562.JGPS.244"},
        {"kidney_right", "VH_M_Kidney_R.glb", "", 2, "FMA7204", 1400, false, "10.48539/HBM272.ZVPQ.979"},
        {"spinal_cord", "VH_M_Spinal_Cord.glb", "", 79, "FMA7647", 1400, false, "10.48539/HBM366.MTJD.685"},
        {"hip_left", "VH_M_Pelvis.glb", "_L", 77, "FMA16587", 1500, true, "10.48539/HBM893.QGJK.978"},
        {"hip_right", "VH_M_Pelvis.glb", "_R", 78, "FMA16586", 1500, true, "10.48539/HBM893.QGJK.978"},
        {"sacrum", "VH_M_Pelvis.glb", "sacrum", 25, "FMA16202", 1200, true, "10.48539/HBM893.QGJK.978"},
    };
    softatlas::io::OrganSet set;
    set.units = "mm";
    set.space = "RAS";
    std::map<std::string, std::vector<Patch>> files;
    std::ostringstream regions;  // landmark table for LICENSE.md / provenance
    for (const In& in : inputs) {
      if (!files.count(in.file)) files[in.file] = read_glb(src + "/" + in.file);
      std::vector<const Patch*> parts;
      const std::string part = in.part;
      for (const Patch& p : files[in.file]) {
        const bool keep = part.empty()       ? true
                          : part == "sacrum" ? (p.name == "sacrum" || p.name == "coccyx")
                                             : (p.name.size() > 2 && p.name.compare(p.name.size() - 2, 2, part) == 0 &&
                                                p.name.find("compact") != std::string::npos);
        if (keep) parts.push_back(&p);
      }
      if (parts.empty()) throw std::runtime_error(std::string(in.file) + ": no sub-mesh for " + in.name);
      const softatlas::pipeline::Volume mask = patches_to_mask(parts, voxel_mm, 2);
      softatlas::pipeline::SurfaceOptions so;
      const auto surf = softatlas::pipeline::label_surface(mask, {1}, so, std::string(in.file) + ": " + in.name);
      softatlas::pipeline::RemeshOptions ro;
      ro.face_budget = in.faces;
      const auto rem = softatlas::pipeline::repair_and_remesh(surf.mesh, ro, std::string(in.file) + ": " + in.name);
      softatlas::io::OrganEntry e;
      e.name = in.name;
      e.label = in.label;
      e.fma = in.fma;
      e.color = softatlas::io::default_organ_color(in.name);
      e.mesh_file = std::string("organs/") + in.name + ".ply";
      e.mesh = rem.mesh;
      e.face_budget = in.faces;
      if (e.name == "spinal_cord") e.color = {0.93, 0.84, 0.50};
      if (in.rigid) {
        e.color = {0.89, 0.85, 0.76};  // bone
        e.material.model = "rigid";
        e.material.density_kg_m3 = 1900;  // cortical + trabecular bone
      } else {
        e.material.model = "solid";  // sim/solid.hpp; E = 4 kPa, nu = 0.49 (docs/physics.md)
        // Anchors: a supine body's organs rest on the posterior wall (RAS -y); the liver also
        // hangs from the diaphragm (+z), the spinal cord lies in its canal along its length.
        const std::array<double, 3> posterior{0, -1, 0}, superior{0, 0, 1};
        e.fixed_vertices = softatlas::io::extreme_vertices(e.mesh, posterior, e.name == "spinal_cord" ? 16 : 6,
                                                           e.name == "spinal_cord" ? 25.0 : 15.0);
        if (e.name == "liver" || e.name == "heart") {
          auto top = softatlas::io::extreme_vertices(e.mesh, superior, 6, 20.0);
          e.fixed_vertices.insert(e.fixed_vertices.end(), top.begin(), top.end());
        }
        // The cord is 10 mm across and 450 mm long: the thickness rule's 400 nodes (sim
        // solid_step.cpp) give it one 11.5 mm cell across, which did not restore after a 30 mm
        // pull (residual 8.9 mm); a budget of 1,500 gives 869 nodes, 6.5 mm cells (residual 0.5 mm).
        if (e.name == "spinal_cord") e.material.solid_nodes = 1500;
        std::sort(e.fixed_vertices.begin(), e.fixed_vertices.end());
        e.fixed_vertices.erase(std::unique(e.fixed_vertices.begin(), e.fixed_vertices.end()), e.fixed_vertices.end());
      }
      std::fprintf(stderr, "%-13s %2zu sub-meshes, mask %zu voxels, V %5zu F %5zu, %.1f mL, repairs:", in.name,
                   parts.size(), surf.mask_voxels, e.mesh.vertex_count(), e.mesh.face_count(),
                   softatlas::pipeline::inspect_surface(e.mesh).signed_volume_mm3 / 1000.0);
      for (const auto& r : rem.repairs) std::fprintf(stderr, " %s", r.c_str());
      std::fprintf(stderr, ", Hausdorff %.2f mm\n", rem.hausdorff_mm);
      // Named regions: each sub-mesh's vertex nearest to its centroid (a point on the source
      // surface, RAS mm), named without the organ ("gastric_impression_of_liver" ->
      // "gastric_impression", "hilum_of_kidney_L" -> "hilum").
      for (const Patch* p : parts) {
        double c[3] = {0, 0, 0};
        const size_t nv = p->mesh.vertex_count();
        for (size_t v = 0; v < nv; ++v)
          for (int k = 0; k < 3; ++k) c[k] += p->mesh.vertices[3 * v + k] / static_cast<double>(nv);
        size_t best = 0;
        double bd = 1e300;
        for (size_t v = 0; v < nv; ++v) {
          double d = 0;
          for (int k = 0; k < 3; ++k) d += (p->mesh.vertices[3 * v + k] - c[k]) * (p->mesh.vertices[3 * v + k] - c[k]);
          if (d < bd) bd = d, best = v;
        }
        std::string rname = p->name;
        for (const char* side : {"_L", "_R"})
          if (rname.size() > 2 && rname.compare(rname.size() - 2, 2, side) == 0) rname.resize(rname.size() - 2);
        for (const char* suffix :
             {"_of_the_pancreas", "_of_pancreas", "_of_liver", "_of_spleen", "_of_kidney", "_of_heart"}) {
          const std::string suf = suffix;
          if (rname.size() > suf.size() && rname.compare(rname.size() - suf.size(), suf.size(), suf) == 0)
            rname.resize(rname.size() - suf.size());
        }
        if (e.find_region(rname)) rname = p->name;  // keep names unique
        const double* q = &p->mesh.vertices[3 * best];
        e.regions.push_back(
            {rname, {std::round(q[0] * 10) / 10, std::round(q[1] * 10) / 10, std::round(q[2] * 10) / 10}});
        char buf[256];
        std::snprintf(buf, sizeof buf, "| %s | %s | %s | %.1f, %.1f, %.1f |\n", in.name, rname.c_str(), p->name.c_str(),
                      q[0], q[1], q[2]);
        regions << buf;
      }
      set.organs.push_back(std::move(e));
    }
    // Connections: the pipeline's proximity springs (default pairs and any pair closer than
    // distance_mm). The reference organs were segmented one by one from the same body, so
    // touching organs are a few mm apart or overlap: 6 mm finds the contacts.
    softatlas::pipeline::ConnectOptions co;
    co.distance_mm = 6.0;
    co.spacing_mm = 10.0;
    co.stiffness = 5.0;
    std::vector<softatlas::pipeline::PairReport> pairs;
    set.connections = softatlas::pipeline::connect_organs(set.organs, co, &pairs);
    // springs between two bones can do nothing (sim::compile leaves them out too)
    auto rigid = [&](const std::string& n) { return set.find(n)->material.model == "rigid"; };
    set.connections.erase(
        std::remove_if(set.connections.begin(), set.connections.end(),
                       [&](const softatlas::io::Connection& c) { return rigid(c.organ_a) && rigid(c.organ_b); }),
        set.connections.end());
    for (const auto& p : pairs)
      if (p.springs && !(rigid(p.organ_a) && rigid(p.organ_b)))
        std::fprintf(stderr, "connections %s-%s: %zu (closest %.1f mm)\n", p.organ_a.c_str(), p.organ_b.c_str(),
                     p.springs, p.closest_mm);
    set.provenance["source"] =
        "HuBMAP CCF 3D Reference Object Library v1.3, Visible Human Male (hubmapconsortium/ccf-releases v1.3/models)";
    set.provenance["license"] =
        "CC BY 4.0, Kristen Browne, Heidi Schlehlein et al., HuBMAP CCF 3D Reference Object Library";
    set.provenance["generator"] = "atlas_app/tools/make_demo_atlas.cpp";
    set.provenance["transform"] =
        "glTF metres (+X left, +Y superior, +Z anterior) to RAS mm: (x, y, z) -> (-1000 x, 1000 z, 1000 y)";
    char vox[32];
    std::snprintf(vox, sizeof vox, "%g", voxel_mm);
    set.provenance["repair"] = std::string("sub-meshes scan-converted to a ") + vox +
                               " mm mask, closed (2 voxels), pipeline::label_surface, pipeline::repair_and_remesh";
    std::string doi_lines;
    for (const In& in : inputs)
      doi_lines += std::string("| ") + in.name + " | " + in.file + " | https://doi.org/" + in.doi + " |\n";
    const std::string license =
        "# Demo organ set: license and attribution\n\n"
        "The meshes in `organs/` are derived from the HuBMAP Human Reference Atlas, Visible Human Male\n"
        "reference organs:\n\n"
        "> Kristen Browne, Heidi Schlehlein et al., *HuBMAP CCF 3D Reference Object Library*, v1.3,\n"
        "> licensed under Creative Commons Attribution 4.0 International (CC BY 4.0),\n"
        "> https://creativecommons.org/licenses/by/4.0/ . Source: hubmapconsortium/ccf-releases, v1.3/models.\n\n"
        "| structure | source file | DOI |\n| --- | --- | --- |\n" +
        doi_lines +
        "\nChanges: converted from glTF metres (+X left, +Y superior, +Z anterior) to RAS millimetres;\n"
        "each organ's sub-meshes scan-converted to a mask, closed and remeshed to a closed surface\n"
        "(SoftAtlas pipeline); the pelvis split into left and right hip bones (compact bone of ilium,\n"
        "ischium, pubis) and sacrum with coccyx; anchors and connection springs added. Generated by\n"
        "atlas_app/tools/make_demo_atlas.cpp. This derived data set is distributed under CC BY 4.0.\n\n"
        "## Named regions (landmarks)\n\n"
        "One per source sub-mesh: its vertex nearest to its centroid, RAS mm, stored in atlas.yaml as the\n"
        "organ's `regions` (a lesson grasps there with `region: NAME`, docs/lessons.md).\n\n"
        "| structure | region | source sub-mesh | point (R, A, S) mm |\n| --- | --- | --- | --- |\n" +
        regions.str();
    size_t faces = 0;
    for (auto& o : set.organs) faces += o.mesh.face_count();
    std::fprintf(stderr, "total faces %zu, connections %zu\n", faces, set.connections.size());
    softatlas::io::write_organ_set(set, out_dir, {{"LICENSE.md", license}}, true);
    std::fprintf(stderr, "wrote %s\n", out_dir.c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "make_demo_atlas: %s\n", e.what());
    return 1;
  }
  return 0;
}
