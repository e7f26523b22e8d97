// Triangle-mesh files in and out: OBJ and glTF/GLB through assimp (OBJ pre-checked line by
// line), PLY, STL and OFF by our own readers that check counts against the file size first.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace softatlas::io {

// A triangle surface as flat arrays (libigl convention, row-major):
//   vertices  #V*3 doubles (x0 y0 z0 x1 ...), in the file's units (mm for organ sets)
//   faces     #F*3 vertex indices, counter-clockwise seen from outside for closed organs
struct TriMesh {
  std::vector<double> vertices;
  std::vector<int32_t> faces;
  size_t vertex_count() const { return vertices.size() / 3; }
  size_t face_count() const { return faces.size() / 3; }
};

struct ReadMeshOptions {
  // Merge vertices at identical positions (OBJ/STL store corners per face).
  bool weld = true;
  // Accept only triangles; polygons are an InputError (never triangulated silently).
  bool triangles_only = true;
};

// Reads a mesh file. Every mesh in the file is appended into one TriMesh. Throws InputError naming
// the file for: missing/unreadable file, a format assimp cannot parse, no faces, non-triangle
// faces, non-finite coordinates, out-of-range indices.
TriMesh read_mesh(const std::string& path, const ReadMeshOptions& options = {});

// PLY (ascii or binary little/big endian; vertex x y z as float or double, other fixed-size
// vertex properties skipped; face lists of any integer type). Read by our own parser, not
// assimp, because organ sets address vertices by their index in the file (connections,
// fixed vertices) and assimp's loaders may reorder vertices.
TriMesh read_ply(const std::string& path);

// The `count` vertices furthest along `dir`, spread out: a vertex is taken only if it is at
// least `spacing_mm` from those already taken. Sorted by index. (Anchors: the posterior-most
// vertices of an organ rest on the body wall.)
std::vector<int32_t> extreme_vertices(const TriMesh& m, const std::array<double, 3>& dir, int count, double spacing_mm);

// Checks the invariants read_mesh guarantees (finite coordinates, indices in range, triangles,
// at least one face); `where` names the source in the error.
void validate_mesh(const TriMesh& mesh, const std::string& where);

// Writes binary little-endian PLY with double vertex coordinates (float32 would round CT-world
// millimetres far from the origin), atomically: temp file + rename.
void write_ply(const TriMesh& mesh, const std::string& path);

// Sane limits of a mesh read from a file (organ sets are in mm): a coordinate beyond 10 m or
// more elements than this is a corrupt file, refused before any geometry code sees it (a single
// far-off vertex makes isotropic remeshing run for minutes).
constexpr double kMaxCoordinate = 1e4;
constexpr long long kMaxMeshElements = 50000000;

// `s` with every byte outside printable ASCII replaced by '?', cut to `max_len` characters
// ("..." appended): for quoting a file's text in an error message.
std::string printable_text(const std::string& s, size_t max_len = 80);

// Writes `text` to `path` atomically (temporary file in the same folder, then rename).
void write_file_atomic(const std::string& path, const std::string& text);

// Reads a whole text file; InputError if it cannot be read.
std::string read_text_file(const std::string& path);

}  // namespace softatlas::io
