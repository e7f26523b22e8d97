// Mesh files through assimp. We read without triangulation so that polygons are reported, not
// silently split, and check everything the core relies on.
#include "softatlas/io/mesh_io.hpp"

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "softatlas/sim/error.hpp"

namespace softatlas::io {
namespace fs = std::filesystem;

std::string read_text_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw InputError(path, "cannot read");
  return ss.str();
}

void write_file_atomic(const std::string& path, const std::string& text) {
  const fs::path target(path);
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  const std::string tmp = (dir / ("." + target.filename().string() + ".tmp." +
                                  std::to_string(::getpid()))).string();
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw InputError(path, std::string("cannot write: ") + std::strerror(errno));
    out.write(text.data(), static_cast<std::streamsize>(text.size()));
    out.flush();
    if (!out) {
      std::error_code ec;
      fs::remove(tmp, ec);
      throw InputError(path, "write failed (disk full?)");
    }
  }
  std::error_code ec;
  fs::rename(tmp, target, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw InputError(path, "cannot rename the temporary file into place: " + ec.message());
  }
}

void validate_mesh(const TriMesh& mesh, const std::string& where) {
  if (mesh.vertices.size() % 3 != 0) throw InputError(where, "vertex array is not #V x 3");
  if (mesh.faces.size() % 3 != 0) throw InputError(where, "face array is not #F x 3 (triangles)");
  if (mesh.faces.empty()) throw InputError(where, "empty mesh: no faces");
  for (size_t i = 0; i < mesh.vertices.size(); ++i)
    if (!std::isfinite(mesh.vertices[i]))
      throw InputError(where, "non-finite coordinate (NaN or inf) at vertex " + std::to_string(i / 3));
  const int64_t nv = static_cast<int64_t>(mesh.vertex_count());
  for (size_t f = 0; f < mesh.faces.size(); ++f)
    if (mesh.faces[f] < 0 || mesh.faces[f] >= nv)
      throw InputError(where, "face " + std::to_string(f / 3) + " uses vertex index " +
                                  std::to_string(mesh.faces[f]) + ", expected 0.." +
                                  std::to_string(nv - 1));
}

namespace {

// Scans an OBJ for what assimp would quietly repair or reject with a vague message: NaN
// coordinates, out-of-range indices, polygons. Gives file:line errors.
void precheck_obj(const std::string& path, const std::string& text, bool triangles_only) {
  std::istringstream in(text);
  std::string line;
  long line_no = 0, nv = 0, nf = 0;
  while (std::getline(in, line)) {
    ++line_no;
    const std::string where = path + ":" + std::to_string(line_no);
    if (line.size() > 2 && line[0] == 'v' && (line[1] == ' ' || line[1] == '\t')) {
      std::istringstream ls(line.substr(2));
      for (int c = 0; c < 3; ++c) {
        std::string tok;
        if (!(ls >> tok)) throw InputError(where, "expected 'v x y z'");
        char* end = nullptr;
        const double v = std::strtod(tok.c_str(), &end);
        if (end == tok.c_str() || *end != '\0') throw InputError(where, "expected a number, got '" + tok + "'");
        if (!std::isfinite(v)) throw InputError(where, "non-finite coordinate '" + tok + "'");
      }
      ++nv;
    } else if (line.size() > 2 && line[0] == 'f' && (line[1] == ' ' || line[1] == '\t')) {
      std::istringstream ls(line.substr(2));
      std::string tok;
      int count = 0;
      while (ls >> tok) {
        char* end = nullptr;
        const long idx = std::strtol(tok.c_str(), &end, 10);
        if (end == tok.c_str() || idx == 0) throw InputError(where, "bad face index '" + tok + "'");
        const long abs_idx = idx < 0 ? nv + 1 + idx : idx;
        if (abs_idx < 1 || abs_idx > nv)
          throw InputError(where, "face index " + std::to_string(idx) + " outside 1.." +
                                      std::to_string(nv) + " (vertices defined so far)");
        ++count;
      }
      if (count < 3) throw InputError(where, "face with fewer than 3 vertices");
      ++nf;
      if (triangles_only && count != 3)
        throw InputError(where, "face with " + std::to_string(count) +
                                    " vertices: expected triangles only");
    }
  }
  if (nf == 0) throw InputError(path, "empty mesh: no faces (" + std::to_string(nv) + " vertices)");
}

}  // namespace

TriMesh read_mesh(const std::string& path, const ReadMeshOptions& options) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError(path, "no such file");
  if (fs::is_directory(path, ec)) throw InputError(path, "is a folder, expected a mesh file");
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".obj") precheck_obj(path, read_text_file(path), options.triangles_only);
  if (ext == ".ply") return read_ply(path);

  Assimp::Importer importer;
  // Keep points and lines out; no triangulation (polygons are an error, checked below).
  importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
  unsigned flags = aiProcess_SortByPType;
  if (options.weld) flags |= aiProcess_JoinIdenticalVertices;
  const aiScene* scene = importer.ReadFile(path, flags);
  if (!scene || !scene->mRootNode)
    throw InputError(path, std::string("cannot read mesh: ") + importer.GetErrorString());
  TriMesh out;
  // Walk the node tree so that node transforms (glTF) are applied.
  std::vector<std::pair<const aiNode*, aiMatrix4x4>> stack{{scene->mRootNode, aiMatrix4x4()}};
  while (!stack.empty()) {
    auto [node, parent] = stack.back();
    stack.pop_back();
    const aiMatrix4x4 T = parent * node->mTransformation;
    for (unsigned mi = 0; mi < node->mNumMeshes; ++mi) {
      const aiMesh* mesh = scene->mMeshes[node->mMeshes[mi]];
      const int32_t base = static_cast<int32_t>(out.vertex_count());
      for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
        const aiVector3D p = T * mesh->mVertices[v];
        out.vertices.insert(out.vertices.end(), {double(p.x), double(p.y), double(p.z)});
      }
      for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
        const aiFace& face = mesh->mFaces[f];
        if (face.mNumIndices != 3) {
          if (options.triangles_only)
            throw InputError(path, "face " + std::to_string(f) + " has " +
                                       std::to_string(face.mNumIndices) +
                                       " vertices: expected triangles only");
          for (unsigned k = 1; k + 1 < face.mNumIndices; ++k)
            out.faces.insert(out.faces.end(), {base + int32_t(face.mIndices[0]),
                                               base + int32_t(face.mIndices[k]),
                                               base + int32_t(face.mIndices[k + 1])});
          continue;
        }
        for (int c = 0; c < 3; ++c) out.faces.push_back(base + static_cast<int32_t>(face.mIndices[c]));
      }
    }
    for (unsigned c = 0; c < node->mNumChildren; ++c) stack.push_back({node->mChildren[c], T});
  }
  if (out.faces.empty()) throw InputError(path, "no triangles in the file (empty mesh)");
  validate_mesh(out, path);
  return out;
}

void write_ply(const TriMesh& mesh, const std::string& path) {
  validate_mesh(mesh, path);
  std::ostringstream os(std::ios::binary);
  os << "ply\nformat binary_little_endian 1.0\ncomment SoftAtlas organ surface (mm, RAS)\n"
     << "element vertex " << mesh.vertex_count() << "\nproperty double x\nproperty double y\n"
     << "property double z\nelement face " << mesh.face_count()
     << "\nproperty list uchar int vertex_indices\nend_header\n";
  os.write(reinterpret_cast<const char*>(mesh.vertices.data()),
           static_cast<std::streamsize>(mesh.vertices.size() * sizeof(double)));
  for (size_t f = 0; f < mesh.face_count(); ++f) {
    const unsigned char three = 3;
    os.write(reinterpret_cast<const char*>(&three), 1);
    os.write(reinterpret_cast<const char*>(&mesh.faces[3 * f]), 3 * sizeof(int32_t));
  }
  write_file_atomic(path, os.str());
}

}  // namespace softatlas::io

namespace softatlas::io {
namespace {

enum class PlyType { i8, u8, i16, u16, i32, u32, f32, f64, none };

PlyType ply_type(const std::string& t) {
  if (t == "char" || t == "int8") return PlyType::i8;
  if (t == "uchar" || t == "uint8") return PlyType::u8;
  if (t == "short" || t == "int16") return PlyType::i16;
  if (t == "ushort" || t == "uint16") return PlyType::u16;
  if (t == "int" || t == "int32") return PlyType::i32;
  if (t == "uint" || t == "uint32") return PlyType::u32;
  if (t == "float" || t == "float32") return PlyType::f32;
  if (t == "double" || t == "float64") return PlyType::f64;
  return PlyType::none;
}

size_t ply_size(PlyType t) {
  switch (t) {
    case PlyType::i8: case PlyType::u8: return 1;
    case PlyType::i16: case PlyType::u16: return 2;
    case PlyType::i32: case PlyType::u32: case PlyType::f32: return 4;
    case PlyType::f64: return 8;
    default: return 0;
  }
}

struct PlyProp {
  std::string name;
  PlyType type = PlyType::none;
  bool list = false;
  PlyType count_type = PlyType::none;
};

struct PlyElement {
  std::string name;
  size_t count = 0;
  std::vector<PlyProp> props;
};

}  // namespace

TriMesh read_ply(const std::string& path) {
  const std::string data = read_text_file(path);
  size_t pos = 0;
  long line_no = 0;
  auto next_line = [&](std::string& line) {
    if (pos >= data.size()) return false;
    size_t e = data.find('\n', pos);
    if (e == std::string::npos) e = data.size();
    line = data.substr(pos, e - pos);
    if (!line.empty() && line.back() == '\r') line.pop_back();
    pos = e + 1;
    ++line_no;
    return true;
  };
  auto fail = [&](const std::string& what) -> InputError {
    return InputError(path + ":" + std::to_string(line_no), what);
  };
  std::string line;
  if (!next_line(line) || line != "ply") throw InputError(path, "not a PLY file (no 'ply' magic)");
  std::string format;
  std::vector<PlyElement> elements;
  while (true) {
    if (!next_line(line)) throw fail("header ends before 'end_header'");
    std::istringstream ls(line);
    std::string kw;
    ls >> kw;
    if (kw == "end_header") break;
    if (kw == "comment" || kw == "obj_info" || kw.empty()) continue;
    if (kw == "format") {
      ls >> format;
      if (format != "ascii" && format != "binary_little_endian" && format != "binary_big_endian")
        throw fail("unknown PLY format '" + format + "'");
    } else if (kw == "element") {
      PlyElement el;
      long long n = -1;
      ls >> el.name >> n;
      if (n < 0) throw fail("bad element count");
      el.count = static_cast<size_t>(n);
      elements.push_back(el);
    } else if (kw == "property") {
      if (elements.empty()) throw fail("property before any element");
      PlyProp p;
      std::string t;
      ls >> t;
      if (t == "list") {
        std::string ct, it;
        ls >> ct >> it >> p.name;
        p.list = true;
        p.count_type = ply_type(ct);
        p.type = ply_type(it);
        if (p.count_type == PlyType::none || p.type == PlyType::none) throw fail("bad list property types");
      } else {
        p.type = ply_type(t);
        ls >> p.name;
        if (p.type == PlyType::none) throw fail("unknown property type '" + t + "'");
      }
      elements.back().props.push_back(p);
    } else {
      throw fail("unexpected header line '" + line + "'");
    }
  }
  if (format.empty()) throw InputError(path, "PLY header has no format line");
  const bool ascii = format == "ascii";
  const bool swap = format == "binary_big_endian";

  auto read_bin = [&](PlyType t) -> double {
    const size_t n = ply_size(t);
    if (pos + n > data.size()) throw InputError(path, "file ends inside the binary body (truncated)");
    unsigned char b[8];
    std::memcpy(b, data.data() + pos, n);
    pos += n;
    if (swap) std::reverse(b, b + n);
    switch (t) {
      case PlyType::i8: { int8_t v; std::memcpy(&v, b, 1); return v; }
      case PlyType::u8: { uint8_t v; std::memcpy(&v, b, 1); return v; }
      case PlyType::i16: { int16_t v; std::memcpy(&v, b, 2); return v; }
      case PlyType::u16: { uint16_t v; std::memcpy(&v, b, 2); return v; }
      case PlyType::i32: { int32_t v; std::memcpy(&v, b, 4); return v; }
      case PlyType::u32: { uint32_t v; std::memcpy(&v, b, 4); return v; }
      case PlyType::f32: { float v; std::memcpy(&v, b, 4); return v; }
      case PlyType::f64: { double v; std::memcpy(&v, b, 8); return v; }
      default: return 0;
    }
  };
  std::istringstream ascii_in;
  if (ascii) ascii_in.str(data.substr(pos));
  auto read_val = [&](PlyType t) -> double {
    if (!ascii) return read_bin(t);
    std::string tok;
    if (!(ascii_in >> tok)) throw InputError(path, "file ends inside the ASCII body (truncated)");
    char* end = nullptr;
    const double v = std::strtod(tok.c_str(), &end);
    if (end == tok.c_str()) throw InputError(path, "expected a number in the body, got '" + tok + "'");
    return v;
  };

  TriMesh mesh;
  for (const PlyElement& el : elements) {
    const bool is_vertex = el.name == "vertex", is_face = el.name == "face";
    int ix = -1, iy = -1, iz = -1, ifaces = -1;
    for (size_t p = 0; p < el.props.size(); ++p) {
      if (el.props[p].name == "x") ix = static_cast<int>(p);
      if (el.props[p].name == "y") iy = static_cast<int>(p);
      if (el.props[p].name == "z") iz = static_cast<int>(p);
      if (el.props[p].list && (el.props[p].name == "vertex_indices" || el.props[p].name == "vertex_index"))
        ifaces = static_cast<int>(p);
    }
    if (is_vertex && (ix < 0 || iy < 0 || iz < 0))
      throw InputError(path, "vertex element without x, y, z properties");
    if (is_face && ifaces < 0) throw InputError(path, "face element without vertex_indices");
    for (size_t i = 0; i < el.count; ++i) {
      double xyz[3] = {0, 0, 0};
      for (size_t p = 0; p < el.props.size(); ++p) {
        const PlyProp& pr = el.props[p];
        if (pr.list) {
          const double cnt = read_val(pr.count_type);
          if (!(cnt >= 0) || cnt > 1e6) throw InputError(path, "bad list length in element " + el.name);
          const size_t n = static_cast<size_t>(cnt);
          if (is_face && static_cast<int>(p) == ifaces) {
            if (n != 3)
              throw InputError(path, "face " + std::to_string(i) + " has " + std::to_string(n) +
                                         " vertices: expected triangles only");
            for (size_t k = 0; k < 3; ++k) {
              const double idx = read_val(pr.type);
              mesh.faces.push_back(idx >= 0 && idx < 2147483647.0 ? static_cast<int32_t>(idx) : -1);
            }
          } else {
            for (size_t k = 0; k < n; ++k) read_val(pr.type);
          }
        } else {
          const double v = read_val(pr.type);
          if (is_vertex) {
            if (static_cast<int>(p) == ix) xyz[0] = v;
            if (static_cast<int>(p) == iy) xyz[1] = v;
            if (static_cast<int>(p) == iz) xyz[2] = v;
          }
        }
      }
      if (is_vertex) mesh.vertices.insert(mesh.vertices.end(), xyz, xyz + 3);
    }
  }
  validate_mesh(mesh, path);
  return mesh;
}

std::vector<int32_t> extreme_vertices(const TriMesh& m, const std::array<double, 3>& dir, int count, double spacing_mm) {
  std::vector<int32_t> order(m.vertex_count());
  for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int32_t>(i);
  auto score = [&](int32_t i) {
    return m.vertices[3 * i] * dir[0] + m.vertices[3 * i + 1] * dir[1] + m.vertices[3 * i + 2] * dir[2];
  };
  std::sort(order.begin(), order.end(), [&](int32_t a, int32_t b) { return score(a) > score(b); });
  std::vector<int32_t> out;
  for (int32_t i : order) {
    if (static_cast<int>(out.size()) >= count) break;
    bool far = true;
    for (int32_t j : out) {
      double d2 = 0;
      for (int k = 0; k < 3; ++k) d2 += (m.vertices[3 * i + k] - m.vertices[3 * j + k]) * (m.vertices[3 * i + k] - m.vertices[3 * j + k]);
      far = far && d2 >= spacing_mm * spacing_mm;
    }
    if (far) out.push_back(i);
  }
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace softatlas::io
