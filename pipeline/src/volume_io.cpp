// Stage 1, read. Voxels come from VTK readers (NIfTI, NRRD, MetaImage) or GDCM (DICOM, JPEG 2000
// included); the image-to-world transform is taken from the file's own header fields so that
// world coordinates are RAS millimetres exactly as the NIfTI sform/qform (or the DICOM/ITK LPS
// geometry, negated in x and y) maps voxels.
#include <openssl/evp.h>
#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>
#include <vtkCallbackCommand.h>
#include <vtkCommand.h>
#include <vtkDataArray.h>
#include <vtkType.h>
#include <vtkImageData.h>
#include <vtkImageReader2.h>
#include <vtkMatrix4x4.h>
#include <vtkNIFTIImageHeader.h>
#include <vtkNIFTIImageReader.h>
#include <vtkNew.h>
#include <vtkObjectFactory.h>
#include <vtkOutputWindow.h>
#include <vtkPointData.h>
#include <vtkSmartPointer.h>
#include <zlib.h>

#include <pugixml.hpp>

#include <gdcmImage.h>
#include <gdcmImageReader.h>
#include <gdcmPixelFormat.h>
#include <gdcmTrace.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
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

// VTK's console for everything not sent to an observer (the executive's errors, warnings):
// kept, not printed, while a reader runs; the first message becomes part of the one-line error.
class CapturedOutputWindow : public vtkOutputWindow {
 public:
  static CapturedOutputWindow* New();
  vtkTypeMacro(CapturedOutputWindow, vtkOutputWindow) void DisplayText(const char* text) override {
    if (text && first.empty()) first = text;
  }
  std::string first;
};
vtkStandardNewMacro(CapturedOutputWindow)

    struct CaptureVtkOutput {
  vtkSmartPointer<vtkOutputWindow> previous = vtkOutputWindow::GetInstance();
  vtkNew<CapturedOutputWindow> window;
  CaptureVtkOutput() { vtkOutputWindow::SetInstance(window); }
  ~CaptureVtkOutput() { vtkOutputWindow::SetInstance(previous); }
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
void read_vtk_voxels(vtkImageReader2* reader, const std::string& path, Volume* out, std::array<double, 3>* spacing,
                     std::array<double, 3>* origin) {
  CaptureVtkOutput console;
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
    const std::string& first = errors.first.empty() ? console.window->first : errors.first;
    std::string why = first.empty() ? "no voxel data could be read" : io::printable_text(one_line(first), 160);
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
    case VTK_UNSIGNED_CHAR:
      copy(static_cast<unsigned char*>(raw));
      break;
    case VTK_SIGNED_CHAR:
      copy(static_cast<signed char*>(raw));
      break;
    case VTK_CHAR:
      copy(static_cast<char*>(raw));
      break;
    case VTK_SHORT:
      copy(static_cast<short*>(raw));
      break;
    case VTK_UNSIGNED_SHORT:
      copy(static_cast<unsigned short*>(raw));
      break;
    case VTK_INT:
      copy(static_cast<int*>(raw));
      break;
    case VTK_UNSIGNED_INT:
      copy(static_cast<unsigned int*>(raw));
      break;
    case VTK_FLOAT:
      copy(static_cast<float*>(raw));
      break;
    case VTK_DOUBLE:
      copy(static_cast<double*>(raw));
      break;
    default:
      for (size_t i = 0; i < n; ++i)
        out->values[i] = static_cast<float>(scalars->GetComponent(static_cast<vtkIdType>(i), 0));
  }
  double sp[3], org[3];
  image->GetSpacing(sp);
  image->GetOrigin(org);
  *spacing = {sp[0], sp[1], sp[2]};
  *origin = {org[0], org[1], org[2]};
}

// Sane limits for a CT or label map: beyond these a header field is corrupt, not a big scan.
constexpr double kMaxVoxels = 2.0e9;  // 2 G voxels (a 1024 x 1024 x 2000 CT)
constexpr double kMaxDim = 100000;    // voxels along one axis
constexpr double kMinSpacingMm = 1e-3, kMaxSpacingMm = 1e3;
constexpr double kMaxWorldMm = 1e4;  // 10 m from the scanner origin

// Bytes of a file after gzip decompression (a plain file: its size). Counts the whole stream
// with zlib, so that a truncated or corrupt stream is found before any reader sees it.
size_t stream_length(const std::string& path, size_t limit) {
  gzFile f = gzopen(path.c_str(), "rb");
  if (!f) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
  gzbuffer(f, 1 << 17);
  std::vector<char> buf(1 << 20);
  size_t total = 0;
  int r;
  while ((r = gzread(f, buf.data(), static_cast<unsigned>(buf.size()))) > 0) {
    total += static_cast<size_t>(r);
    if (total > limit) break;  // more than the header needs: enough to know it is not short
  }
  int err = Z_OK;
  const char* zmsg = gzerror(f, &err);
  const std::string msg = zmsg && *zmsg ? zmsg : "zlib error";  // zlib owns zmsg: copy before gzclose
  gzclose(f);
  if (r < 0 || (err != Z_OK && err != Z_STREAM_END && err != Z_BUF_ERROR))
    throw InputError(path, "corrupt compressed stream (" + io::printable_text(msg) + ")");
  if (err == Z_BUF_ERROR) throw InputError(path, "truncated compressed stream (gzip data ends early)");
  return total;
}

// The fields of a NIfTI-1 or NIfTI-2 header that decide where and how the voxels are read.
struct NiftiHeader {
  int version = 1;
  bool swap = false;
  int64_t dim[8] = {};
  int datatype = 0, bitpix = 0;
  double pixdim[8] = {};
  double vox_offset = 0, scl_slope = 0, scl_inter = 0;
  int qform_code = 0, sform_code = 0;
  double quatern[3] = {}, qoffset[3] = {}, srow[12] = {};
  bool has_extension = false;
  size_t header_size = 0;  // 348 or 540 (the extension flag follows)
};

// Reads and checks the header before VTK's reader sees the file: every field VTK trusts (dims,
// datatype, bitpix, vox_offset, pixdim, the qform/sform, the rescale) is validated against sane
// limits and the voxel count against the stream length. Errors name the file and the field.
NiftiHeader check_nifti_header(const std::string& path) {
  gzFile f = gzopen(path.c_str(), "rb");
  if (!f) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
  unsigned char h[544] = {};
  const int got = gzread(f, h, sizeof(h));
  gzclose(f);
  if (got < 348)
    throw InputError(path,
                     "truncated NIfTI header (" + std::to_string(std::max(got, 0)) + " bytes, expected at least 348)");
  NiftiHeader n;
  auto raw32 = [&](int off) {
    uint32_t u;
    std::memcpy(&u, h + off, 4);
    return n.swap ? __builtin_bswap32(u) : u;
  };
  auto raw64 = [&](int off) {
    uint64_t u;
    std::memcpy(&u, h + off, 8);
    return n.swap ? __builtin_bswap64(u) : u;
  };
  auto i16 = [&](int off) {
    uint16_t u;
    std::memcpy(&u, h + off, 2);
    if (n.swap) u = __builtin_bswap16(u);
    return static_cast<int16_t>(u);
  };
  auto i32 = [&](int off) { return static_cast<int32_t>(raw32(off)); };
  auto i64 = [&](int off) { return static_cast<int64_t>(raw64(off)); };
  auto f32 = [&](int off) {
    const uint32_t u = raw32(off);
    float x;
    std::memcpy(&x, &u, 4);
    return static_cast<double>(x);
  };
  auto f64 = [&](int off) {
    const uint64_t u = raw64(off);
    double x;
    std::memcpy(&x, &u, 8);
    return x;
  };
  int32_t sizeof_hdr = i32(0);
  if (sizeof_hdr != 348 && sizeof_hdr != 540) {
    n.swap = true;
    sizeof_hdr = i32(0);
  }
  auto bad = [&](const std::string& field, const std::string& what) { return InputError(path + ": " + field, what); };
  if (sizeof_hdr == 348) {
    n.version = 1;
    n.header_size = 348;
    if (std::memcmp(h + 344, "n+1", 4) != 0) throw bad("magic", "expected 'n+1' (a single-file NIfTI-1 .nii)");
    for (int d = 0; d < 8; ++d) n.dim[d] = i16(40 + 2 * d);
    n.datatype = i16(70);
    n.bitpix = i16(72);
    for (int d = 0; d < 8; ++d) n.pixdim[d] = f32(76 + 4 * d);
    n.vox_offset = f32(108);
    n.scl_slope = f32(112);
    n.scl_inter = f32(116);
    n.qform_code = i16(252);
    n.sform_code = i16(254);
    for (int k = 0; k < 3; ++k) n.quatern[k] = f32(256 + 4 * k);
    for (int k = 0; k < 3; ++k) n.qoffset[k] = f32(268 + 4 * k);
    for (int k = 0; k < 12; ++k) n.srow[k] = f32(280 + 4 * k);
  } else if (sizeof_hdr == 540) {
    if (got < 544) throw InputError(path, "truncated NIfTI-2 header");
    n.version = 2;
    n.header_size = 540;
    if (std::memcmp(h + 4, "n+2\0\r\n\032\n", 8) != 0)
      throw bad("magic", "expected 'n+2' (a single-file NIfTI-2 .nii)");
    n.datatype = i16(12);
    n.bitpix = i16(14);
    for (int d = 0; d < 8; ++d) n.dim[d] = i64(16 + 8 * d);
    for (int d = 0; d < 8; ++d) n.pixdim[d] = f64(104 + 8 * d);
    const int64_t vo = i64(168);
    n.vox_offset = static_cast<double>(vo);
    n.scl_slope = f64(176);
    n.scl_inter = f64(184);
    n.qform_code = i32(344);
    n.sform_code = i32(348);
    for (int k = 0; k < 3; ++k) n.quatern[k] = f64(352 + 8 * k);
    for (int k = 0; k < 3; ++k) n.qoffset[k] = f64(376 + 8 * k);
    for (int k = 0; k < 12; ++k) n.srow[k] = f64(400 + 8 * k);
  } else {
    throw bad("sizeof_hdr", "expected 348 (NIfTI-1) or 540 (NIfTI-2), got " + std::to_string(i32(0)));
  }
  n.has_extension = got >= static_cast<int>(n.header_size) + 4 && h[n.header_size] != 0;
  // Dimensions: 1 to 3 spatial axes, anything after the third must be 1 (one scalar per voxel).
  if (n.dim[0] < 1 || n.dim[0] > 7) throw bad("dim[0]", "expected 1..7 dimensions, got " + std::to_string(n.dim[0]));
  double voxels = 1;
  for (int d = 1; d <= n.dim[0]; ++d) {
    if (n.dim[d] < 1 || n.dim[d] > kMaxDim)
      throw bad("dim[" + std::to_string(d) + "]",
                "expected 1.." + std::to_string(static_cast<long>(kMaxDim)) + ", got " + std::to_string(n.dim[d]));
    if (d > 3 && n.dim[d] != 1)
      throw bad("dim[" + std::to_string(d) + "]",
                "expected a 3-D volume (dim[4..7] = 1), got " + std::to_string(n.dim[d]));
    voxels *= static_cast<double>(n.dim[d]);
  }
  if (voxels > kMaxVoxels) throw bad("dim", "more than 2e9 voxels (" + std::to_string(voxels) + ")");
  struct Type {
    int code, bits;
  };
  static const Type kTypes[] = {{2, 8},   {4, 16},   {8, 32},   {16, 32},   {64, 64},
                                {256, 8}, {512, 16}, {768, 32}, {1024, 64}, {1280, 64}};
  const Type* type = nullptr;
  for (const Type& t : kTypes)
    if (t.code == n.datatype) type = &t;
  if (!type)
    throw bad("datatype", "unsupported NIfTI datatype " + std::to_string(n.datatype) +
                              " (expected a scalar integer or float type)");
  if (n.bitpix != type->bits)
    throw bad("bitpix", "expected " + std::to_string(type->bits) + " for datatype " + std::to_string(n.datatype) +
                            ", got " + std::to_string(n.bitpix));
  const double min_offset = static_cast<double>(n.header_size) + 4;
  if (!std::isfinite(n.vox_offset) || n.vox_offset < min_offset || n.vox_offset > 1e8 ||
      n.vox_offset != std::floor(n.vox_offset))
    throw bad("vox_offset", "expected a whole number of bytes >= " + std::to_string(static_cast<int>(min_offset)) +
                                " (and < 1e8), got " + io::printable_text(std::to_string(n.vox_offset)));
  for (int d = 1; d <= 3; ++d) {
    const double s = d <= n.dim[0] ? std::abs(n.pixdim[d]) : 1.0;
    if (!std::isfinite(s) || s < kMinSpacingMm || s > kMaxSpacingMm)
      throw bad("pixdim[" + std::to_string(d) + "]",
                "voxel size must be finite and in 0.001..1000 mm, got " + std::to_string(n.pixdim[d]));
  }
  if (!std::isfinite(n.pixdim[0])) throw bad("pixdim[0]", "qfac must be finite");
  if (!std::isfinite(n.scl_slope) || !std::isfinite(n.scl_inter) || std::abs(n.scl_slope) > 1e6 ||
      std::abs(n.scl_inter) > 1e9)
    throw bad(std::isfinite(n.scl_slope) && std::abs(n.scl_slope) <= 1e6 ? "scl_inter" : "scl_slope",
              "rescale must be finite (|slope| <= 1e6, |intercept| <= 1e9)");
  if (n.qform_code < 0 || n.qform_code > 5)
    throw bad("qform_code", "expected 0..5, got " + std::to_string(n.qform_code));
  if (n.sform_code < 0 || n.sform_code > 5)
    throw bad("sform_code", "expected 0..5, got " + std::to_string(n.sform_code));
  if (n.qform_code > 0) {
    double q2 = 0;
    for (int k = 0; k < 3; ++k) {
      if (!std::isfinite(n.quatern[k])) throw bad("quatern", "quaternion must be finite");
      if (!std::isfinite(n.qoffset[k]) || std::abs(n.qoffset[k]) > kMaxWorldMm)
        throw bad("qoffset", "origin must be finite and within 10 m, got " + std::to_string(n.qoffset[k]));
      q2 += n.quatern[k] * n.quatern[k];
    }
    if (q2 > 1.0 + 1e-4) throw bad("quatern", "b^2 + c^2 + d^2 > 1: not a rotation");
  }
  if (n.sform_code > 0) {
    for (int k = 0; k < 12; ++k)
      if (!std::isfinite(n.srow[k]) || std::abs(n.srow[k]) > (k % 4 == 3 ? kMaxWorldMm : kMaxSpacingMm))
        throw bad(std::string("srow_") + "xyz"[k / 4], "sform must be finite (axes <= 1000 mm, offset within 10 m)");
    const double* m = n.srow;
    const double det =
        m[0] * (m[5] * m[10] - m[6] * m[9]) - m[1] * (m[4] * m[10] - m[6] * m[8]) + m[2] * (m[4] * m[9] - m[5] * m[8]);
    if (!(std::abs(det) > 1e-12)) throw bad("srow", "sform is singular (its axes are not independent)");
  }
  // The stream must hold every voxel the header promises.
  const double need = n.vox_offset + voxels * (type->bits / 8);
  const size_t have = stream_length(path, static_cast<size_t>(need));
  if (static_cast<double>(have) < need)
    throw InputError(path, "truncated volume: " + std::to_string(have) + " bytes, header needs " +
                               std::to_string(static_cast<size_t>(need)));
  return n;
}

// Label names of a Caret/CIFTI <LabelTable>: <Label Key="N" ...>name</Label> (CDATA or text),
// read with pugixml (no recursion, any length). Bad XML or a bad key is an error naming the file.
std::map<int, std::string> parse_label_table(const std::string& xml, const std::string& path) {
  std::map<int, std::string> names;
  pugi::xml_document doc;
  const pugi::xml_parse_result r = doc.load_buffer(xml.data(), xml.size(), pugi::parse_default, pugi::encoding_utf8);
  if (!r)
    throw InputError(path + ": LabelTable", std::string("malformed XML in the header extension (") + r.description() +
                                                " at byte " + std::to_string(r.offset) + ")");
  for (const pugi::xpath_node& xn : doc.select_nodes("//LabelTable/Label")) {
    const pugi::xml_node label = xn.node();
    const std::string key_text = label.attribute("Key").value();
    char* end = nullptr;
    errno = 0;
    const long key = std::strtol(key_text.c_str(), &end, 10);
    if (key_text.empty() || *end != '\0' || errno == ERANGE || key < -2147483647L || key > 2147483647L)
      throw InputError(path + ": LabelTable",
                       "Label Key must be an integer, got '" + io::printable_text(key_text) + "'");
    std::string name = label.child_value();
    if (name.empty())
      for (const pugi::xml_node c : label.children())
        if (c.type() == pugi::node_cdata || c.type() == pugi::node_pcdata) name += c.value();
    const auto b = name.find_first_not_of(" \t\r\n"), e = name.find_last_not_of(" \t\r\n");
    name = b == std::string::npos ? std::string() : name.substr(b, e - b + 1);
    if (key != 0 && !name.empty()) names[static_cast<int>(key)] = io::printable_text(name, 200);
  }
  return names;
}

// Label names from the header extensions of a NIfTI file (checked by check_nifti_header): a
// Caret/CIFTI XML extension (ecode 0 or 30). Other extensions are skipped; a malformed
// extension list names the file.
std::map<int, std::string> read_nifti_label_names(const std::string& path, const NiftiHeader& n) {
  std::map<int, std::string> names;
  if (!n.has_extension) return names;
  gzFile f = gzopen(path.c_str(), "rb");
  if (!f) return names;
  const size_t vox_offset = static_cast<size_t>(n.vox_offset);
  std::string head(vox_offset, '\0');
  const int got = gzread(f, head.data(), static_cast<unsigned>(vox_offset));
  gzclose(f);
  if (got != static_cast<int>(vox_offset)) throw InputError(path, "truncated NIfTI header extension");
  auto i32 = [&](size_t off) {
    uint32_t u;
    std::memcpy(&u, head.data() + off, 4);
    if (n.swap) u = __builtin_bswap32(u);
    return static_cast<int32_t>(u);
  };
  size_t pos = n.header_size + 4;
  while (pos + 8 <= vox_offset) {
    const int32_t esize = i32(pos), ecode = i32(pos + 4);
    if (esize < 16 || esize % 16 != 0 || pos + static_cast<size_t>(esize) > vox_offset)
      throw InputError(path + ": extension", "corrupt NIfTI header extension (size " + std::to_string(esize) +
                                                 " at byte " + std::to_string(pos) + ")");
    const std::string content = head.substr(pos + 8, static_cast<size_t>(esize) - 8);
    pos += static_cast<size_t>(esize);
    if ((ecode != 0 && ecode != 30) || content.find("<LabelTable") == std::string::npos) continue;
    const auto zero = content.find('\0');  // extensions are padded with NULs to 16 bytes
    for (const auto& [key, name] : parse_label_table(content.substr(0, zero), path)) names[key] = name;
  }
  return names;
}

Volume read_nifti(const std::string& path) {
  const NiftiHeader header = check_nifti_header(path);
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
  v.label_names = read_nifti_label_names(path, header);
  return v;
}

// ---- text headers of NRRD and MetaImage, for the geometry VTK's readers do not keep ----

struct TextHeader {
  std::map<std::string, std::string> kv;  // lower-case key -> trimmed value
  size_t data_offset = 0;                 // first byte after the header
};

// Reads "key<sep>value" lines up to the blank line (NRRD) or the ElementDataFile line
// (MetaImage). The header must end within 64 KiB and 1000 lines; values are checked later.
TextHeader read_text_header(const std::string& path, char sep, const char* format) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
  std::string head(65536, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<size_t>(in.gcount()));
  TextHeader h;
  size_t pos = 0;
  int line_no = 0;
  auto trim = [](const std::string& s) {
    const auto b = s.find_first_not_of(" \t"), e = s.find_last_not_of(" \t");
    return b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
  };
  const bool nrrd = sep == ':';
  while (true) {
    const size_t e = head.find('\n', pos);
    if (e == std::string::npos || ++line_no > 1000)
      throw InputError(path, std::string("the ") + format + " header does not end within 64 KiB / 1000 lines" +
                                 (nrrd ? " (no blank line before the data)" : " (no ElementDataFile line)"));
    std::string line = head.substr(pos, e - pos);
    pos = e + 1;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (nrrd && line.empty()) break;                         // NRRD: blank line ends the header
    if (nrrd && (line_no == 1 || line[0] == '#')) continue;  // magic and comments
    const auto p = line.find(sep);
    if (p == std::string::npos) {
      if (nrrd) throw InputError(path + ":" + std::to_string(line_no), "expected 'field: value'");
      continue;
    }
    std::string key = lower(trim(line.substr(0, p))), value = line.substr(p + 1);
    if (nrrd && !value.empty() && value[0] == '=') value = value.substr(1);  // key:=value
    value = trim(value);
    if (key.empty()) throw InputError(path + ":" + std::to_string(line_no), "empty field name");
    if (h.kv.count(key))
      throw InputError(path + ": " + io::printable_text(key),
                       std::string("field given twice in the ") + format + " header");
    h.kv[key] = value;
    if (!nrrd && key == "elementdatafile") break;  // MetaImage: data follows
  }
  h.data_offset = pos;
  return h;
}

// The numbers of a header field, each a whole finite token; `count` of them (0: any number).
std::vector<double> numbers(const std::string& path, const std::string& field, std::string s, size_t count) {
  for (char& c : s)
    if (c == '(' || c == ')' || c == ',') c = ' ';
  std::istringstream is(s);
  std::vector<double> out;
  std::string tok;
  while (is >> tok) {
    char* end = nullptr;
    const double x = std::strtod(tok.c_str(), &end);
    if (end == tok.c_str() || *end != '\0' || !std::isfinite(x))
      throw InputError(path + ": " + field, "expected finite numbers, got '" + io::printable_text(tok) + "'");
    out.push_back(x);
  }
  if (count && out.size() != count)
    throw InputError(path + ": " + field,
                     "expected " + std::to_string(count) + " numbers, got " + std::to_string(out.size()));
  return out;
}

// Positive whole numbers (sizes of the grid), product within the voxel limit.
std::array<int, 3> grid_sizes(const std::string& path, const std::string& field, const std::string& text) {
  const auto s = numbers(path, field, text, 0);
  if (s.size() != 3)
    throw InputError(path + ": " + field, "expected a 3-D volume (three sizes), got " + std::to_string(s.size()));
  std::array<int, 3> d{};
  double total = 1;
  for (int k = 0; k < 3; ++k) {
    if (!(s[k] >= 1 && s[k] <= kMaxDim) || s[k] != std::floor(s[k]))
      throw InputError(path + ": " + field, "sizes must be whole numbers in 1..100000");
    d[k] = static_cast<int>(s[k]);
    total *= s[k];
  }
  if (total > kMaxVoxels) throw InputError(path + ": " + field, "more than 2e9 voxels");
  return d;
}

// Affine from axis vectors (columns, world units per voxel step) and origin, in `space`;
// LPS spaces are turned into RAS by negating x and y.
Mat4 affine_from(const std::array<std::array<double, 3>, 3>& axes, const std::array<double, 3>& o, bool lps) {
  Mat4 a = identity4();
  const double s[3] = {lps ? -1.0 : 1.0, lps ? -1.0 : 1.0, 1.0};
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) a[r * 4 + c] = s[r] * axes[c][r];
    a[r * 4 + 3] = s[r] * o[r];
  }
  return a;
}

// Inflates a zlib/gzip buffer, at most `limit` bytes (more is not needed and would only cost
// memory: a small bomb cannot grow past the volume's size).
std::string inflate_at_most(const std::string& packed, size_t limit, const std::string& where) {
  z_stream zs{};
  if (inflateInit2(&zs, 15 + 32) != Z_OK) throw InputError(where, "zlib cannot start");
  zs.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(packed.data()));
  zs.avail_in = static_cast<uInt>(std::min<size_t>(packed.size(), 0xffffffffu));
  std::string data;
  std::vector<char> buf(1 << 20);
  int rc;
  do {
    zs.next_out = reinterpret_cast<Bytef*>(buf.data());
    zs.avail_out = static_cast<uInt>(buf.size());
    rc = inflate(&zs, Z_NO_FLUSH);
    data.append(buf.data(), buf.size() - zs.avail_out);
  } while (rc == Z_OK && data.size() < limit);
  inflateEnd(&zs);
  if (rc != Z_STREAM_END && data.size() < limit)
    throw InputError(where, "corrupt or truncated compressed data (" +
                                std::string(rc == Z_BUF_ERROR ? "ends early" : "bad zlib stream") + ")");
  if (data.size() > limit) data.resize(limit);
  return data;
}

// Reads `need` bytes of voxel data from `file` at `offset`, raw or compressed; a short file is
// an error (checked against the file size before anything is allocated).
std::string read_voxel_bytes(const std::string& file, size_t offset, size_t need, bool compressed,
                             const std::string& header_path) {
  std::error_code ec;
  const auto size = fs::file_size(file, ec);
  if (ec) throw InputError(file, "cannot open the voxel data: " + ec.message());
  if (size < offset) throw InputError(file, "truncated: no voxel data after the header");
  const size_t avail = static_cast<size_t>(size) - offset;
  if (!compressed && avail < need)
    throw InputError(header_path, "truncated volume: " + std::to_string(avail) + " bytes of data, sizes need " +
                                      std::to_string(need));
  if (compressed && avail > (size_t{1} << 34)) throw InputError(file, "compressed data larger than 16 GiB");
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(file, std::string("cannot open: ") + std::strerror(errno));
  in.seekg(static_cast<std::streamoff>(offset));
  std::string bytes(compressed ? avail : need, '\0');
  in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (static_cast<size_t>(in.gcount()) != bytes.size()) throw InputError(file, "read error in the voxel data");
  if (!compressed) return bytes;
  std::string data = inflate_at_most(bytes, need, file);
  if (data.size() < need)
    throw InputError(header_path, "truncated volume: " + std::to_string(data.size()) +
                                      " bytes after decompression, sizes need " + std::to_string(need));
  return data;
}

// Converts `n` samples of a scalar type to float.
void decode_samples(const std::string& data, size_t n, int bytes, char kind, bool is_signed, bool big_endian,
                    std::vector<float>* out) {
  out->resize(n);
  const size_t nb = bytes == 1 || bytes == 2 || bytes == 4 ? static_cast<size_t>(bytes) : 8;
  for (size_t i = 0; i < n; ++i) {
    unsigned char b[8];
    std::memcpy(b, data.data() + i * nb, nb);
    if (big_endian)
      for (size_t k = 0; k < nb / 2; ++k) std::swap(b[k], b[nb - 1 - k]);
    double x = 0;
    if (kind == 'f') {
      if (bytes == 4) {
        float f;
        std::memcpy(&f, b, 4);
        x = f;
      } else {
        double dd;
        std::memcpy(&dd, b, 8);
        x = dd;
      }
    } else if (bytes == 1) {
      x = is_signed ? static_cast<double>(static_cast<int8_t>(b[0])) : b[0];
    } else if (bytes == 2) {
      if (is_signed) {
        int16_t s16;
        std::memcpy(&s16, b, 2);
        x = s16;
      } else {
        uint16_t u16;
        std::memcpy(&u16, b, 2);
        x = u16;
      }
    } else if (bytes == 4) {
      if (is_signed) {
        int32_t s32;
        std::memcpy(&s32, b, 4);
        x = s32;
      } else {
        uint32_t u32;
        std::memcpy(&u32, b, 4);
        x = u32;
      }
    } else {
      if (is_signed) {
        int64_t s64;
        std::memcpy(&s64, b, 8);
        x = static_cast<double>(s64);
      } else {
        uint64_t u64;
        std::memcpy(&u64, b, 8);
        x = static_cast<double>(u64);
      }
    }
    (*out)[i] = static_cast<float>(x);
  }
}

// A detached data file beside the header: a plain relative or absolute name (no lists or
// patterns), which must exist.
std::string data_file_beside(const std::string& path, const std::string& field, const std::string& name) {
  if (name.empty() || name.find_first_of("%*?\n") != std::string::npos || lower(name).rfind("list", 0) == 0)
    throw InputError(path + ": " + field, "expected one data file name, got '" + io::printable_text(name) + "'");
  const fs::path p = fs::path(name).is_absolute() ? fs::path(name) : fs::path(path).parent_path() / name;
  std::error_code ec;
  if (!fs::is_regular_file(p, ec))
    throw InputError(path + ": " + field, "data file '" + io::printable_text(name) + "' not found");
  return p.string();
}

// NRRD is read here rather than by vtkNrrdReader, which takes a first axis of size 3 for vector
// components even when `kinds` says domain. Raw and gzip encodings, attached or detached data.
Volume read_nrrd(const std::string& path) {
  Volume v;
  v.path = path;
  v.format = "nrrd";
  {
    std::ifstream in(path, std::ios::binary);
    char magic[5] = {};
    in.read(magic, 4);
    if (std::memcmp(magic, "NRRD", 4) != 0) throw InputError(path, "not a NRRD file (no 'NRRD' magic)");
  }
  const TextHeader th = read_text_header(path, ':', "NRRD");
  const auto& kv = th.kv;
  auto need = [&](const char* key) -> const std::string& {
    auto it = kv.find(key);
    if (it == kv.end()) throw InputError(path + ": " + key, "missing NRRD field");
    return it->second;
  };
  if (kv.count("dimension") && numbers(path, "dimension", kv.at("dimension"), 1)[0] != 3)
    throw InputError(path + ": dimension", "expected a 3-D volume (dimension: 3)");
  v.dims = grid_sizes(path, "sizes", need("sizes"));
  const std::string type = lower(need("type"));
  const std::string encoding = lower(need("encoding"));
  const bool big_endian = kv.count("endian") && lower(kv.at("endian")) == "big";
  int bytes = 0;
  char kind = 'i';
  bool is_signed = true;
  if (type == "short" || type == "int16" || type == "int16_t" || type == "signed short")
    bytes = 2;
  else if (type == "ushort" || type == "unsigned short" || type == "uint16" || type == "uint16_t")
    bytes = 2, is_signed = false;
  else if (type == "uchar" || type == "unsigned char" || type == "uint8" || type == "uint8_t")
    bytes = 1, is_signed = false;
  else if (type == "char" || type == "signed char" || type == "int8" || type == "int8_t")
    bytes = 1;
  else if (type == "int" || type == "int32" || type == "int32_t" || type == "signed int")
    bytes = 4;
  else if (type == "uint" || type == "unsigned int" || type == "uint32" || type == "uint32_t")
    bytes = 4, is_signed = false;
  else if (type == "float")
    bytes = 4, kind = 'f';
  else if (type == "double")
    bytes = 8, kind = 'f';
  else
    throw InputError(path + ": type", "unsupported NRRD type '" + io::printable_text(type) + "'");
  if (encoding != "raw" && encoding != "gzip" && encoding != "gz")
    throw InputError(path + ": encoding",
                     "unsupported NRRD encoding '" + io::printable_text(encoding) + "' (expected raw or gzip)");
  // Data: after the blank line that ends the header, or in the detached `data file`.
  std::string file = path;
  size_t offset = th.data_offset;
  for (const char* key : {"data file", "datafile"})
    if (kv.count(key)) {
      file = data_file_beside(path, key, kv.at(key));
      offset = 0;
    }
  const size_t n = static_cast<size_t>(v.dims[0]) * v.dims[1] * v.dims[2];
  const std::string data = read_voxel_bytes(file, offset, n * static_cast<size_t>(bytes), encoding != "raw", path);
  decode_samples(data, n, bytes, kind, is_signed, big_endian, &v.values);
  std::array<double, 3> sp{1, 1, 1};
  if (kv.count("spacings")) {
    const auto s = numbers(path, "spacings", kv.at("spacings"), 3);
    for (int d = 0; d < 3; ++d) sp[d] = s[d];
  }
  std::array<std::array<double, 3>, 3> axes{{{sp[0], 0, 0}, {0, sp[1], 0}, {0, 0, sp[2]}}};
  std::array<double, 3> o{0, 0, 0};
  bool lps = false;
  if (kv.count("space")) {
    const std::string space = lower(kv.at("space"));
    lps = space.find("left-posterior") != std::string::npos || space == "lps";
  }
  if (kv.count("space directions")) {
    const auto d = numbers(path, "space directions", kv.at("space directions"), 9);
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r) axes[c][r] = d[c * 3 + r];
  }
  if (kv.count("space origin")) {
    const auto d = numbers(path, "space origin", kv.at("space origin"), 3);
    o = {d[0], d[1], d[2]};
  }
  v.ijk_to_ras = affine_from(axes, o, lps);
  return v;
}

// MetaImage (.mha/.mhd): the header is checked here (dimensions, type, spacing, geometry, data
// size against the file) before VTK's MetaIO reader sees the file.
Volume read_metaimage(const std::string& path) {
  Volume v;
  v.path = path;
  v.format = "metaimage";
  const TextHeader th = read_text_header(path, '=', "MetaImage");
  const auto& kv = th.kv;
  auto need = [&](const char* key, const char* name) -> const std::string& {
    auto it = kv.find(key);
    if (it == kv.end()) throw InputError(path + ": " + name, "missing MetaImage field");
    return it->second;
  };
  if (kv.count("objecttype") && lower(kv.at("objecttype")) != "image")
    throw InputError(path + ": ObjectType", "expected Image");
  if (numbers(path, "NDims", need("ndims", "NDims"), 1)[0] != 3)
    throw InputError(path + ": NDims", "expected a 3-D volume (NDims = 3)");
  v.dims = grid_sizes(path, "DimSize", need("dimsize", "DimSize"));
  if (kv.count("elementnumberofchannels") &&
      numbers(path, "ElementNumberOfChannels", kv.at("elementnumberofchannels"), 1)[0] != 1)
    throw InputError(path + ": ElementNumberOfChannels", "expected 1 (a scalar volume)");
  struct Type {
    const char* name;
    int bytes;
    char kind;
    bool is_signed;
  };
  static const Type kTypes[] = {{"met_uchar", 1, 'i', false},  {"met_char", 1, 'i', true},
                                {"met_ushort", 2, 'i', false}, {"met_short", 2, 'i', true},
                                {"met_uint", 4, 'i', false},   {"met_int", 4, 'i', true},
                                {"met_float", 4, 'f', true},   {"met_double", 8, 'f', true}};
  const std::string et = lower(need("elementtype", "ElementType"));
  const Type* type = nullptr;
  for (const Type& t : kTypes)
    if (et == t.name) type = &t;
  if (!type) throw InputError(path + ": ElementType", "unsupported element type '" + io::printable_text(et) + "'");
  auto boolean = [&](const char* key, const char* name) {
    if (!kv.count(key)) return false;
    const std::string b = lower(kv.at(key));
    if (b == "true" || b == "1") return true;
    if (b == "false" || b == "0") return false;
    throw InputError(path + ": " + name, "expected True or False, got '" + io::printable_text(b) + "'");
  };
  const bool compressed = boolean("compresseddata", "CompressedData");
  const bool msb = boolean("binarydatabyteordermsb", "BinaryDataByteOrderMSB") ||
                   boolean("elementbyteordermsb", "ElementByteOrderMSB");
  if (kv.count("binarydata") && !boolean("binarydata", "BinaryData"))
    throw InputError(path + ": BinaryData", "ASCII MetaImage data is not supported (expected True)");
  if (kv.count("headersize")) throw InputError(path + ": HeaderSize", "HeaderSize is not supported");
  std::array<double, 3> sp{1, 1, 1};
  for (const char* key : {"elementsize", "elementspacing"})  // ElementSpacing wins, as in MetaIO
    if (kv.count(key)) {
      const auto s = numbers(path, key == std::string("elementsize") ? "ElementSize" : "ElementSpacing", kv.at(key), 3);
      sp = {s[0], s[1], s[2]};
    }
  std::array<std::array<double, 3>, 3> axes{{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};
  for (const char* key : {"transformmatrix", "rotation", "orientation"})
    if (kv.count(key)) {
      // MetaIO stores the direction cosines axis by axis (ITK MetaImageIO convention).
      const auto d = numbers(path, "TransformMatrix", kv.at(key), 9);
      for (int c = 0; c < 3; ++c)
        for (int r = 0; r < 3; ++r) axes[c][r] = d[c * 3 + r];
      break;
    }
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) axes[c][r] *= sp[c];
  std::array<double, 3> o{0, 0, 0};
  for (const char* key : {"offset", "origin", "position"})
    if (kv.count(key)) {
      const auto d = numbers(path, "Offset", kv.at(key), 3);
      o = {d[0], d[1], d[2]};
      break;
    }
  for (const char* key : {"centerofrotation", "compresseddatasize"})
    if (kv.count(key)) numbers(path, key, kv.at(key), 0);
  const std::string df = need("elementdatafile", "ElementDataFile");
  std::string file = path;
  size_t offset = th.data_offset;
  if (lower(df) != "local") {
    file = data_file_beside(path, "ElementDataFile", df);
    offset = 0;
  }
  const size_t n = static_cast<size_t>(v.dims[0]) * v.dims[1] * v.dims[2];
  // The voxels are read here (the header is fully known): MetaIO's own reader trusts sizes and
  // prints to the console, so it is not given the file.
  const std::string data = read_voxel_bytes(file, offset, n * static_cast<size_t>(type->bytes), compressed, path);
  decode_samples(data, n, type->bytes, type->kind, type->is_signed, msb, &v.values);
  // MetaImage follows ITK: physical space is LPS.
  v.ijk_to_ras = affine_from(axes, o, true);
  return v;
}

// ---- DICOM series (GDCM) ----

// One decoded slice: geometry and rescaled pixels.
struct DicomSlice {
  int nx = 0, ny = 0;
  std::array<double, 3> ipp{};
  std::array<double, 6> iop{};
  std::array<double, 2> spacing{};
  std::vector<float> pixels;
  double position_along_normal = 0;
};

// Walks the data elements of a DICOM file (Part 10, little endian, explicit or implicit VR) and
// checks every length against the bytes that are left, nested items and sequences included,
// before GDCM allocates what a length says (a mutated length asked GDCM for 4 GiB).
void check_dicom_lengths(const fs::path& f) {
  std::ifstream in(f, std::ios::binary);
  std::string d((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string where = f.string();
  size_t pos = 0;
  if (d.size() >= 132 && d.compare(128, 4, "DICM") == 0) pos = 132;
  // Part 10: the file meta group follows "DICM" (GDCM asserts in Reader::InternalReadCommon on a
  // file that ends there).
  if (pos == 132 && (d.size() < 136 || d.compare(132, 2, std::string("\x02\x00", 2)) != 0))
    throw InputError(where, "DICOM file: no file meta information (group 0002) after the 'DICM' prefix at byte 128");
  auto u16 = [&](size_t o) {
    return static_cast<uint32_t>(static_cast<unsigned char>(d[o]) | (static_cast<unsigned char>(d[o + 1]) << 8));
  };
  auto u32 = [&](size_t o) { return u16(o) | (u16(o + 2) << 16); };
  bool explicit_vr = pos == 132;  // group 0002 is always explicit VR little endian
  bool meta_done = pos != 132;
  std::string syntax;
  // Each open undefined-length sequence or item: its end is found by a delimiter.
  int depth = 0;
  // GDCM asserts (ReadExplicitDataElement) when the file ends inside the file meta group.
  bool saw_meta = false, saw_data_set = false;
  int bits_allocated = 0, bits_stored = 0;  // 0: absent
  bool saw_intercept = false, saw_slope = false;
  while (pos < d.size()) {
    if (pos + 8 > d.size()) throw InputError(where, "truncated DICOM data element at byte " + std::to_string(pos));
    const uint32_t group = u16(pos), elem = u16(pos + 2);
    (group == 0x0002 ? saw_meta : saw_data_set) = true;
    if (!meta_done && group != 0x0002) {
      meta_done = true;
      const std::string ts = syntax.substr(0, syntax.find_last_not_of(std::string("\0 ", 2)) + 1);
      if (ts == "1.2.840.10008.1.2")
        explicit_vr = false;
      else if (ts == "1.2.840.10008.1.2.2" || ts == "1.2.840.10008.1.2.1.99")
        throw InputError(where,
                         "unsupported DICOM transfer syntax " + io::printable_text(ts) + " (big endian or deflated)");
    }
    if (group == 0xFFFE) {  // item, item delimiter, sequence delimiter: 4-byte length, no VR
      const uint32_t len = u32(pos + 4);
      pos += 8;
      if (elem == 0xE000) {
        if (len == 0xFFFFFFFFu) {
          ++depth;
          continue;
        }
        if (len > d.size() - pos)
          throw InputError(where, "DICOM item length " + std::to_string(len) + " runs past the end of the file");
        // A defined-length item is walked as elements too (its content is data elements or,
        // in encapsulated pixel data, a fragment, which we skip).
        pos += len;
        continue;
      }
      if (elem == 0xE00D || elem == 0xE0DD) {
        // a delimiter has length 0 (GDCM allocated 4 GB for one that claimed 0xFF26FFFF)
        if (len != 0)
          throw InputError(where, "DICOM delimiter at byte " + std::to_string(pos - 8) + " with length " +
                                      std::to_string(len) + " (expected 0)");
        if (depth > 0) --depth;
        continue;
      }
      throw InputError(where, "bad DICOM delimiter tag at byte " + std::to_string(pos - 8));
    }
    uint32_t len;
    bool undefined_ok = false;
    const bool ev = explicit_vr || group == 0x0002;
    if (ev) {
      const std::string vr = d.substr(pos + 4, 2);
      static const std::string kVrs =
          "AE AS AT CS DA DS DT FL FD IS LO LT OB OD OF OL OV OW PN SH SL SQ SS ST SV TM UC UI UL UN UR US UT UV";
      if (vr.size() != 2 || !std::isupper(static_cast<unsigned char>(vr[0])) ||
          !std::isupper(static_cast<unsigned char>(vr[1])) || kVrs.find(vr) == std::string::npos)
        throw InputError(where, "bad DICOM value representation '" + io::printable_text(vr) + "' at byte " +
                                    std::to_string(pos + 4));
      // GDCM asserts (ExplicitDataElement::ReadValue) on Pixel Data read as a sequence.
      if (group == 0x7FE0 && elem == 0x0010 && vr != "OB" && vr != "OW")
        throw InputError(where, "DICOM Pixel Data (7FE0,0010): expected VR OB or OW, got '" + io::printable_text(vr) +
                                    "' at byte " + std::to_string(pos + 4));
      if (vr == "OB" || vr == "OW" || vr == "OF" || vr == "OD" || vr == "OL" || vr == "OV" || vr == "SQ" ||
          vr == "UC" || vr == "UN" || vr == "UR" || vr == "UT" || vr == "SV" || vr == "UV") {
        if (pos + 12 > d.size()) throw InputError(where, "truncated DICOM data element at byte " + std::to_string(pos));
        len = u32(pos + 8);
        pos += 12;
        // An undefined length is a sequence (SQ, UN) or encapsulated Pixel Data; on any other
        // OB/OW element GDCM asserts (ExplicitDataElement::ReadValue: VR must be UN).
        undefined_ok = vr == "SQ" || vr == "UN" || ((vr == "OB" || vr == "OW") && group == 0x7FE0 && elem == 0x0010);
      } else {
        len = u16(pos + 6);
        pos += 8;
      }
    } else {
      len = u32(pos + 4);
      pos += 8;
      undefined_ok = true;
    }
    // GDCM asserts (ReadExplicitDataElement, "Should not happen") on a sequence or an undefined
    // length in the file meta group.
    if (group == 0x0002 && (len == 0xFFFFFFFFu || (ev && d.compare(pos - 8, 2, "SQ") == 0)))
      throw InputError(where, "DICOM file meta element (0002," + std::to_string(elem) +
                                  "): a sequence or an undefined length (expected a plain value)");
    if (len == 0xFFFFFFFFu) {
      if (!undefined_ok) throw InputError(where, "undefined length on a DICOM element that cannot have one");
      ++depth;
      continue;
    }
    if (len > d.size() - pos)
      throw InputError(where, "DICOM element (" + std::to_string(group) + "," + std::to_string(elem) + ") length " +
                                  std::to_string(len) + " runs past the end of the file");
    if (group == 0x0002 && elem == 0x0010) syntax = d.substr(pos, len);
    // The image attributes GDCM reads with a fixed VR and value count (it asserts otherwise).
    struct Known {
      uint32_t group, elem;
      const char* vr;
      int count;
    };
    static const Known kKnown[] = {
        {0x0028, 0x0002, "US", 1}, {0x0028, 0x0010, "US", 1}, {0x0028, 0x0011, "US", 1}, {0x0028, 0x0100, "US", 1},
        {0x0028, 0x0101, "US", 1}, {0x0028, 0x0102, "US", 1}, {0x0028, 0x0103, "US", 1}, {0x0028, 0x0030, "DS", 2},
        {0x0028, 0x1052, "DS", 1}, {0x0028, 0x1053, "DS", 1}, {0x0020, 0x0032, "DS", 3}, {0x0020, 0x0037, "DS", 6},
        {0x0018, 0x0050, "DS", 1}, {0x0018, 0x0088, "DS", 1}, {0x0028, 0x0008, "IS", 1}, {0x0028, 0x0006, "US", 1},
        {0x0028, 0x0034, "IS", 2}, {0x0028, 0x0009, "AT", 0}};  // FrameIncrementPointer: tags, any count
    if (depth == 0)
      for (const Known& k : kKnown) {
        if (k.group != group || k.elem != elem || len == 0) continue;  // empty: absent
        const std::string value = d.substr(pos, len);
        const std::string name = "DICOM (" + std::to_string(group) + "," + std::to_string(elem) + ")";
        if (ev && d.compare(pos - 4, 2, k.vr) != 0)  // US, DS, IS: the 8-byte header, VR at byte 4
          throw InputError(where, name + ": expected VR " + k.vr);
        if (k.vr[0] == 'A') {  // AT: 4 bytes per value
          if (len % 4 != 0) throw InputError(where, name + ": expected tags of 4 bytes each");
          continue;
        }
        if (k.vr[0] == 'U' ? len != 2 * static_cast<uint32_t>(k.count)
                           : static_cast<int>(std::count(value.begin(), value.end(), '\\')) + 1 != k.count)
          throw InputError(where, name + ": expected " + std::to_string(k.count) + " value(s)");
        // GDCM asserts on SamplesPerPixel > 4; a CT slice is greyscale anyway.
        if (group == 0x0028 && elem == 0x0002 && u16(pos) != 1)
          throw InputError(where, name + " SamplesPerPixel: expected 1 (greyscale), got " + std::to_string(u16(pos)));
        // BitsAllocated 1 or 12 made GDCM assert in GetScalarType; the slice reader takes 8, 16, 32.
        if (group == 0x0028 && elem == 0x0100 && u16(pos) != 8 && u16(pos) != 16 && u16(pos) != 32)
          throw InputError(where, name + " BitsAllocated: expected 8, 16 or 32, got " + std::to_string(u16(pos)));
        if (group == 0x0028 && elem == 0x0100) bits_allocated = static_cast<int>(u16(pos));
        if (group == 0x0028 && elem == 0x0101) bits_stored = static_cast<int>(u16(pos));
        if (group == 0x0028 && elem == 0x1052) saw_intercept = true;
        if (group == 0x0028 && elem == 0x1053) saw_slope = true;
        if (k.vr[0] != 'U') {
          std::istringstream vs(value);
          std::string tok;
          while (std::getline(vs, tok, '\\')) {
            const auto b = tok.find_first_not_of(" "), e = tok.find_last_not_of(std::string(" \0", 2));
            tok = b == std::string::npos ? std::string() : tok.substr(b, e - b + 1);
            char* end = nullptr;
            const double x = std::strtod(tok.c_str(), &end);
            if (tok.empty() || *end != '\0' || !std::isfinite(x))
              throw InputError(where, name + ": expected finite numbers, got '" + io::printable_text(value) + "'");
            // GDCM asserts (ImageHelper::GetRescaleInterceptSlopeValue) on a zero slope.
            if (group == 0x0028 && elem == 0x1053 && x == 0.0)
              throw InputError(
                  where, name + " RescaleSlope: expected a non-zero number, got '" + io::printable_text(value) + "'");
          }
        }
      }
    // A CT slice is greyscale; on a palette or colour interpretation without its lookup tables GDCM
    // asserts (PixmapReader::ReadImageInternal).
    if (depth == 0 && group == 0x0028 && elem == 0x0004 && len > 0) {
      std::string pi = d.substr(pos, len);
      pi = pi.substr(0, pi.find_last_not_of(std::string("\0 ", 2)) + 1);
      if (pi != "MONOCHROME1" && pi != "MONOCHROME2")
        throw InputError(
            where,
            "DICOM Photometric Interpretation (0028,0004): expected MONOCHROME1 or MONOCHROME2 (a greyscale CT "
            "slice), got '" +
                io::printable_text(pi) + "'");
    }
    // GDCM asserts on a retired Recognition Code it does not know: PixmapReader::ReadImageInternal
    // on one that is not ACR-NEMA, ReadACRNEMAImage on any but these four, byte for byte (fuzzing:
    // "ACRNEMA" and a NUL passed the prefix test that was here). The LIBIDO codes are compared up
    // to a NUL (strcmp), the ACR-NEMA ones whole.
    if (depth == 0 && group == 0x0008 && elem == 0x0010 && len > 0) {
      const std::string code = d.substr(pos, len);
      const std::string upto_nul = code.substr(0, code.find('\0'));
      if (code != "ACR-NEMA 1.0" && code != "ACR-NEMA 2.0" && upto_nul != "ACRNEMA_LIBIDO_1.0" &&
          upto_nul != "ACRNEMA_LIBIDO_1.1")
        throw InputError(where,
                         "DICOM Recognition Code (0008,0010): expected ACR-NEMA 1.0, ACR-NEMA 2.0, ACRNEMA_LIBIDO_1.0 or "
                         "ACRNEMA_LIBIDO_1.1, got '" +
                             io::printable_text(code) + "'");
    }
    pos += len;
    if (depth > 1000) throw InputError(where, "DICOM sequences nested more than 1000 deep");
  }
  if (saw_meta && !saw_data_set)
    throw InputError(where, "DICOM file meta information (group 0002): the file ends inside it (no data set follows)");
  // DICOM has RescaleIntercept and RescaleSlope together; with the intercept alone GDCM took a zero
  // slope and asserted (ImageHelper::GetRescaleInterceptSlopeValue).
  if (saw_intercept != saw_slope)
    throw InputError(where, std::string("DICOM ") +
                                (saw_intercept ? "RescaleIntercept (0028,1052) without RescaleSlope (0028,1053)"
                                               : "RescaleSlope (0028,1053) without RescaleIntercept (0028,1052)") +
                                ": expected both or neither");
  // GDCM's raw codec masks unused high bits only in 16-bit samples; on 8 or 32 bits with fewer
  // stored it asserts (ImageCodec::DecodeByStreams: BitsAllocated == BitsStored).
  if (bits_allocated > 0 && bits_stored > 0 &&
      (bits_stored > bits_allocated || (bits_allocated != 16 && bits_stored != bits_allocated)))
    throw InputError(where, "DICOM BitsStored (0028,0101) " + std::to_string(bits_stored) +
                                " with BitsAllocated (0028,0100) " + std::to_string(bits_allocated) +
                                ": expected BitsStored <= 16 with 16 bits allocated, else equal");
}

// Decodes one file with GDCM, in this process. Throws InputError; returns false for a DICOMDIR.
bool decode_dicom_slice(const fs::path& f, DicomSlice* s) {
  if (f.filename() == "DICOMDIR") return false;
  check_dicom_lengths(f);
  gdcm::ImageReader reader;
  reader.SetFileName(f.string().c_str());
  if (!reader.Read()) {
    if (f.filename() == "DICOMDIR") return false;
    throw InputError(f.string(), "not a readable DICOM image (corrupt or truncated file)");
  }
  const gdcm::Image& img = reader.GetImage();
  const unsigned int* dim = img.GetDimensions();
  if (img.GetNumberOfDimensions() < 2 || dim[0] == 0 || dim[1] == 0)
    throw InputError(f.string(), "DICOM image without pixel dimensions");
  if (dim[0] > 16384 || dim[1] > 16384)
    throw InputError(f.string(), "DICOM slice of " + std::to_string(dim[0]) + " x " + std::to_string(dim[1]) +
                                     " pixels (expected at most 16384 x 16384)");
  const int frames = img.GetNumberOfDimensions() > 2 ? static_cast<int>(dim[2]) : 1;
  if (frames != 1) throw InputError(f.string(), "multi-frame DICOM is not supported (expected one slice per file)");
  const double* org = img.GetOrigin();
  const double* dc = img.GetDirectionCosines();
  const double* spc = img.GetSpacing();
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(org[i]) || !std::isfinite(dc[i]) || !std::isfinite(dc[i + 3]) || !std::isfinite(spc[i]))
      throw InputError(f.string(), "ImagePositionPatient, ImageOrientationPatient or PixelSpacing is not finite");
  const double slope = img.GetSlope(), inter = img.GetIntercept();
  if (!std::isfinite(slope) || !std::isfinite(inter))
    throw InputError(f.string(), "RescaleSlope or RescaleIntercept is not finite");
  const gdcm::PixelFormat pf = img.GetPixelFormat();
  if (pf.GetSamplesPerPixel() != 1) throw InputError(f.string(), "expected a greyscale CT slice");
  s->nx = static_cast<int>(dim[0]);
  s->ny = static_cast<int>(dim[1]);
  s->ipp = {org[0], org[1], org[2]};
  for (int i = 0; i < 6; ++i) s->iop[i] = dc[i];
  s->spacing = {spc[0], spc[1]};
  const size_t len = img.GetBufferLength();
  const size_t n = static_cast<size_t>(s->nx) * s->ny;
  if (len > (size_t{1} << 31) || len < n) throw InputError(f.string(), "pixel data size does not match the image size");
  // Uncompressed pixel data is in the file: a 480-byte file that claimed 16384 x 8192 pixels
  // was decoded into 128 M zeros (fuzzing, 4 s under ASan).
  std::error_code size_error;
  const auto file_bytes = fs::file_size(f, size_error);
  const bool encapsulated = reader.GetFile().GetHeader().GetDataSetTransferSyntax().IsEncapsulated();
  if (!encapsulated && !size_error && len > file_bytes)
    throw InputError(f.string(), "pixel data shorter than the image size (" + std::to_string(file_bytes) +
                                     " bytes in the file, " + std::to_string(len) + " needed): truncated");
  // GDCM's raw codec copies the image size from the Pixel Data element's value without checking
  // its length (heap overflow on a 31-byte value, fuzzing).
  if (!encapsulated) {
    const gdcm::DataSet& ds = reader.GetFile().GetDataSet();
    const gdcm::Tag pixel_data(0x7fe0, 0x0010);
    const gdcm::ByteValue* bv = ds.FindDataElement(pixel_data) ? ds.GetDataElement(pixel_data).GetByteValue() : nullptr;
    const size_t have = bv ? static_cast<size_t>(static_cast<uint32_t>(bv->GetLength())) : 0;
    if (have < len)
      throw InputError(f.string(), "Pixel Data (7FE0,0010) holds " + std::to_string(have) + " bytes, the image needs " +
                                       std::to_string(len) + ": truncated");
  }
  std::vector<char> buffer(len);
  if (!img.GetBuffer(buffer.data()))
    throw InputError(f.string(), "pixel data cannot be decoded (corrupt or unsupported transfer syntax)");
  s->pixels.resize(n);
  auto fill = [&](auto sample) {
    using T = decltype(sample);
    if (len < n * sizeof(T)) throw InputError(f.string(), "pixel data shorter than the image size (truncated)");
    for (size_t i = 0; i < n; ++i) {
      T v;
      std::memcpy(&v, buffer.data() + i * sizeof(T), sizeof(T));
      s->pixels[i] = static_cast<float>(v * slope + inter);
    }
  };
  switch (pf.GetScalarType()) {
    case gdcm::PixelFormat::UINT8:
      fill(uint8_t{});
      break;
    case gdcm::PixelFormat::INT8:
      fill(int8_t{});
      break;
    case gdcm::PixelFormat::UINT16:
      fill(uint16_t{});
      break;
    case gdcm::PixelFormat::INT16:
      fill(int16_t{});
      break;
    case gdcm::PixelFormat::UINT32:
      fill(uint32_t{});
      break;
    case gdcm::PixelFormat::INT32:
      fill(int32_t{});
      break;
    case gdcm::PixelFormat::FLOAT32:
      fill(float{});
      break;
    default:
      throw InputError(f.string(), "unsupported DICOM pixel type");
  }
  return true;
}

bool write_all(int fd, const void* data, size_t n) {
  const char* p = static_cast<const char*>(data);
  while (n > 0) {
    const ssize_t w = ::write(fd, p, n);
    if (w <= 0) return false;
    p += w;
    n -= static_cast<size_t>(w);
  }
  return true;
}

bool read_all(int fd, void* data, size_t n) {
  char* p = static_cast<char*>(data);
  while (n > 0) {
    const ssize_t r = ::read(fd, p, n);
    if (r <= 0) return false;
    p += r;
    n -= static_cast<size_t>(r);
  }
  return true;
}

// GDCM asserts (abort) on some malformed files; a file's bytes must never end the process. Each
// slice is therefore decoded in a child process that sends back the slice or the error text;
// a child that dies is reported as one InputError naming the file.
// SOFTATLAS_DICOM_IN_PROCESS=1 decodes in this process (the fuzz targets set it, so that the
// fuzzer sees the decoder's coverage and its crashes).
bool read_dicom_slice(const fs::path& f, DicomSlice* s) {
  static const bool in_process = [] {
    const char* e = std::getenv("SOFTATLAS_DICOM_IN_PROCESS");
    return e && std::string(e) == "1";
  }();
  int fds[2];
  if (in_process || ::pipe(fds) != 0) return decode_dicom_slice(f, s);
  std::fflush(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) {
    ::close(fds[0]);
    ::close(fds[1]);
    return decode_dicom_slice(f, s);
  }
  if (pid == 0) {
    ::close(fds[0]);
    // The decoder's own messages (an assertion text, GDCM's console) are not the user's error.
    if (const int devnull = ::open("/dev/null", O_WRONLY); devnull >= 0) {
      ::dup2(devnull, 1);
      ::dup2(devnull, 2);
    }
    int32_t status = 0;
    std::string msg;
    DicomSlice out;
    try {
      status = decode_dicom_slice(f, &out) ? 0 : 2;
    } catch (const InputError& e) {
      status = 1;
      msg = e.problem();
    } catch (const std::exception& e) {
      status = 1;
      msg = std::string("not a readable DICOM image (") + e.what() + ")";
    }
    const uint64_t len = status == 1 ? msg.size() : out.pixels.size();
    bool ok = write_all(fds[1], &status, sizeof status) && write_all(fds[1], &len, sizeof len);
    if (status == 1) {
      ok = ok && write_all(fds[1], msg.data(), msg.size());
    } else if (status == 0) {
      ok = ok && write_all(fds[1], &out.nx, sizeof out.nx) && write_all(fds[1], &out.ny, sizeof out.ny) &&
           write_all(fds[1], out.ipp.data(), sizeof out.ipp) && write_all(fds[1], out.iop.data(), sizeof out.iop) &&
           write_all(fds[1], out.spacing.data(), sizeof out.spacing) &&
           write_all(fds[1], out.pixels.data(), out.pixels.size() * sizeof(float));
    }
    ::close(fds[1]);
    ::_exit(ok ? 0 : 3);
  }
  ::close(fds[1]);
  int32_t status = -1;
  uint64_t len = 0;
  bool got =
      read_all(fds[0], &status, sizeof status) && read_all(fds[0], &len, sizeof len) && len <= (uint64_t{1} << 30);
  std::string msg;
  if (got && status == 1) {
    msg.resize(len);
    got = read_all(fds[0], msg.data(), len);
  } else if (got && status == 0) {
    s->pixels.resize(len);
    got = read_all(fds[0], &s->nx, sizeof s->nx) && read_all(fds[0], &s->ny, sizeof s->ny) &&
          read_all(fds[0], s->ipp.data(), sizeof s->ipp) && read_all(fds[0], s->iop.data(), sizeof s->iop) &&
          read_all(fds[0], s->spacing.data(), sizeof s->spacing) &&
          read_all(fds[0], s->pixels.data(), len * sizeof(float)) &&
          len == static_cast<uint64_t>(s->nx) * static_cast<uint64_t>(s->ny);
  }
  ::close(fds[0]);
  int wstatus = 0;
  while (::waitpid(pid, &wstatus, 0) < 0 && errno == EINTR) {}
  if (!got || !WIFEXITED(wstatus) || WEXITSTATUS(wstatus) != 0) {
    const std::string how = WIFSIGNALED(wstatus) ? "signal " + std::to_string(WTERMSIG(wstatus))
                                                 : "exit " + std::to_string(WEXITSTATUS(wstatus));
    throw InputError(f.string(), "not a readable DICOM image (the DICOM decoder failed on it: " + how + ")");
  }
  if (status == 1) throw InputError(f.string(), io::printable_text(msg, 200));
  return status == 0;
}

Volume read_dicom_series(const std::string& path) {
  const fs::path folder = fs::is_directory(path) ? fs::path(path) : fs::path(path).parent_path();
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(folder))
    if (e.is_regular_file()) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  if (files.empty()) throw InputError(path, "no DICOM files in the folder");
  // GDCM prints warnings and errors to the console; they are kept, and a failed read becomes
  // one InputError naming the file.
  static std::ostringstream gdcm_log;
  gdcm::Trace::SetStream(gdcm_log);
  gdcm::Trace::WarningOff();
  gdcm::Trace::ErrorOff();
  gdcm::Trace::DebugOff();
  using Slice = DicomSlice;
  std::vector<Slice> slices;
  int nx = 0, ny = 0;
  std::array<double, 6> iop{};
  std::array<double, 2> pixel_spacing{};
  for (const auto& f : files) {
    // Slices are grouped by folder, not by SeriesInstanceUID: anonymised files may have it empty.
    Slice s;
    if (!read_dicom_slice(f, &s)) continue;
    if (slices.empty()) {
      nx = s.nx;
      ny = s.ny;
      iop = s.iop;
      pixel_spacing = s.spacing;
    } else if (s.nx != nx || s.ny != ny) {
      throw InputError(f.string(), "slice size " + std::to_string(s.nx) + "x" + std::to_string(s.ny) +
                                       " differs from the series (" + std::to_string(nx) + "x" + std::to_string(ny) +
                                       ")");
    }
    gdcm_log.str("");
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

namespace {

// What every reader's result must satisfy before the pipeline uses it: a complete grid, finite
// voxel values, and a geometry within sane limits (each voxel axis 0.001..1000 mm long, the
// grid within 10 m of the origin): a far-off corner or a 1e30 spacing would make the surface
// stages run for minutes.
Volume checked(Volume v) {
  const std::string& path = v.path;
  const size_t n = static_cast<size_t>(v.dims[0]) * v.dims[1] * v.dims[2];
  if (v.dims[0] < 1 || v.dims[1] < 1 || v.dims[2] < 1 || v.values.size() != n)
    throw InputError(path, "incomplete volume (voxel count does not match the dimensions)");
  for (size_t i = 0; i < n; ++i)
    if (!std::isfinite(v.values[i]))
      throw InputError(path, "voxel " + std::to_string(i) + " is not a finite number (NaN or inf)");
  const auto& a = v.ijk_to_ras;
  for (double x : a)
    if (!std::isfinite(x)) throw InputError(path, "the image-to-world transform is not finite (NaN or inf)");
  for (int c = 0; c < 3; ++c) {
    const double len = std::sqrt(a[c] * a[c] + a[4 + c] * a[4 + c] + a[8 + c] * a[8 + c]);
    if (!(len >= kMinSpacingMm && len <= kMaxSpacingMm))
      throw InputError(path, std::string("voxel spacing along ") + "ijk"[c] + " is " + std::to_string(len) +
                                 " mm, expected 0.001..1000 mm");
  }
  if (!(v.voxel_volume_mm3() > 1e-12))
    throw InputError(path, "the voxel axes are not independent (singular transform)");
  const auto b = v.world_bounds();
  for (double x : b)
    if (!(std::abs(x) <= kMaxWorldMm))
      throw InputError(path, "the volume reaches " + std::to_string(x) + " mm from the origin (more than 10 m)");
  return v;
}

}  // namespace

Volume read_volume(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError(io::printable_text(path, 300), "file not found");
  const std::string l = lower(path);
  if (fs::is_directory(path, ec)) return checked(read_dicom_series(path));
  if (ends_with(l, ".nii") || ends_with(l, ".nii.gz")) return checked(read_nifti(path));
  if (ends_with(l, ".nrrd") || ends_with(l, ".nhdr")) return checked(read_nrrd(path));
  if (ends_with(l, ".mha") || ends_with(l, ".mhd")) return checked(read_metaimage(path));
  if (ends_with(l, ".dcm") || looks_like_dicom(path)) return checked(read_dicom_series(path));
  throw InputError(path,
                   "unknown volume format (expected .nii, .nii.gz, .nrrd, .nhdr, .mha, "
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
  const int16_t dim[8] = {3,
                          static_cast<int16_t>(labels.dims[0]),
                          static_cast<int16_t>(labels.dims[1]),
                          static_cast<int16_t>(labels.dims[2]),
                          1,
                          1,
                          1,
                          1};
  std::memcpy(h + 40, dim, 16);
  put_i16(70, u8 ? 2 : 4);   // DT_UINT8 or DT_INT16
  put_i16(72, u8 ? 8 : 16);  // bitpix
  const auto& a = labels.ijk_to_ras;
  float pixdim[8] = {1, 1, 1, 1, 1, 1, 1, 1};
  for (int c = 0; c < 3; ++c)
    pixdim[c + 1] = static_cast<float>(std::sqrt(a[c] * a[c] + a[4 + c] * a[4 + c] + a[8 + c] * a[8 + c]));
  std::memcpy(h + 76, pixdim, 32);
  put_f32(108, 352.0f);  // vox_offset
  put_f32(112, 1.0f);    // scl_slope
  h[123] = 2;            // xyzt_units: mm
  std::snprintf(reinterpret_cast<char*>(h + 148), 80, "softatlas segment");
  put_i16(252, 0);  // qform_code: unset; the sform carries the full affine
  put_i16(254, 1);  // sform_code: scanner anatomical
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
