// `softatlas export SET -o atlas.glb`: binary glTF 2.0 written by assimp's glb2 exporter. One
// node per organ carrying its name, one material per organ with its colour (base colour and
// diffuse), per-vertex normals. glTF is metres and +Y up: the root node scales mm -> m and turns
// RAS (+Z superior) into +Y up, so the vertex data stay the organ set's own numbers.
#include <assimp/Exporter.hpp>
#include <assimp/material.h>
#include <assimp/scene.h>

#include <cmath>
#include <filesystem>
#include <memory>

#include "softatlas/io/organ_set.hpp"
#include "softatlas/pipeline/build.hpp"
#include "softatlas/sim/error.hpp"

namespace softatlas::pipeline {

void export_gltf(const std::string& set_folder, const std::string& glb_path) {
  const io::OrganSet set = io::read_organ_set(set_folder);
  if (set.organs.empty()) throw InputError(set_folder, "the organ set has no organs to export");
  const unsigned n = static_cast<unsigned>(set.organs.size());
  auto scene = std::make_unique<aiScene>();
  scene->mRootNode = new aiNode("softatlas_organ_set");
  // Row-major aiMatrix4x4: x' = x, y' = z, z' = -y, all times 0.001 (mm -> m).
  scene->mRootNode->mTransformation = aiMatrix4x4(0.001f, 0, 0, 0, 0, 0, 0.001f, 0, 0, -0.001f, 0, 0, 0, 0, 0, 1);
  scene->mNumMaterials = n;
  scene->mMaterials = new aiMaterial*[n];
  scene->mNumMeshes = n;
  scene->mMeshes = new aiMesh*[n];
  scene->mRootNode->mNumChildren = n;
  scene->mRootNode->mChildren = new aiNode*[n];
  for (unsigned i = 0; i < n; ++i) {
    const io::OrganEntry& e = set.organs[i];
    auto* mat = new aiMaterial();
    const aiString name(e.name);
    mat->AddProperty(&name, AI_MATKEY_NAME);
    const aiColor4D colour(e.color[0], e.color[1], e.color[2], 1.0f);
    mat->AddProperty(&colour, 1, AI_MATKEY_COLOR_DIFFUSE);
    mat->AddProperty(&colour, 1, AI_MATKEY_BASE_COLOR);
    scene->mMaterials[i] = mat;

    auto* mesh = new aiMesh();
    mesh->mName = aiString(e.name);
    mesh->mMaterialIndex = i;
    mesh->mPrimitiveTypes = aiPrimitiveType_TRIANGLE;
    const size_t nv = e.mesh.vertex_count(), nf = e.mesh.face_count();
    mesh->mNumVertices = static_cast<unsigned>(nv);
    mesh->mVertices = new aiVector3D[nv];
    mesh->mNormals = new aiVector3D[nv];
    for (size_t v = 0; v < nv; ++v) {
      mesh->mVertices[v] = aiVector3D(static_cast<float>(e.mesh.vertices[3 * v]), static_cast<float>(e.mesh.vertices[3 * v + 1]),
                                      static_cast<float>(e.mesh.vertices[3 * v + 2]));
      mesh->mNormals[v] = aiVector3D(0, 0, 0);
    }
    mesh->mNumFaces = static_cast<unsigned>(nf);
    mesh->mFaces = new aiFace[nf];
    for (size_t f = 0; f < nf; ++f) {
      aiFace& face = mesh->mFaces[f];
      face.mNumIndices = 3;
      face.mIndices = new unsigned[3];
      for (int c = 0; c < 3; ++c) face.mIndices[c] = static_cast<unsigned>(e.mesh.faces[3 * f + c]);
      // Area-weighted vertex normals (the cross product's length is twice the area).
      const aiVector3D& a = mesh->mVertices[face.mIndices[0]];
      const aiVector3D nrm = (mesh->mVertices[face.mIndices[1]] - a) ^ (mesh->mVertices[face.mIndices[2]] - a);
      for (int c = 0; c < 3; ++c) mesh->mNormals[face.mIndices[c]] += nrm;
    }
    for (size_t v = 0; v < nv; ++v) {
      const float len = mesh->mNormals[v].Length();
      if (len > 0) mesh->mNormals[v] /= len;
    }
    scene->mMeshes[i] = mesh;

    auto* node = new aiNode(e.name);
    node->mParent = scene->mRootNode;
    node->mNumMeshes = 1;
    node->mMeshes = new unsigned[1]{i};
    scene->mRootNode->mChildren[i] = node;
  }
  const std::string tmp = glb_path + ".tmp.glb";
  Assimp::Exporter exporter;
  if (exporter.Export(scene.get(), "glb2", tmp) != AI_SUCCESS) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw InputError(glb_path, std::string("cannot write glTF: ") + exporter.GetErrorString());
  }
  std::filesystem::rename(tmp, glb_path);
}

}  // namespace softatlas::pipeline
