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
  EXPECT_NE(error_of(quad).find("quad.obj:5: face with 4 vertices: expected triangles only"), std::string::npos)
      << error_of(quad);
  const std::string nan = write_tmp("nan.obj", "v 0 0 0\nv nan 0 0\nv 1 1 0\nf 1 2 3\n");
  EXPECT_NE(error_of(nan).find("nan.obj:2: non-finite coordinate"), std::string::npos) << error_of(nan);
  const std::string range = write_tmp("range.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 7\n");
  EXPECT_NE(error_of(range).find("range.obj:4: face index 7 outside 1..3"), std::string::npos) << error_of(range);
  const std::string junk =
      write_tmp("junk.ply",
                "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty "
                "float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\nabc");
  EXPECT_NE(error_of(junk).find("truncated"), std::string::npos) << error_of(junk);
}

// Counts read from a file are checked against its size before anything is allocated, far-off
// and non-finite coordinates are refused, STL/OFF are read by our own readers (issue 17).
TEST(MeshIo, CountsAndCoordinatesAreCheckedBeforeAllocating) {
  auto binary = [](const std::string& name, uint32_t count, size_t facets) {
    std::string b(80, ' ');
    b.append(reinterpret_cast<const char*>(&count), 4);
    for (size_t f = 0; f < facets; ++f) {
      float v[12] = {0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 1, 0};
      b.append(reinterpret_cast<const char*>(v), 48);
      b.append(2, '\0');
    }
    const fs::path dir = fs::temp_directory_path() / "softatlas_io_test";
    fs::create_directories(dir);
    const std::string p = (dir / name).string();
    std::ofstream(p, std::ios::binary) << b;
    return p;
  };
  const std::string ok_stl = binary("one.stl", 1, 1);
  EXPECT_EQ(io::read_mesh(ok_stl).face_count(), 1u);
  EXPECT_EQ(io::read_mesh(ok_stl).vertex_count(), 3u);
  const std::string lying = binary("lying.stl", 4000000000u, 1);
  EXPECT_NE(error_of(lying).find("lying.stl: not an STL file"), std::string::npos) << error_of(lying);
  const std::string ascii_stl = write_tmp("a.stl",
                                          "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
                                          "vertex 0 1 0\nendloop\nendfacet\nendsolid x\n");
  EXPECT_EQ(io::read_mesh(ascii_stl).face_count(), 1u);
  const std::string nan_stl = write_tmp("nan.stl",
                                        "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex nan 0 0\n"
                                        "vertex 0 1 0\nendloop\nendfacet\nendsolid x\n");
  EXPECT_NE(error_of(nan_stl).find("non-finite"), std::string::npos) << error_of(nan_stl);
  const std::string off =
      write_tmp("t.off", "OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 1 2 3\n3 0 3 2\n");
  EXPECT_EQ(io::read_mesh(off).face_count(), 4u);
  const std::string off_huge = write_tmp("huge.off", "OFF\n4000000000 4 0\n0 0 0\n");
  EXPECT_NE(error_of(off_huge).find("vertex count"), std::string::npos) << error_of(off_huge);
  const std::string off_idx = write_tmp("idx.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 9\n");
  EXPECT_NE(error_of(off_idx).find("vertex index"), std::string::npos) << error_of(off_idx);
  const std::string ply_huge =
      write_tmp("huge.ply",
                "ply\nformat binary_little_endian 1.0\nelement vertex 2000000000\nproperty float x\n"
                "property float y\nproperty float z\nelement face 1\n"
                "property list uchar int vertex_indices\nend_header\nabc");
  EXPECT_NE(error_of(ply_huge).find("huge.ply"), std::string::npos) << error_of(ply_huge);
  const std::string ply_empty_el =
      write_tmp("noprop.ply", "ply\nformat ascii 1.0\nelement junk 999999999999\nend_header\n");
  EXPECT_NE(error_of(ply_empty_el).find("no properties"), std::string::npos) << error_of(ply_empty_el);
  const std::string ply_count = write_tmp("count.ply", "ply\nformat ascii 1.0\nelement vertex 3abc\nend_header\n");
  EXPECT_NE(error_of(ply_count).find("bad element count"), std::string::npos) << error_of(ply_count);
  // One far-off vertex (liver_1000.obj with z = -2147483649) made isotropic remeshing run for minutes.
  const std::string far = write_tmp("far.obj", "v 0 0 0\nv 1 0 0\nv 0 1 -2147483649\nf 1 2 3\n");
  EXPECT_NE(error_of(far).find("far.obj:3: coordinate -2147483649 is more than 10 m"), std::string::npos)
      << error_of(far);
  const std::string bad_idx = write_tmp("slash.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/x 2 3\n");
  EXPECT_NE(error_of(bad_idx).find("slash.obj:4: bad"), std::string::npos) << error_of(bad_idx);
  const std::string binary_text = write_tmp("bin.obj", std::string("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 \x01\xff\n"));
  EXPECT_NE(error_of(binary_text)
                .find("'?"
                      "?'"),
            std::string::npos)
      << "raw bytes echoed: " << error_of(binary_text);
}

}  // namespace
}  // namespace softatlas
