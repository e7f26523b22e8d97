// Mesh files: real data in, bad files out with one clear error naming the file.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "softatlas/io/mesh_io.hpp"
#include "softatlas/sim/error.hpp"

namespace softatlas {
namespace {
namespace fs = std::filesystem;

std::string shared(const std::string& rel) { return std::string(SOFTATLAS_SHARED_DATA) + "/" + rel; }

std::string write_tmp(const std::string& name, const std::string& text) {
  const fs::path dir = fs::temp_directory_path() / "softatlas_io_test";
  fs::create_directories(dir);
  const std::string p = (dir / name).string();
  std::ofstream(p) << text;
  return p;
}

std::string error_of(const std::string& path) {
  try {
    io::read_mesh(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(MeshIo, ReadsSharedMeshes) {
  const io::TriMesh liver = io::read_mesh(shared("meshes/sofa/liver-smooth.obj"));
  EXPECT_EQ(liver.vertex_count(), 2194u);
  EXPECT_EQ(liver.face_count(), 4384u);
  const io::TriMesh stomach = io::read_mesh(shared("meshes/bodyparts3d/FMA7148_Stomach.obj"));
  EXPECT_EQ(stomach.vertex_count(), 4694u);
  EXPECT_EQ(stomach.face_count(), 9384u);
}

TEST(MeshIo, PlyRoundTripKeepsVertexOrderAndDoubles) {
  io::TriMesh m;
  m.vertices = {249.51234567891, -61.5, -804.5, 250.0, -61.0, -804.0, 249.0, -60.0, -803.0, 251, -62, -805};
  m.faces = {0, 1, 2, 0, 2, 3, 0, 3, 1, 1, 3, 2};
  const std::string p = (fs::temp_directory_path() / "softatlas_roundtrip.ply").string();
  io::write_ply(m, p);
  const io::TriMesh r = io::read_mesh(p);
  EXPECT_EQ(r.vertices, m.vertices);
  EXPECT_EQ(r.faces, m.faces);
}

TEST(MeshIo, BadFilesGiveOneLineNamingTheFile) {
  EXPECT_NE(error_of("/nonexistent/liver.obj").find("/nonexistent/liver.obj: no such file"), std::string::npos);
  const std::string empty = write_tmp("empty.obj", "# nothing\n");
  EXPECT_NE(error_of(empty).find(empty), std::string::npos);
  EXPECT_NE(error_of(empty).find("empty mesh"), std::string::npos) << error_of(empty);
  const std::string quad = write_tmp("quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n");
  EXPECT_NE(error_of(quad).find("quad.obj:5: face with 4 vertices: expected triangles only"), std::string::npos) << error_of(quad);
  const std::string nan = write_tmp("nan.obj", "v 0 0 0\nv nan 0 0\nv 1 1 0\nf 1 2 3\n");
  EXPECT_NE(error_of(nan).find("nan.obj:2: non-finite coordinate"), std::string::npos) << error_of(nan);
  const std::string range = write_tmp("range.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 7\n");
  EXPECT_NE(error_of(range).find("range.obj:4: face index 7 outside 1..3"), std::string::npos) << error_of(range);
  const std::string junk = write_tmp("junk.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\nabc");
  EXPECT_NE(error_of(junk).find("truncated"), std::string::npos) << error_of(junk);
}

}  // namespace
}  // namespace softatlas
