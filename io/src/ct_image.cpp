// SET/ct.nii.gz: a small NIfTI-1 writer and reader for the organ set's CT (docs/organ-set.md).
#include "softatlas/io/ct_image.hpp"

#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>

#include "softatlas/io/mesh_io.hpp"
#include "softatlas/sim/error.hpp"

namespace softatlas::io {

std::array<double, 3> CtImage::world(double i, double j, double k) const {
  const auto& a = ijk_to_ras;
  return {a[0] * i + a[1] * j + a[2] * k + a[3], a[4] * i + a[5] * j + a[6] * k + a[7],
          a[8] * i + a[9] * j + a[10] * k + a[11]};
}

std::array<double, 3> CtImage::voxel(const std::array<double, 3>& p) const {
  const auto& a = ijk_to_ras;
  const double m00 = a[0], m01 = a[1], m02 = a[2], m10 = a[4], m11 = a[5], m12 = a[6], m20 = a[8], m21 = a[9],
               m22 = a[10];
  const double det = m00 * (m11 * m22 - m12 * m21) - m01 * (m10 * m22 - m12 * m20) + m02 * (m10 * m21 - m11 * m20);
  const double q0 = p[0] - a[3], q1 = p[1] - a[7], q2 = p[2] - a[11];
  return {((m11 * m22 - m12 * m21) * q0 + (m02 * m21 - m01 * m22) * q1 + (m01 * m12 - m02 * m11) * q2) / det,
          ((m12 * m20 - m10 * m22) * q0 + (m00 * m22 - m02 * m20) * q1 + (m02 * m10 - m00 * m12) * q2) / det,
          ((m10 * m21 - m11 * m20) * q0 + (m01 * m20 - m00 * m21) * q1 + (m00 * m11 - m01 * m10) * q2) / det};
}

bool CtImage::sample(const std::array<double, 3>& ras, float* out) const {
  const auto v = voxel(ras);
  int i0[3];
  double f[3];
  for (int d = 0; d < 3; ++d) {
    if (!(v[d] >= -0.5 && v[d] <= dims[d] - 0.5)) return false;
    const double c = std::clamp(v[d], 0.0, static_cast<double>(dims[d] - 1));
    i0[d] = std::min(static_cast<int>(std::floor(c)), std::max(dims[d] - 2, 0));
    f[d] = dims[d] > 1 ? c - i0[d] : 0.0;
  }
  auto at = [&](int di, int dj, int dk) {
    const size_t i = std::min(i0[0] + di, dims[0] - 1), j = std::min(i0[1] + dj, dims[1] - 1),
                 k = std::min(i0[2] + dk, dims[2] - 1);
    return static_cast<double>(hu[i + static_cast<size_t>(dims[0]) * (j + static_cast<size_t>(dims[1]) * k)]);
  };
  double s = 0;
  for (int c = 0; c < 8; ++c) {
    const int di = c & 1, dj = (c >> 1) & 1, dk = (c >> 2) & 1;
    s += (di ? f[0] : 1 - f[0]) * (dj ? f[1] : 1 - f[1]) * (dk ? f[2] : 1 - f[2]) * at(di, dj, dk);
  }
  *out = static_cast<float>(s);
  return true;
}

std::array<double, 6> CtImage::world_bounds() const {
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

std::string encode_ct_nifti_gz(const CtImage& ct) {
  unsigned char h[352] = {};
  auto put_i32 = [&](int off, int32_t x) { std::memcpy(h + off, &x, 4); };
  auto put_i16 = [&](int off, int16_t x) { std::memcpy(h + off, &x, 2); };
  auto put_f32 = [&](int off, float x) { std::memcpy(h + off, &x, 4); };
  put_i32(0, 348);
  const int16_t dim[8] = {
      3, static_cast<int16_t>(ct.dims[0]), static_cast<int16_t>(ct.dims[1]), static_cast<int16_t>(ct.dims[2]), 1, 1, 1,
      1};
  std::memcpy(h + 40, dim, 16);
  put_i16(70, 4);   // DT_INT16
  put_i16(72, 16);  // bitpix
  const auto& a = ct.ijk_to_ras;
  float pixdim[8] = {1, 1, 1, 1, 1, 1, 1, 1};
  for (int c = 0; c < 3; ++c)
    pixdim[c + 1] = static_cast<float>(std::sqrt(a[c] * a[c] + a[4 + c] * a[4 + c] + a[8 + c] * a[8 + c]));
  std::memcpy(h + 76, pixdim, 32);
  put_f32(108, 352.0f);  // vox_offset
  put_f32(112, 1.0f);    // scl_slope: the values are HU
  h[123] = 2;            // xyzt_units: mm
  std::snprintf(reinterpret_cast<char*>(h + 148), 80, "softatlas organ set CT (HU)");
  put_i16(254, 1);  // sform_code: scanner anatomical; qform unset
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) put_f32(280 + r * 16 + c * 4, static_cast<float>(a[r * 4 + c]));
  std::memcpy(h + 344, "n+1\0", 4);
  std::string raw(reinterpret_cast<const char*>(h), 352);
  raw.append(reinterpret_cast<const char*>(ct.hu.data()), ct.hu.size() * sizeof(int16_t));
  z_stream zs{};
  if (deflateInit2(&zs, 6, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK)
    throw InputError("ct.nii.gz", "cannot start the gzip compressor");
  std::string out(deflateBound(&zs, raw.size()) + 64, '\0');
  zs.next_in = reinterpret_cast<Bytef*>(raw.data());
  zs.avail_in = static_cast<uInt>(raw.size());
  zs.next_out = reinterpret_cast<Bytef*>(out.data());
  zs.avail_out = static_cast<uInt>(out.size());
  const int rc = deflate(&zs, Z_FINISH);
  out.resize(zs.total_out);
  deflateEnd(&zs);
  if (rc != Z_STREAM_END) throw InputError("ct.nii.gz", "gzip compression failed");
  return out;
}

CtImage read_ct_nifti(const std::string& path, bool header_only) {
  gzFile f = gzopen(path.c_str(), "rb");
  if (!f) throw InputError(path, std::string("cannot open the CT: ") + std::strerror(errno));
  struct Closer {
    gzFile f;
    ~Closer() { gzclose(f); }
  } closer{f};
  unsigned char h[348] = {};
  if (gzread(f, h, 348) != 348) throw InputError(path, "truncated NIfTI header (expected 348 bytes)");
  bool swap = false;
  int32_t sizeof_hdr;
  std::memcpy(&sizeof_hdr, h, 4);
  if (sizeof_hdr != 348) {
    swap = true;
    sizeof_hdr = static_cast<int32_t>(__builtin_bswap32(static_cast<uint32_t>(sizeof_hdr)));
  }
  if (sizeof_hdr != 348 || std::memcmp(h + 344, "n+1", 4) != 0)
    throw InputError(path, "not a single-file NIfTI-1 image (sizeof_hdr 348, magic 'n+1')");
  auto i16 = [&](int off) {
    uint16_t u;
    std::memcpy(&u, h + off, 2);
    return static_cast<int16_t>(swap ? __builtin_bswap16(u) : u);
  };
  auto f32 = [&](int off) {
    uint32_t u;
    std::memcpy(&u, h + off, 4);
    if (swap) u = __builtin_bswap32(u);
    float x;
    std::memcpy(&x, &u, 4);
    return static_cast<double>(x);
  };
  auto bad = [&](const std::string& field, const std::string& what) { return InputError(path + ": " + field, what); };
  CtImage ct;
  const int nd = i16(40);
  if (nd < 3 || nd > 7) throw bad("dim[0]", "expected a 3-D volume");
  for (int d = 1; d <= nd; ++d) {
    const int n = i16(40 + 2 * d);
    if (d <= 3 && (n < 1 || n > 4096))
      throw bad("dim[" + std::to_string(d) + "]", "expected 1..4096, got " + std::to_string(n));
    if (d > 3 && n != 1) throw bad("dim[" + std::to_string(d) + "]", "expected a 3-D volume (dim[4..7] = 1)");
    if (d <= 3) ct.dims[d - 1] = n;
  }
  const int datatype = i16(70);
  int bytes = 0;
  if (datatype == 2)
    bytes = 1;  // uint8
  else if (datatype == 4)
    bytes = 2;  // int16
  else if (datatype == 8)
    bytes = 4;  // int32
  else if (datatype == 16)
    bytes = 4;  // float32
  else
    throw bad("datatype", "expected int16, uint8, int32 or float32, got " + std::to_string(datatype));
  const double vox_offset = f32(108);
  if (!(vox_offset >= 348 && vox_offset <= 1e6) || vox_offset != std::floor(vox_offset))
    throw bad("vox_offset", "expected a whole number of bytes in 348..1e6");
  double slope = f32(112), inter = f32(116);
  if (!std::isfinite(slope) || !std::isfinite(inter)) throw bad("scl_slope", "rescale must be finite");
  if (slope == 0) slope = 1, inter = 0;
  auto& a = ct.ijk_to_ras;
  if (i16(254) > 0) {
    for (int k = 0; k < 12; ++k) a[k] = f32(280 + 4 * k);
    a[12] = a[13] = a[14] = 0;
    a[15] = 1;
  } else if (i16(252) > 0) {  // qform: quaternion (b, c, d), pixdim, qfac, offset
    const double b = f32(256), c = f32(260), d = f32(264);
    const double aa = std::sqrt(std::max(0.0, 1.0 - (b * b + c * c + d * d)));
    const double qfac = f32(76) < 0 ? -1.0 : 1.0;
    const double R[3][3] = {{aa * aa + b * b - c * c - d * d, 2 * (b * c - aa * d), 2 * (b * d + aa * c)},
                            {2 * (b * c + aa * d), aa * aa + c * c - b * b - d * d, 2 * (c * d - aa * b)},
                            {2 * (b * d - aa * c), 2 * (c * d + aa * b), aa * aa + d * d - c * c - b * b}};
    const double s[3] = {f32(80), f32(84), f32(88) * qfac};
    for (int r = 0; r < 3; ++r) {
      for (int col = 0; col < 3; ++col) a[r * 4 + col] = R[r][col] * s[col];
      a[r * 4 + 3] = f32(268 + 4 * r);
    }
  } else {
    throw bad("sform_code", "neither an sform nor a qform: the CT has no position in patient space");
  }
  for (int k = 0; k < 12; ++k)
    if (!std::isfinite(a[k]) || std::abs(a[k]) > (k % 4 == 3 ? 1e4 : 1e3))
      throw bad("srow", "voxel-to-world transform must be finite (axes <= 1000 mm, origin within 10 m)");
  const double det =
      a[0] * (a[5] * a[10] - a[6] * a[9]) - a[1] * (a[4] * a[10] - a[6] * a[8]) + a[2] * (a[4] * a[9] - a[5] * a[8]);
  if (!(std::abs(det) > 1e-9)) throw bad("srow", "voxel-to-world transform is singular");
  const size_t n = static_cast<size_t>(ct.dims[0]) * ct.dims[1] * ct.dims[2];
  if (n > 512u * 1024u * 1024u) throw bad("dim", "more than 512 M voxels");
  std::string rest(static_cast<size_t>(vox_offset) - 348, '\0');
  if (!rest.empty() && gzread(f, rest.data(), static_cast<unsigned>(rest.size())) != static_cast<int>(rest.size()))
    throw InputError(path, "truncated NIfTI header extension");
  std::vector<unsigned char> data(header_only ? std::min<size_t>(n * bytes, 1) : n * bytes);
  if (header_only) {  // the voxels must be there: the last byte is readable
    if (gzseek(f, static_cast<z_off_t>(vox_offset + n * bytes - 1), SEEK_SET) < 0 || gzread(f, data.data(), 1) != 1)
      throw InputError(path, "truncated CT: the header promises " + std::to_string(n) + " voxels");
    return ct;
  }
  size_t got = 0;
  while (got < data.size()) {
    const unsigned chunk = static_cast<unsigned>(std::min<size_t>(data.size() - got, 1u << 30));
    const int r = gzread(f, data.data() + got, chunk);
    if (r <= 0) break;
    got += static_cast<size_t>(r);
  }
  if (got != data.size())
    throw InputError(
        path, "truncated CT: " + std::to_string(got) + " bytes of voxels, header needs " + std::to_string(data.size()));
  ct.hu.resize(n);
  for (size_t i = 0; i < n; ++i) {
    double x = 0;
    const unsigned char* p = data.data() + i * bytes;
    if (datatype == 2) {
      x = p[0];
    } else if (datatype == 4) {
      uint16_t u;
      std::memcpy(&u, p, 2);
      if (swap) u = __builtin_bswap16(u);
      x = static_cast<int16_t>(u);
    } else {
      uint32_t u;
      std::memcpy(&u, p, 4);
      if (swap) u = __builtin_bswap32(u);
      if (datatype == 8) {
        x = static_cast<int32_t>(u);
      } else {
        float fl;
        std::memcpy(&fl, &u, 4);
        x = std::isfinite(fl) ? fl : -1024.0;
      }
    }
    x = x * slope + inter;
    ct.hu[i] = static_cast<int16_t>(std::lround(std::clamp(x, -32768.0, 32767.0)));
  }
  return ct;
}

}  // namespace softatlas::io
