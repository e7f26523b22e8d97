// Stage 1, read. Voxels come from VTK readers (NIfTI, NRRD, MetaImage) or GDCM (DICOM, JPEG 2000
// included); the image-to-world transform is taken from the file's own header fields so that
// world coordinates are RAS millimetres exactly as the NIfTI sform/qform (or the DICOM/ITK LPS
// geometry, negated in x and y) maps voxels.
#include <openssl/evp.h>
#include <vtkCallbackCommand.h>
#include <vtkCommand.h>
#include <vtkDataArray.h>
#include <vtkType.h>
#include <vtkImageData.h>
#include <vtkImageReader2.h>
#include <vtkMatrix4x4.h>
#include <vtkMetaImageReader.h>
#include <vtkNIFTIImageHeader.h>
#include <vtkNIFTIImageReader.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkSmartPointer.h>
#include <zlib.h>

#include <gdcmImage.h>
#include <gdcmImageReader.h>
#include <gdcmPixelFormat.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>

#include "softatlas/io/mesh_io.hpp"
#include "softatlas/pipeline/volume.hpp"
#include "softatlas/sim/error.hpp"

namespace fs = std::filesystem;

namespace softatlas::pipeline {
namespace {

using Mat4 = std::array<double, 16>;

Mat4 identity4() { return {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}; }

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// Collects VTK error messages instead of printing them, so a broken file becomes one InputError.
struct VtkErrors {
  std::string first;
  static void callback(vtkObject*, unsigned long, void* client, void* call) {
    auto* self = static_cast<VtkErrors*>(client);
    if (self->first.empty() && call) self->first = static_cast<const char*>(call);
  }
};

std::string one_line(std::string s) {
  for (char& c : s)
    if (c == '\n' || c == '\r') c = ' ';
  while (!s.empty() && s.back() == ' ') s.pop_back();
  // VTK messages start with "ERROR: In file.cxx, line N\nvtkClass (0x...): text"; keep the text.
  const auto p = s.rfind("): ");
  if (p != std::string::npos) s = s.substr(p + 3);
  return s;
}

// Runs a VTK image reader, copies the scalars (first component) as float.
void read_vtk_voxels(vtkImageReader2* reader, const std::string& path, Volume* out,
                     std::array<double, 3>* spacing, std::array<double, 3>* origin) {
  VtkErrors errors;
  vtkNew<vtkCallbackCommand> cb;
  cb->SetCallback(&VtkErrors::callback);
  cb->SetClientData(&errors);
  reader->AddObserver(vtkCommand::ErrorEvent, cb);
  reader->GetExecutive();  // make sure the executive exists so its errors reach the observer
  reader->SetFileName(path.c_str());
  reader->Update();
  vtkImageData* image = reader->GetOutput();
  const unsigned long code = reader->GetErrorCode();
  vtkDataArray* scalars = image ? image->GetPointData()->GetScalars() : nullptr;
  int dims[3] = {0, 0, 0};
  if (image) image->GetDimensions(dims);
  const size_t n = static_cast<size_t>(dims[0]) * dims[1] * dims[2];
  if (!errors.first.empty() || code != 0 || !scalars || n == 0 ||
      static_cast<size_t>(scalars->GetNumberOfTuples()) != n) {
    std::string why = errors.first.empty() ? "no voxel data could be read"
                                           : one_line(errors.first);
    throw InputError(path, "unreadable or truncated volume (" + why + ")");
  }
  out->dims = {dims[0], dims[1], dims[2]};
  out->values.resize(n);
  const int nc = scalars->GetNumberOfComponents();
  void* raw = scalars->GetVoidPointer(0);
  auto copy = [&](auto* p) {
    for (size_t i = 0; i < n; ++i) out->values[i] = static_cast<float>(p[i * nc]);
  };
  switch (scalars->GetDataType()) {
    case VTK_UNSIGNED_CHAR: copy(static_cast<unsigned char*>(raw)); break;
    case VTK_SIGNED_CHAR: copy(static_cast<signed char*>(raw)); break;
    case VTK_CHAR: copy(static_cast<char*>(raw)); break;
    case VTK_SHORT: copy(static_cast<short*>(raw)); break;
    case VTK_UNSIGNED_SHORT: copy(static_cast<unsigned short*>(raw)); break;
    case VTK_INT: copy(static_cast<int*>(raw)); break;
    case VTK_UNSIGNED_INT: copy(static_cast<unsigned int*>(raw)); break;
    case VTK_FLOAT: copy(static_cast<float*>(raw)); break;
    case VTK_DOUBLE: copy(static_cast<double*>(raw)); break;
    default:
      for (size_t i = 0; i < n; ++i) out->values[i] = static_cast<float>(scalars->GetComponent(static_cast<vtkIdType>(i), 0));
  }
  double sp[3], org[3];
  image->GetSpacing(sp);
  image->GetOrigin(org);
  *spacing = {sp[0], sp[1], sp[2]};
  *origin = {org[0], org[1], org[2]};
}

// A .gz NIfTI whose stream ends early is reported by VTK only sometimes; check the stream
// length against the header independently so that truncation is never silent.
void check_nifti_length(const std::string& path) {
  gzFile f = gzopen(path.c_str(), "rb");
  if (!f) throw InputError(path, "cannot open file");
  unsigned char hdr[352];
  const int got = gzread(f, hdr, sizeof(hdr));
  if (got < 348) {
    gzclose(f);
    throw InputError(path, "truncated NIfTI header (" + std::to_string(std::max(got, 0)) +
                               " bytes, expected at least 348)");
  }
  int32_t sizeof_hdr;
  std::memcpy(&sizeof_hdr, hdr, 4);
  if (sizeof_hdr != 348) {
    gzclose(f);
    return;  // NIfTI-2 or byte-swapped: leave the checks to VTK
  }
  int16_t dim[8], bitpix;
  float vox_offset;
  std::memcpy(dim, hdr + 40, 16);
  std::memcpy(&bitpix, hdr + 72, 2);
  std::memcpy(&vox_offset, hdr + 108, 4);
  size_t voxels = 1;
  for (int d = 1; d <= std::min<int>(dim[0], 7); ++d) voxels *= static_cast<size_t>(std::max<int>(dim[d], 1));
  const size_t expected = static_cast<size_t>(vox_offset) + voxels * static_cast<size_t>(bitpix / 8);
  // Fast path: a complete gzip member ends with ISIZE, the uncompressed length mod 2^32
  // (RFC 1952). When it matches (or the file is plain), skip decompressing everything twice.
  {
    std::ifstream raw(path, std::ios::binary | std::ios::ate);
    const std::streamoff size = raw.tellg();
    unsigned char magic[2] = {0, 0};
    raw.seekg(0);
    raw.read(reinterpret_cast<char*>(magic), 2);
    const bool is_gz = magic[0] == 0x1f && magic[1] == 0x8b;
    if (!is_gz) {
      gzclose(f);
      if (static_cast<size_t>(size) < expected)
        throw InputError(path, "truncated volume: " + std::to_string(size) + " bytes, header needs " +
                                   std::to_string(expected));
      return;
    }
    if (size > 18) {
      unsigned char tail[4];
      raw.seekg(size - 4);
      raw.read(reinterpret_cast<char*>(tail), 4);
      const uint32_t isize = tail[0] | (tail[1] << 8) | (tail[2] << 16) | (static_cast<uint32_t>(tail[3]) << 24);
      if (isize == static_cast<uint32_t>(expected & 0xffffffffu)) {
        gzclose(f);
        return;
      }
    }
  }
  // Skip through the stream to count its bytes.
  std::vector<char> buf(1 << 20);
  size_t total = static_cast<size_t>(got);
  int r;
  while ((r = gzread(f, buf.data(), static_cast<unsigned>(buf.size()))) > 0) total += static_cast<size_t>(r);
  int err = 0;
  const char* zmsg = gzerror(f, &err);
  const std::string msg = zmsg && *zmsg ? zmsg : "zlib error";  // zlib owns zmsg: copy before gzclose
  gzclose(f);
  if (r < 0 || (err != Z_OK && err != Z_STREAM_END))
    throw InputError(path, "corrupt compressed stream (" + msg + ")");
  if (total < expected)
    throw InputError(path, "truncated volume: " + std::to_string(total) + " bytes, header needs " +
                               std::to_string(expected));
}

// Label names from the header extensions of a NIfTI-1 file: a Caret/CIFTI XML extension with
// <Label Key="N" ...><![CDATA[name]]></Label> entries (TotalSegmentator's multi-label maps;
// ecode 0 or 30). Other extensions are skipped; a malformed extension list names the file.
std::map<int, std::string> read_nifti_label_names(const std::string& path) {
  std::map<int, std::string> names;
  gzFile f = gzopen(path.c_str(), "rb");
  if (!f) return names;
  unsigned char hdr[352];
  const int got = gzread(f, hdr, sizeof(hdr));
  auto i32 = [](const unsigned char* b, bool swap) {
    uint32_t u;
    std::memcpy(&u, b, 4);
    if (swap) u = __builtin_bswap32(u);
    return static_cast<int32_t>(u);
  };
  int32_t size = got == 352 ? i32(hdr, false) : 0;
  const bool swap = size != 348;
  if (swap) size = got == 352 ? i32(hdr, true) : 0;
  if (size != 348 || hdr[348] == 0) {  // not NIfTI-1, or no extension flag
    gzclose(f);
    return names;
  }
  float vox_offset_f;
  uint32_t vo;
  std::memcpy(&vo, hdr + 108, 4);
  if (swap) vo = __builtin_bswap32(vo);
  std::memcpy(&vox_offset_f, &vo, 4);
  const long vox_offset = static_cast<long>(vox_offset_f);
  long pos = 352;
  while (pos + 8 <= vox_offset) {
    unsigned char eh[8];
    if (gzread(f, eh, 8) != 8) break;
    const int32_t esize = i32(eh, swap), ecode = i32(eh + 4, swap);
    if (esize < 8 || esize % 16 != 0 || pos + esize > vox_offset) {
      gzclose(f);
      throw InputError(path, "corrupt NIfTI header extension (size " + std::to_string(esize) + " at byte " +
                                 std::to_string(pos) + ")");
    }
    std::string content(static_cast<size_t>(esize - 8), '\0');
    if (gzread(f, content.data(), static_cast<unsigned>(content.size())) != static_cast<int>(content.size())) break;
    pos += esize;
    if ((ecode != 0 && ecode != 30) || content.find("<LabelTable>") == std::string::npos) continue;
    static const std::regex label(R"re(<Label\s+Key="(-?\d+)"[^>]*>\s*(?:<!\[CDATA\[([^\]]*)\]\]>|([^<]*))\s*</Label>)re");
    for (auto it = std::sregex_iterator(content.begin(), content.end(), label); it != std::sregex_iterator(); ++it) {
      const int key = std::stoi((*it)[1].str());
      std::string name = (*it)[2].matched ? (*it)[2].str() : (*it)[3].str();
      while (!name.empty() && std::isspace(static_cast<unsigned char>(name.back()))) name.pop_back();
      if (key != 0 && !name.empty()) names[key] = name;
    }
  }
  gzclose(f);
  return names;
}

Volume read_nifti(const std::string& path) {
  check_nifti_length(path);
  Volume v;
  v.path = path;
  v.format = "nifti";
  vtkNew<vtkNIFTIImageReader> reader;
  std::array<double, 3> sp{}, org{};
  read_vtk_voxels(reader, path, &v, &sp, &org);
  // Rescale as the header says (scl_slope 0 means "not set").
  const double slope = reader->GetRescaleSlope(), inter = reader->GetRescaleIntercept();
  if (slope != 0.0 && (slope != 1.0 || inter != 0.0))
    for (float& x : v.values) x = static_cast<float>(x * slope + inter);
  // VTK's matrices map VTK data coordinates (origin + spacing * IJK, slices reversed when
  // qfac = -1) to NIfTI world (RAS). The sform wins when both are present, as in Slicer.
  vtkMatrix4x4* m = nullptr;
  vtkNIFTIImageHeader* h = reader->GetNIFTIHeader();
  if (h && h->GetSFormCode() > 0) m = reader->GetSFormMatrix();
  if (!m && h && h->GetQFormCode() > 0) m = reader->GetQFormMatrix();
  Mat4 a = identity4();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      const double mrc = m ? m->GetElement(r, c) : (r == c ? 1.0 : 0.0);
      a[r * 4 + c] = mrc * sp[c];
    }
    double t = m ? m->GetElement(r, 3) : 0.0;
    for (int c = 0; c < 3; ++c) t += (m ? m->GetElement(r, c) : (r == c ? 1.0 : 0.0)) * org[c];
    a[r * 4 + 3] = t;
  }
  // With qfac = -1 VTK stores the slices in reverse order (to keep its frame right-handed). Undo
  // that, so that voxel (i, j, k) is the file's voxel (i, j, k): a label map written on this grid
  // then has the CT's own index order and header, as other tools (nibabel, Slicer) expect.
  if (reader->GetQFac() < 0 && v.dims[2] > 1) {
    const size_t slice = static_cast<size_t>(v.dims[0]) * v.dims[1];
    for (int k = 0; k < v.dims[2] / 2; ++k)
      std::swap_ranges(v.values.begin() + k * slice, v.values.begin() + (k + 1) * slice,
                       v.values.begin() + (v.dims[2] - 1 - k) * slice);
    for (int r = 0; r < 3; ++r) {
      a[r * 4 + 3] += a[r * 4 + 2] * (v.dims[2] - 1);
      a[r * 4 + 2] = -a[r * 4 + 2];
    }
  }
  v.ijk_to_ras = a;
  v.label_names = read_nifti_label_names(path);
  return v;
}

// ---- text headers of NRRD and MetaImage, for the geometry VTK's readers do not keep ----

std::map<std::string, std::string> read_text_header(const std::string& path, char sep) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "cannot open file");
  std::map<std::string, std::string> kv;
  std::string line;
  int lines = 0;
  while (std::getline(in, line) && lines++ < 200) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) break;  // NRRD: blank line ends the header
    const auto p = line.find(sep);
    if (p == std::string::npos) continue;
    std::string key = line.substr(0, p), value = line.substr(p + 1);
    if (!value.empty() && value[0] == '=') value = value.substr(1);
    auto trim = [](std::string s) {
      const auto b = s.find_first_not_of(" \t"), e = s.find_last_not_of(" \t");
      return b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
    };
    kv[lower(trim(key))] = trim(value);
    if (lower(trim(key)) == "elementdatafile") break;  // MetaImage: data follows
  }
  return kv;
}

std::vector<double> numbers(std::string s) {
  for (char& c : s)
    if (c == '(' || c == ')' || c == ',') c = ' ';
  std::istringstream is(s);
  std::vector<double> out;
  std::string tok;
  while (is >> tok) {
    try {
      out.push_back(std::stod(tok));
    } catch (...) {
      out.push_back(std::nan(""));
    }
  }
  return out;
}

// Affine from axis vectors (columns, world units per voxel step) and origin, in `space`;
// LPS spaces are turned into RAS by negating x and y.
Mat4 affine_from(const std::array<std::array<double, 3>, 3>& axes, const std::array<double, 3>& o,
                 bool lps) {
  Mat4 a = identity4();
  const double s[3] = {lps ? -1.0 : 1.0, lps ? -1.0 : 1.0, 1.0};
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) a[r * 4 + c] = s[r] * axes[c][r];
    a[r * 4 + 3] = s[r] * o[r];
  }
  return a;
}

// NRRD is read here rather than by vtkNrrdReader, which takes a first axis of size 3 for vector
// components even when `kinds` says domain. Raw and gzip encodings, attached or detached data.
Volume read_nrrd(const std::string& path) {
  Volume v;
  v.path = path;
  v.format = "nrrd";
  const auto kv = read_text_header(path, ':');
  auto need = [&](const char* key) -> const std::string& {
    auto it = kv.find(key);
    if (it == kv.end()) throw InputError(path + ": " + key, "missing NRRD field");
    return it->second;
  };
  const auto sizes = numbers(need("sizes"));
  if (sizes.size() != 3) throw InputError(path + ": sizes", "expected a 3-D volume (three sizes)");
  for (int d = 0; d < 3; ++d) {
    if (!(sizes[d] >= 1)) throw InputError(path + ": sizes", "expected positive sizes");
    v.dims[d] = static_cast<int>(sizes[d]);
  }
  const std::string type = lower(need("type"));
  const std::string encoding = lower(need("encoding"));
  const bool big_endian = kv.count("endian") && lower(kv.at("endian")) == "big";
  int bytes = 0;
  char kind = 'i';
  bool is_signed = true;
  if (type == "short" || type == "int16" || type == "int16_t" || type == "signed short") bytes = 2;
  else if (type == "ushort" || type == "unsigned short" || type == "uint16" || type == "uint16_t") bytes = 2, is_signed = false;
  else if (type == "uchar" || type == "unsigned char" || type == "uint8" || type == "uint8_t") bytes = 1, is_signed = false;
  else if (type == "char" || type == "signed char" || type == "int8" || type == "int8_t") bytes = 1;
  else if (type == "int" || type == "int32" || type == "int32_t" || type == "signed int") bytes = 4;
  else if (type == "uint" || type == "unsigned int" || type == "uint32" || type == "uint32_t") bytes = 4, is_signed = false;
  else if (type == "float") bytes = 4, kind = 'f';
  else if (type == "double") bytes = 8, kind = 'f';
  else throw InputError(path + ": type", "unsupported NRRD type '" + type + "'");
  // Data: after the blank line that ends the header, or in the detached `data file`.
  std::string data;
  {
    std::string file = path;
    size_t offset = 0;
    if (kv.count("data file") || kv.count("datafile")) {
      const std::string df = kv.count("data file") ? kv.at("data file") : kv.at("datafile");
      file = (fs::path(path).parent_path() / df).string();
    } else {
      std::ifstream in(path, std::ios::binary);
      std::string line;
      while (std::getline(in, line)) {
        if (line.empty() || line == "\r") break;
      }
      offset = static_cast<size_t>(in.tellg());
    }
    if (encoding == "raw") {
      std::ifstream in(file, std::ios::binary);
      if (!in) throw InputError(file, "cannot open NRRD data");
      in.seekg(static_cast<std::streamoff>(offset));
      data.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    } else if (encoding == "gzip" || encoding == "gz") {
      std::ifstream in(file, std::ios::binary);
      in.seekg(static_cast<std::streamoff>(offset));
      std::string packed((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      z_stream zs{};
      inflateInit2(&zs, 15 + 32);
      zs.next_in = reinterpret_cast<Bytef*>(packed.data());
      zs.avail_in = static_cast<uInt>(packed.size());
      std::vector<char> buf(1 << 20);
      int rc;
      do {
        zs.next_out = reinterpret_cast<Bytef*>(buf.data());
        zs.avail_out = static_cast<uInt>(buf.size());
        rc = inflate(&zs, Z_NO_FLUSH);
        data.append(buf.data(), buf.size() - zs.avail_out);
      } while (rc == Z_OK);
      inflateEnd(&zs);
      if (rc != Z_STREAM_END) throw InputError(file, "corrupt or truncated gzip data in NRRD");
    } else {
      throw InputError(path + ": encoding", "unsupported NRRD encoding '" + encoding + "' (expected raw or gzip)");
    }
  }
  const size_t n = static_cast<size_t>(v.dims[0]) * v.dims[1] * v.dims[2];
  if (data.size() < n * static_cast<size_t>(bytes))
    throw InputError(path, "truncated volume: " + std::to_string(data.size()) + " bytes of data, sizes need " +
                               std::to_string(n * static_cast<size_t>(bytes)));
  v.values.resize(n);
  for (size_t i = 0; i < n; ++i) {
    unsigned char b[8];
    std::memcpy(b, data.data() + i * bytes, static_cast<size_t>(bytes));
    if (big_endian) std::reverse(b, b + bytes);
    double x = 0;
    if (kind == 'f') {
      if (bytes == 4) { float f; std::memcpy(&f, b, 4); x = f; } else { double dd; std::memcpy(&dd, b, 8); x = dd; }
    } else if (bytes == 1) {
      x = is_signed ? static_cast<double>(static_cast<int8_t>(b[0])) : b[0];
    } else if (bytes == 2) {
      if (is_signed) { int16_t s16; std::memcpy(&s16, b, 2); x = s16; } else { uint16_t u16; std::memcpy(&u16, b, 2); x = u16; }
    } else {
      if (is_signed) { int32_t s32; std::memcpy(&s32, b, 4); x = s32; } else { uint32_t u32; std::memcpy(&u32, b, 4); x = u32; }
    }
    v.values[i] = static_cast<float>(x);
  }
  std::array<double, 3> sp{1, 1, 1};
  if (kv.count("spacings")) {
    const auto s = numbers(kv.at("spacings"));
    for (int d = 0; d < 3 && d < static_cast<int>(s.size()); ++d) sp[d] = std::isfinite(s[d]) ? s[d] : 1.0;
  }
  std::array<std::array<double, 3>, 3> axes{{{sp[0], 0, 0}, {0, sp[1], 0}, {0, 0, sp[2]}}};
  std::array<double, 3> o{0, 0, 0};
  bool lps = false;
  if (kv.count("space")) {
    const std::string space = lower(kv.at("space"));
    lps = space.find("left-posterior") != std::string::npos || space == "lps";
  }
  if (kv.count("space directions")) {
    const auto d = numbers(kv.at("space directions"));
    if (d.size() < 9) throw InputError(path + ": space directions", "expected three 3-vectors");
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r) axes[c][r] = d[c * 3 + r];
  }
  if (kv.count("space origin")) {
    const auto d = numbers(kv.at("space origin"));
    if (d.size() < 3) throw InputError(path + ": space origin", "expected a 3-vector");
    o = {d[0], d[1], d[2]};
  }
  v.ijk_to_ras = affine_from(axes, o, lps);
  return v;
}

Volume read_metaimage(const std::string& path) {
  Volume v;
  v.path = path;
  v.format = "metaimage";
  vtkNew<vtkMetaImageReader> reader;
  std::array<double, 3> sp{}, org{};
  read_vtk_voxels(reader, path, &v, &sp, &org);
  const auto kv = read_text_header(path, '=');
  std::array<std::array<double, 3>, 3> axes{{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};
  if (kv.count("transformmatrix")) {
    // MetaIO stores the direction cosines axis by axis (ITK MetaImageIO convention).
    const auto d = numbers(kv.at("transformmatrix"));
    if (d.size() >= 9)
      for (int c = 0; c < 3; ++c)
        for (int r = 0; r < 3; ++r) axes[c][r] = d[c * 3 + r];
  }
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) axes[c][r] *= sp[c];
  std::array<double, 3> o{org[0], org[1], org[2]};
  for (const char* key : {"offset", "origin", "position"})
    if (kv.count(key)) {
      const auto d = numbers(kv.at(key));
      if (d.size() >= 3) o = {d[0], d[1], d[2]};
      break;
    }
  // MetaImage follows ITK: physical space is LPS.
  v.ijk_to_ras = affine_from(axes, o, true);
  return v;
}

// ---- DICOM series (GDCM) ----

Volume read_dicom_series(const std::string& path) {
  const fs::path folder = fs::is_directory(path) ? fs::path(path) : fs::path(path).parent_path();
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(folder))
    if (e.is_regular_file()) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  if (files.empty()) throw InputError(path, "no DICOM files in the folder");

  struct Slice {
    std::array<double, 3> ipp;
    std::vector<float> pixels;
    double position_along_normal = 0;
  };
  std::vector<Slice> slices;
  int nx = 0, ny = 0;
  std::array<double, 6> iop{};
  std::array<double, 2> pixel_spacing{};
  for (const auto& f : files) {
    // Slices are grouped by folder, not by SeriesInstanceUID: anonymised files may have it empty.
    gdcm::ImageReader reader;
    reader.SetFileName(f.string().c_str());
    if (!reader.Read()) {
      if (f.filename() == "DICOMDIR") continue;
      throw InputError(f.string(), "not a readable DICOM image (corrupt or truncated file)");
    }
    const gdcm::Image& img = reader.GetImage();
    const unsigned int* dim = img.GetDimensions();
    if (img.GetNumberOfDimensions() < 2 || dim[0] == 0 || dim[1] == 0)
      throw InputError(f.string(), "DICOM image without pixel dimensions");
    const int fnx = static_cast<int>(dim[0]), fny = static_cast<int>(dim[1]);
    const int frames = img.GetNumberOfDimensions() > 2 ? static_cast<int>(dim[2]) : 1;
    if (frames != 1) throw InputError(f.string(), "multi-frame DICOM is not supported (expected one slice per file)");
    const double* org = img.GetOrigin();
    const double* dc = img.GetDirectionCosines();
    const double* spc = img.GetSpacing();
    if (slices.empty()) {
      nx = fnx;
      ny = fny;
      for (int i = 0; i < 6; ++i) iop[i] = dc[i];
      pixel_spacing = {spc[0], spc[1]};
    } else if (fnx != nx || fny != ny) {
      throw InputError(f.string(), "slice size " + std::to_string(fnx) + "x" + std::to_string(fny) +
                                       " differs from the series (" + std::to_string(nx) + "x" +
                                       std::to_string(ny) + ")");
    }
    const size_t len = img.GetBufferLength();
    std::vector<char> buffer(len);
    if (!img.GetBuffer(buffer.data()))
      throw InputError(f.string(), "pixel data cannot be decoded (corrupt or unsupported transfer syntax)");
    const gdcm::PixelFormat pf = img.GetPixelFormat();
    if (pf.GetSamplesPerPixel() != 1) throw InputError(f.string(), "expected a greyscale CT slice");
    const size_t n = static_cast<size_t>(nx) * ny;
    Slice s;
    s.ipp = {org[0], org[1], org[2]};
    s.pixels.resize(n);
    const double slope = img.GetSlope(), inter = img.GetIntercept();
    auto fill = [&](auto sample) {
      using T = decltype(sample);
      if (len < n * sizeof(T)) throw InputError(f.string(), "pixel data shorter than the image size (truncated)");
      const T* p = reinterpret_cast<const T*>(buffer.data());
      for (size_t i = 0; i < n; ++i) s.pixels[i] = static_cast<float>(p[i] * slope + inter);
    };
    switch (pf.GetScalarType()) {
      case gdcm::PixelFormat::UINT8: fill(uint8_t{}); break;
      case gdcm::PixelFormat::INT8: fill(int8_t{}); break;
      case gdcm::PixelFormat::UINT16: fill(uint16_t{}); break;
      case gdcm::PixelFormat::INT16: fill(int16_t{}); break;
      case gdcm::PixelFormat::UINT32: fill(uint32_t{}); break;
      case gdcm::PixelFormat::INT32: fill(int32_t{}); break;
      case gdcm::PixelFormat::FLOAT32: fill(float{}); break;
      default: throw InputError(f.string(), "unsupported DICOM pixel type");
    }
    slices.push_back(std::move(s));
  }
  if (slices.empty()) throw InputError(path, "no DICOM image slices found");
  // Slice normal = row x column direction; sort by position along it (instance numbers may run
  // either way).
  const std::array<double, 3> row{iop[0], iop[1], iop[2]}, col{iop[3], iop[4], iop[5]};
  const std::array<double, 3> nrm{row[1] * col[2] - row[2] * col[1], row[2] * col[0] - row[0] * col[2],
                                  row[0] * col[1] - row[1] * col[0]};
  for (Slice& s : slices) s.position_along_normal = s.ipp[0] * nrm[0] + s.ipp[1] * nrm[1] + s.ipp[2] * nrm[2];
  std::sort(slices.begin(), slices.end(),
            [](const Slice& a, const Slice& b) { return a.position_along_normal < b.position_along_normal; });
  std::array<double, 3> step{0, 0, 1};
  if (slices.size() > 1) {
    const double dz = (slices.back().position_along_normal - slices.front().position_along_normal) /
                      static_cast<double>(slices.size() - 1);
    if (!(std::abs(dz) > 1e-6)) throw InputError(path, "DICOM slices share one position (duplicate slices?)");
    for (size_t i = 1; i < slices.size(); ++i) {
      const double d = slices[i].position_along_normal - slices[i - 1].position_along_normal;
      if (std::abs(d - dz) > 0.01 * std::abs(dz) + 1e-3)
        throw InputError(path, "DICOM slices are not evenly spaced (missing slice?)");
    }
    for (int r = 0; r < 3; ++r)
      step[r] = (slices.back().ipp[r] - slices.front().ipp[r]) / static_cast<double>(slices.size() - 1);
  }
  Volume v;
  v.path = path;
  v.format = "dicom";
  v.dims = {nx, ny, static_cast<int>(slices.size())};
  const size_t per = static_cast<size_t>(nx) * ny;
  v.values.resize(per * slices.size());
  for (size_t k = 0; k < slices.size(); ++k)
    std::copy(slices[k].pixels.begin(), slices[k].pixels.end(), v.values.begin() + k * per);
  // DICOM PixelSpacing is (row spacing, column spacing); GDCM's GetSpacing gives x (column
  // index i) first. Voxel (i, j, k) sits at IPP_0 + i*sx*row + j*sy*col + k*step (LPS).
  std::array<std::array<double, 3>, 3> axes{};
  for (int r = 0; r < 3; ++r) {
    axes[0][r] = row[r] * pixel_spacing[0];
    axes[1][r] = col[r] * pixel_spacing[1];
    axes[2][r] = step[r];
  }
  v.ijk_to_ras = affine_from(axes, slices.front().ipp, true);
  return v;
}

bool looks_like_dicom(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char buf[132] = {};
  in.read(buf, 132);
  return in.gcount() == 132 && std::memcmp(buf + 128, "DICM", 4) == 0;
}

}  // namespace

std::array<double, 3> Volume::world(double i, double j, double k) const {
  const auto& a = ijk_to_ras;
  return {a[0] * i + a[1] * j + a[2] * k + a[3], a[4] * i + a[5] * j + a[6] * k + a[7],
          a[8] * i + a[9] * j + a[10] * k + a[11]};
}

std::array<double, 3> Volume::voxel(const std::array<double, 3>& p) const {
  const auto& a = ijk_to_ras;
  const double m[3][3] = {{a[0], a[1], a[2]}, {a[4], a[5], a[6]}, {a[8], a[9], a[10]}};
  const double det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
                     m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                     m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
  const double q[3] = {p[0] - a[3], p[1] - a[7], p[2] - a[11]};
  double inv[3][3];
  inv[0][0] = (m[1][1] * m[2][2] - m[1][2] * m[2][1]) / det;
  inv[0][1] = (m[0][2] * m[2][1] - m[0][1] * m[2][2]) / det;
  inv[0][2] = (m[0][1] * m[1][2] - m[0][2] * m[1][1]) / det;
  inv[1][0] = (m[1][2] * m[2][0] - m[1][0] * m[2][2]) / det;
  inv[1][1] = (m[0][0] * m[2][2] - m[0][2] * m[2][0]) / det;
  inv[1][2] = (m[0][2] * m[1][0] - m[0][0] * m[1][2]) / det;
  inv[2][0] = (m[1][0] * m[2][1] - m[1][1] * m[2][0]) / det;
  inv[2][1] = (m[0][1] * m[2][0] - m[0][0] * m[2][1]) / det;
  inv[2][2] = (m[0][0] * m[1][1] - m[0][1] * m[1][0]) / det;
  return {inv[0][0] * q[0] + inv[0][1] * q[1] + inv[0][2] * q[2],
          inv[1][0] * q[0] + inv[1][1] * q[1] + inv[1][2] * q[2],
          inv[2][0] * q[0] + inv[2][1] * q[1] + inv[2][2] * q[2]};
}

double Volume::voxel_volume_mm3() const {
  const auto& a = ijk_to_ras;
  return std::abs(a[0] * (a[5] * a[10] - a[6] * a[9]) - a[1] * (a[4] * a[10] - a[6] * a[8]) +
                  a[2] * (a[4] * a[9] - a[5] * a[8]));
}

std::array<double, 6> Volume::world_bounds() const {
  std::array<double, 6> b{1e300, 1e300, 1e300, -1e300, -1e300, -1e300};
  for (int c = 0; c < 8; ++c) {
    const auto p = world((c & 1) ? dims[0] - 1 : 0, (c & 2) ? dims[1] - 1 : 0, (c & 4) ? dims[2] - 1 : 0);
    for (int d = 0; d < 3; ++d) {
      b[d] = std::min(b[d], p[d]);
      b[d + 3] = std::max(b[d + 3], p[d]);
    }
  }
  return b;
}

Volume read_volume(const std::string& path) {
  if (!fs::exists(path)) throw InputError(path, "file not found");
  const std::string l = lower(path);
  if (fs::is_directory(path)) return read_dicom_series(path);
  if (ends_with(l, ".nii") || ends_with(l, ".nii.gz")) return read_nifti(path);
  if (ends_with(l, ".nrrd") || ends_with(l, ".nhdr")) return read_nrrd(path);
  if (ends_with(l, ".mha") || ends_with(l, ".mhd")) return read_metaimage(path);
  if (ends_with(l, ".dcm") || looks_like_dicom(path)) return read_dicom_series(path);
  throw InputError(path, "unknown volume format (expected .nii, .nii.gz, .nrrd, .nhdr, .mha, "
                         ".mhd, or a DICOM file/folder)");
}

void write_label_nifti(const Volume& labels, const std::string& path) {
  float vmax = 0, vmin = 0;
  for (float x : labels.values) {
    vmax = std::max(vmax, x);
    vmin = std::min(vmin, x);
  }
  const bool u8 = vmin >= 0 && vmax <= 255;
  unsigned char h[352] = {};
  auto put_i32 = [&](int off, int32_t x) { std::memcpy(h + off, &x, 4); };
  auto put_i16 = [&](int off, int16_t x) { std::memcpy(h + off, &x, 2); };
  auto put_f32 = [&](int off, float x) { std::memcpy(h + off, &x, 4); };
  put_i32(0, 348);
  h[39] = 0;
  const int16_t dim[8] = {3, static_cast<int16_t>(labels.dims[0]), static_cast<int16_t>(labels.dims[1]),
                          static_cast<int16_t>(labels.dims[2]), 1, 1, 1, 1};
  std::memcpy(h + 40, dim, 16);
  put_i16(70, u8 ? 2 : 4);    // DT_UINT8 or DT_INT16
  put_i16(72, u8 ? 8 : 16);   // bitpix
  const auto& a = labels.ijk_to_ras;
  float pixdim[8] = {1, 1, 1, 1, 1, 1, 1, 1};
  for (int c = 0; c < 3; ++c)
    pixdim[c + 1] = static_cast<float>(std::sqrt(a[c] * a[c] + a[4 + c] * a[4 + c] + a[8 + c] * a[8 + c]));
  std::memcpy(h + 76, pixdim, 32);
  put_f32(108, 352.0f);       // vox_offset
  put_f32(112, 1.0f);         // scl_slope
  h[123] = 2;                 // xyzt_units: mm
  std::snprintf(reinterpret_cast<char*>(h + 148), 80, "softatlas segment");
  put_i16(252, 0);            // qform_code: unset; the sform carries the full affine
  put_i16(254, 1);            // sform_code: scanner anatomical
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) put_f32(280 + r * 16 + c * 4, static_cast<float>(a[r * 4 + c]));
  std::memcpy(h + 344, "n+1\0", 4);
  const std::string tmp = path + ".tmp";
  const bool gz = ends_with(lower(path), ".gz");
  std::vector<unsigned char> data;
  data.reserve(labels.values.size() * (u8 ? 1 : 2));
  for (float x : labels.values) {
    const long v = std::lround(x);
    if (u8) {
      data.push_back(static_cast<unsigned char>(v));
    } else {
      const int16_t s = static_cast<int16_t>(v);
      unsigned char b[2];
      std::memcpy(b, &s, 2);
      data.push_back(b[0]);
      data.push_back(b[1]);
    }
  }
  bool ok = true;
  if (gz) {
    gzFile f = gzopen(tmp.c_str(), "wb6");
    ok = f && gzwrite(f, h, 352) == 352 &&
         gzwrite(f, data.data(), static_cast<unsigned>(data.size())) == static_cast<int>(data.size());
    if (f) ok = (gzclose(f) == Z_OK) && ok;
  } else {
    std::ofstream out(tmp, std::ios::binary);
    out.write(reinterpret_cast<const char*>(h), 352);
    out.write(reinterpret_cast<const char*>(data.data()), static_cast<std::streamsize>(data.size()));
    ok = static_cast<bool>(out);
  }
  if (!ok) {
    std::error_code ec;
    fs::remove(tmp, ec);
    throw InputError(path, "cannot write the label map");
  }
  fs::rename(tmp, path);
}

std::string sha256_file(const std::string& path) {
  std::vector<fs::path> files;
  if (fs::is_directory(path)) {
    for (const auto& e : fs::directory_iterator(path))
      if (e.is_regular_file()) files.push_back(e.path());
    std::sort(files.begin(), files.end());
  } else {
    files.push_back(path);
  }
  EVP_MD_CTX* ctx = EVP_MD_CTX_new();
  EVP_DigestInit_ex(ctx, EVP_sha256(), nullptr);
  std::vector<char> buf(1 << 20);
  for (const auto& f : files) {
    std::ifstream in(f, std::ios::binary);
    if (!in) {
      EVP_MD_CTX_free(ctx);
      throw InputError(f.string(), "cannot open file");
    }
    while (in.read(buf.data(), static_cast<std::streamsize>(buf.size())) || in.gcount() > 0)
      EVP_DigestUpdate(ctx, buf.data(), static_cast<size_t>(in.gcount()));
  }
  unsigned char md[EVP_MAX_MD_SIZE];
  unsigned int len = 0;
  EVP_DigestFinal_ex(ctx, md, &len);
  EVP_MD_CTX_free(ctx);
  static const char* hex = "0123456789abcdef";
  std::string out;
  for (unsigned i = 0; i < len; ++i) {
    out += hex[md[i] >> 4];
    out += hex[md[i] & 15];
  }
  return out;
}

}  // namespace softatlas::pipeline
