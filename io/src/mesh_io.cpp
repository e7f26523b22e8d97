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
#include <map>
#include <sstream>

#include "softatlas/sim/error.hpp"

namespace softatlas::io {
namespace fs = std::filesystem;

std::string printable_text(const std::string& s, size_t max_len) {
  std::string out;
  for (unsigned char c : s) {
    if (out.size() >= max_len) {
      out += "...";
      break;
    }
    out += (c >= 32 && c < 127) ? static_cast<char>(c) : '?';
  }
  return out;
}

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
  const std::string tmp = (dir / ("." + target.filename().string() + ".tmp." + std::to_string(::getpid()))).string();
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
  if (mesh.vertices.size() / 3 > static_cast<size_t>(kMaxMeshElements) ||
      mesh.faces.size() / 3 > static_cast<size_t>(kMaxMeshElements))
    throw InputError(where, "more than 50,000,000 vertices or faces");
  for (size_t i = 0; i < mesh.vertices.size(); ++i) {
    if (!std::isfinite(mesh.vertices[i]))
      throw InputError(where, "non-finite coordinate (NaN or inf) at vertex " + std::to_string(i / 3));
    if (std::abs(mesh.vertices[i]) > kMaxCoordinate)
      throw InputError(where, "vertex " + std::to_string(i / 3) + " lies " + std::to_string(mesh.vertices[i]) +
                                  " from the origin (more than 10 m): a corrupt coordinate");
  }
  const int64_t nv = static_cast<int64_t>(mesh.vertex_count());
  for (size_t f = 0; f < mesh.faces.size(); ++f)
    if (mesh.faces[f] < 0 || mesh.faces[f] >= nv)
      throw InputError(where, "face " + std::to_string(f / 3) + " uses vertex index " + std::to_string(mesh.faces[f]) +
                                  ", expected 0.." + std::to_string(nv - 1));
}

namespace {

// Scans an OBJ for what assimp would quietly repair or reject with a vague message (or trust):
// NaN or far-off coordinates, out-of-range or malformed indices, polygons. Gives file:line errors.
void precheck_obj(const std::string& path, const std::string& text, bool triangles_only) {
  std::istringstream in(text);
  std::string line;
  long line_no = 0, nv = 0, nf = 0, nvt = 0, nvn = 0;
  // A whole index token: i, i/t, i//n or i/t/n, each a nonzero integer within its list.
  auto index_ok = [](const std::string& t, long count, long* value) {
    if (t.empty() || t.size() > 20) return false;
    char* end = nullptr;
    errno = 0;
    const long idx = std::strtol(t.c_str(), &end, 10);
    if (end != t.c_str() + t.size() || errno == ERANGE || idx == 0) return false;
    const long abs_idx = idx < 0 ? count + 1 + idx : idx;
    *value = idx;
    return abs_idx >= 1 && abs_idx <= count;
  };
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const std::string where = path + ":" + std::to_string(line_no);
    std::istringstream ls(line);
    std::string kw;
    ls >> kw;
    if (kw == "v" || kw == "vt" || kw == "vn") {
      const int need = kw == "vt" ? 1 : 3;
      for (int c = 0; c < need; ++c) {
        std::string tok;
        if (!(ls >> tok)) throw InputError(where, "expected '" + kw + "' and " + std::to_string(need) + " numbers");
        char* end = nullptr;
        const double v = std::strtod(tok.c_str(), &end);
        if (end == tok.c_str() || *end != '\0')
          throw InputError(where, "expected a number, got '" + printable_text(tok) + "'");
        if (!std::isfinite(v)) throw InputError(where, "non-finite coordinate '" + printable_text(tok) + "'");
        if (kw == "v" && std::abs(v) > kMaxCoordinate)
          throw InputError(where, "coordinate " + printable_text(tok) + " is more than 10 m from the origin");
      }
      (kw == "v" ? nv : kw == "vt" ? nvt : nvn)++;
    } else if (kw == "f") {
      std::string tok;
      int count = 0;
      while (ls >> tok) {
        std::string part[3];
        int parts = 0;
        size_t start = 0;
        while (parts < 3) {
          const size_t slash = tok.find('/', start);
          part[parts++] = tok.substr(start, slash == std::string::npos ? std::string::npos : slash - start);
          if (slash == std::string::npos) break;
          start = slash + 1;
          if (parts == 3) throw InputError(where, "bad face index '" + printable_text(tok) + "'");
        }
        long idx = 0;
        if (!index_ok(part[0], nv, &idx)) {
          if (idx != 0 && part[0].find_first_not_of("-0123456789") == std::string::npos)
            throw InputError(where, "face index " + std::to_string(idx) + " outside 1.." + std::to_string(nv) +
                                        " (vertices defined so far)");
          throw InputError(where, "bad face index '" + printable_text(tok) + "'");
        }
        long other = 0;
        if ((parts > 1 && !part[1].empty() && !index_ok(part[1], nvt, &other)) ||
            (parts > 2 && !index_ok(part[2], nvn, &other)))
          throw InputError(where, "bad texture or normal index in '" + printable_text(tok) + "'");
        ++count;
      }
      if (count < 3) throw InputError(where, "face with fewer than 3 vertices");
      ++nf;
      if (triangles_only && count != 3)
        throw InputError(where, "face with " + std::to_string(count) + " vertices: expected triangles only");
    }
  }
  if (nf == 0) throw InputError(path, "empty mesh: no faces (" + std::to_string(nv) + " vertices)");
}

// Little-endian binary helpers for STL.
uint32_t le32(const unsigned char* p) {
  return p[0] | (p[1] << 8) | (p[2] << 16) | (static_cast<uint32_t>(p[3]) << 24);
}
float lef32(const unsigned char* p) {
  const uint32_t u = le32(p);
  float f;
  std::memcpy(&f, &u, 4);
  return f;
}

// Merges corners at identical positions (STL stores three corners per facet), in order of first
// appearance, as assimp's JoinIdenticalVertices does.
void add_corner(TriMesh& m, std::map<std::array<double, 3>, int32_t>& seen, const std::array<double, 3>& p, bool weld,
                const std::string& path) {
  for (double x : p)  // also keeps NaN out of the map's ordering
    if (!std::isfinite(x))
      throw InputError(path, "non-finite coordinate (NaN or inf) in facet " + std::to_string(m.faces.size() / 3));
  if (weld) {
    const auto it = seen.find(p);
    if (it != seen.end()) {
      m.faces.push_back(it->second);
      return;
    }
  }
  const int32_t id = static_cast<int32_t>(m.vertex_count());
  if (weld) seen.emplace(p, id);
  m.vertices.insert(m.vertices.end(), p.begin(), p.end());
  m.faces.push_back(id);
}

// STL, binary or ASCII, read here: the facet count of a binary file is checked against the file
// size before anything is allocated.
TriMesh read_stl(const std::string& path, const std::string& data, bool weld) {
  TriMesh m;
  std::map<std::array<double, 3>, int32_t> seen;
  const bool ascii_magic = data.compare(0, 5, "solid") == 0;
  bool binary = data.size() >= 84;
  uint32_t n = 0;
  if (binary) {
    n = le32(reinterpret_cast<const unsigned char*>(data.data()) + 80);
    binary = 84 + 50 * static_cast<uint64_t>(n) == data.size();
  }
  if (binary) {
    if (n == 0) throw InputError(path, "empty mesh: binary STL with 0 facets");
    if (n > kMaxMeshElements) throw InputError(path, "more than 50,000,000 facets");
    m.vertices.reserve(static_cast<size_t>(n) * 3);
    m.faces.reserve(static_cast<size_t>(n) * 3);
    for (uint32_t f = 0; f < n; ++f) {
      const auto* p = reinterpret_cast<const unsigned char*>(data.data()) + 84 + 50 * static_cast<size_t>(f) + 12;
      for (int c = 0; c < 3; ++c)
        add_corner(m, seen, {lef32(p + 12 * c), lef32(p + 12 * c + 4), lef32(p + 12 * c + 8)}, weld, path);
    }
    return m;
  }
  if (!ascii_magic) {
    const uint64_t promised = data.size() >= 84 ? 84 + 50 * static_cast<uint64_t>(n) : 84;
    throw InputError(path, "not an STL file: binary STL of " + std::to_string(data.size()) +
                               " bytes, its facet count needs " + std::to_string(promised) + " (truncated or corrupt)");
  }
  std::istringstream in(data);
  std::string line;
  long line_no = 0, corners = 0;
  while (std::getline(in, line)) {
    ++line_no;
    std::istringstream ls(line);
    std::string kw;
    ls >> kw;
    if (kw != "vertex") continue;
    std::array<double, 3> p{};
    for (double& x : p) {
      std::string tok;
      char* end = nullptr;
      if (!(ls >> tok) || (x = std::strtod(tok.c_str(), &end), end == tok.c_str() || *end != '\0'))
        throw InputError(path + ":" + std::to_string(line_no), "expected 'vertex x y z'");
    }
    add_corner(m, seen, p, weld, path);
    ++corners;
  }
  if (corners % 3 != 0) throw InputError(path, "ASCII STL with a facet of fewer than 3 vertices (truncated?)");
  return m;
}

// OFF: "OFF", then "#V #F #E", vertices, faces "n i j k". Counts are checked against the file
// size before anything is allocated; polygons are split into fans unless triangles_only.
TriMesh read_off(const std::string& path, const std::string& data, bool triangles_only) {
  std::istringstream in(data);
  std::string tok;
  auto next = [&](const char* what) -> std::string {
    while (in >> tok) {
      if (tok[0] != '#') return tok;
      std::string rest;
      std::getline(in, rest);  // comment to the end of the line
    }
    throw InputError(path, std::string("file ends before ") + what + " (truncated)");
  };
  auto integer = [&](const char* what, long long lo, long long hi) {
    const std::string t = next(what);
    char* end = nullptr;
    errno = 0;
    const long long v = std::strtoll(t.c_str(), &end, 10);
    if (end == t.c_str() || *end != '\0' || errno == ERANGE || v < lo || v > hi)
      throw InputError(path, std::string("expected ") + what + " (an integer in " + std::to_string(lo) + ".." +
                                 std::to_string(hi) + "), got '" + printable_text(t) + "'");
    return v;
  };
  const std::string magic = next("the OFF magic");
  if (magic != "OFF") throw InputError(path, "not an OFF file (expected 'OFF' first)");
  // Each vertex needs at least 6 bytes of text ("0 0 0\n"), each face 8 ("3 0 1 2\n").
  const long long nv = integer("the vertex count", 0, static_cast<long long>(data.size() / 6));
  const long long nf = integer("the face count", 1, static_cast<long long>(data.size() / 8));
  integer("the edge count", 0, 1LL << 40);
  TriMesh m;
  m.vertices.reserve(static_cast<size_t>(nv) * 3);
  for (long long i = 0; i < nv * 3; ++i) {
    const std::string t = next("the vertices");
    char* end = nullptr;
    const double x = std::strtod(t.c_str(), &end);
    if (end == t.c_str() || *end != '\0')
      throw InputError(path, "expected a coordinate, got '" + printable_text(t) + "'");
    m.vertices.push_back(x);
  }
  for (long long f = 0; f < nf; ++f) {
    const long long k = integer("a face's vertex count", 3, 1000);
    if (triangles_only && k != 3)
      throw InputError(
          path, "face " + std::to_string(f) + " has " + std::to_string(k) + " vertices: expected triangles only");
    std::vector<int32_t> ids;
    for (long long c = 0; c < k; ++c) ids.push_back(static_cast<int32_t>(integer("a vertex index", 0, nv - 1)));
    for (long long c = 1; c + 1 < k; ++c) m.faces.insert(m.faces.end(), {ids[0], ids[c], ids[c + 1]});
  }
  return m;
}

}  // namespace

TriMesh read_mesh(const std::string& path, const ReadMeshOptions& options) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError(path, "no such file");
  if (fs::is_directory(path, ec)) throw InputError(path, "is a folder, expected a mesh file");
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".ply") return read_ply(path);
  if (ext == ".stl" || ext == ".off") {
    TriMesh m = ext == ".stl" ? read_stl(path, read_text_file(path), options.weld)
                              : read_off(path, read_text_file(path), options.triangles_only);
    if (m.faces.empty()) throw InputError(path, "no triangles in the file (empty mesh)");
    validate_mesh(m, path);
    return m;
  }
  if (ext == ".obj") precheck_obj(path, read_text_file(path), options.triangles_only);

  Assimp::Importer importer;
  // Keep points and lines out; no triangulation (polygons are an error, checked below).
  importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
  unsigned flags = aiProcess_SortByPType;
  if (options.weld) flags |= aiProcess_JoinIdenticalVertices;
  const aiScene* scene = importer.ReadFile(path, flags);
  if (!scene || !scene->mRootNode)
    throw InputError(path, std::string("cannot read mesh: ") + printable_text(importer.GetErrorString()));
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
            throw InputError(path, "face " + std::to_string(f) + " has " + std::to_string(face.mNumIndices) +
                                       " vertices: expected triangles only");
          for (unsigned k = 1; k + 1 < face.mNumIndices; ++k)
            out.faces.insert(out.faces.end(), {base + int32_t(face.mIndices[0]), base + int32_t(face.mIndices[k]),
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
    case PlyType::i8:
    case PlyType::u8:
      return 1;
    case PlyType::i16:
    case PlyType::u16:
      return 2;
    case PlyType::i32:
    case PlyType::u32:
    case PlyType::f32:
      return 4;
    case PlyType::f64:
      return 8;
    default:
      return 0;
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
    pos = std::min(e + 1, data.size());  // a last line without '\n' ends at the end, not past it
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
        throw fail("unknown PLY format '" + printable_text(format) + "'");
    } else if (kw == "element") {
      PlyElement el;
      std::string count_text;
      ls >> el.name >> count_text;
      char* end = nullptr;
      errno = 0;
      const long long n = std::strtoll(count_text.c_str(), &end, 10);
      if (count_text.empty() || *end != '\0' || errno == ERANGE || n < 0)
        throw fail("bad element count '" + printable_text(count_text) + "'");
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
        if (p.type == PlyType::none) throw fail("unknown property type '" + printable_text(t) + "'");
      }
      elements.back().props.push_back(p);
    } else {
      throw fail("unexpected header line '" + printable_text(line) + "'");
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
      case PlyType::i8: {
        int8_t v;
        std::memcpy(&v, b, 1);
        return v;
      }
      case PlyType::u8: {
        uint8_t v;
        std::memcpy(&v, b, 1);
        return v;
      }
      case PlyType::i16: {
        int16_t v;
        std::memcpy(&v, b, 2);
        return v;
      }
      case PlyType::u16: {
        uint16_t v;
        std::memcpy(&v, b, 2);
        return v;
      }
      case PlyType::i32: {
        int32_t v;
        std::memcpy(&v, b, 4);
        return v;
      }
      case PlyType::u32: {
        uint32_t v;
        std::memcpy(&v, b, 4);
        return v;
      }
      case PlyType::f32: {
        float v;
        std::memcpy(&v, b, 4);
        return v;
      }
      case PlyType::f64: {
        double v;
        std::memcpy(&v, b, 8);
        return v;
      }
      default:
        return 0;
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
    if (end == tok.c_str() || *end != '\0')
      throw InputError(path, "expected a number in the body, got '" + printable_text(tok) + "'");
    return v;
  };

  // Counts against the file size before anything is allocated: every element needs at least
  // its fixed-size properties (binary) or two characters per property (ASCII).
  {
    double need = 0;
    for (const PlyElement& el : elements) {
      if (el.count > 0 && el.props.empty())
        throw InputError(path, "element '" + printable_text(el.name) + "' has no properties");
      if (el.count > static_cast<size_t>(kMaxMeshElements))
        throw InputError(path, "element '" + printable_text(el.name) + "' count " + std::to_string(el.count) +
                                   " is more than 50,000,000");
      double per = 0;
      for (const PlyProp& pr : el.props)
        per += ascii ? 2.0 : static_cast<double>(ply_size(pr.list ? pr.count_type : pr.type));
      need += per * static_cast<double>(el.count);
    }
    if (need > static_cast<double>(data.size() - std::min(pos, data.size())))
      throw InputError(path, "truncated: the element counts need at least " +
                                 std::to_string(static_cast<size_t>(need)) + " bytes of data, the file has " +
                                 std::to_string(data.size() - std::min(pos, data.size())));
  }
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
    if (is_vertex && (ix < 0 || iy < 0 || iz < 0)) throw InputError(path, "vertex element without x, y, z properties");
    if (is_face && ifaces < 0) throw InputError(path, "face element without vertex_indices");
    for (size_t i = 0; i < el.count; ++i) {
      double xyz[3] = {0, 0, 0};
      for (size_t p = 0; p < el.props.size(); ++p) {
        const PlyProp& pr = el.props[p];
        if (pr.list) {
          const double cnt = read_val(pr.count_type);
          if (!(cnt >= 0) || cnt > 1e6 || cnt != std::floor(cnt))
            throw InputError(path, "bad list length in element " + printable_text(el.name));
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

std::vector<int32_t> extreme_vertices(const TriMesh& m, const std::array<double, 3>& dir, int count,
                                      double spacing_mm) {
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
      for (int k = 0; k < 3; ++k)
        d2 += (m.vertices[3 * i + k] - m.vertices[3 * j + k]) * (m.vertices[3 * i + k] - m.vertices[3 * j + k]);
      far = far && d2 >= spacing_mm * spacing_mm;
    }
    if (far) out.push_back(i);
  }
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace softatlas::io
