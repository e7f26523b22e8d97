// Stage 1 (read): world coordinates against header values stated independently in the shared
// data README, DICOM slab against its NIfTI twin voxel by voxel, NRRD/MetaImage headers written
// here by hand, truncated and corrupt files.
#include <gtest/gtest.h>
#include <zlib.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include "softatlas/pipeline/label_table.hpp"
#include "softatlas/pipeline/volume.hpp"
#include "softatlas/sim/error.hpp"
#include "test_util.hpp"

namespace softatlas::pipeline {
namespace {
using test::abdomen;
using test::chest;

TEST(VolumeIo, NiftiSformGivesRasWorldMillimetres) {
  const Volume v = read_volume(chest("ct_heart_crop.nii.gz"));
  EXPECT_EQ(v.dims, (std::array<int, 3>{122, 102, 112}));
  // README: sform diag(-1.5, -1.5, 1.5), origin (71.66, 255.66, 576.2).
  const auto p0 = v.world(0, 0, 0);
  EXPECT_NEAR(p0[0], 71.658203125, 1e-4);
  EXPECT_NEAR(p0[1], 255.658203125, 1e-4);
  EXPECT_NEAR(p0[2], 576.2, 1e-4);
  const auto p1 = v.world(10, 20, 30);
  EXPECT_NEAR(p1[0], 71.658203125 - 15.0, 1e-4);
  EXPECT_NEAR(p1[1], 255.658203125 - 30.0, 1e-4);
  EXPECT_NEAR(p1[2], 576.2 + 45.0, 1e-4);
  EXPECT_NEAR(v.voxel_volume_mm3(), 3.375, 1e-9);
  const auto back = v.voxel(p1);
  EXPECT_NEAR(back[0], 10, 1e-9);
  EXPECT_NEAR(back[2], 30, 1e-9);
}

TEST(VolumeIo, HeartOnLargerGridIsOffsetByTheStatedVoxels) {
  const Volume big = read_volume(chest("heart.nii.gz"));
  const Volume crop = read_volume(chest("heart_on_ct_heart_crop_grid.nii.gz"));
  EXPECT_EQ(big.dims, (std::array<int, 3>{233, 167, 191}));
  // README: same spacing, offset by exactly (72, 13, 24) voxels; the crop is lossless.
  const auto a = big.world(72, 13, 24), b = crop.world(0, 0, 0);
  for (int d = 0; d < 3; ++d) EXPECT_NEAR(a[d], b[d], 1e-4);
  size_t n_big = 0, n_crop = 0;
  for (float x : big.values) n_big += x != 0;
  for (float x : crop.values) n_crop += x != 0;
  EXPECT_EQ(n_big, 198176u);
  EXPECT_EQ(n_crop, 198176u);
  for (int k = 0; k < crop.dims[2]; k += 7)
    for (int j = 0; j < crop.dims[1]; j += 5)
      for (int i = 0; i < crop.dims[0]; i += 3)
        ASSERT_EQ(crop.values[crop.index(i, j, k)], big.values[big.index(i + 72, j + 13, k + 24)]);
}

TEST(VolumeIo, DicomSlabMatchesItsNiftiTwinVoxelByVoxel) {
  // JPEG 2000, empty UIDs, instance numbers running against z: must equal the derived NIfTI
  // (HU = stored - 1024) at the same world position.
  const Volume dcm = read_volume(abdomen("dicom"));
  const Volume nii = read_volume(abdomen("ct_from_dicom.nii.gz"));
  ASSERT_EQ(dcm.dims, (std::array<int, 3>{512, 512, 20}));
  EXPECT_EQ(dcm.format, "dicom");
  size_t compared = 0, equal = 0;
  for (int k = 0; k < 20; ++k)
    for (int j = 0; j < 512; j += 3)
      for (int i = 0; i < 512; i += 3) {
        const auto w = dcm.world(i, j, k);
        const auto v = nii.voxel(w);
        const long a = std::lround(v[0]), b = std::lround(v[1]), c = std::lround(v[2]);
        ASSERT_NEAR(v[0], a, 1e-3);
        ASSERT_NEAR(v[1], b, 1e-3);
        ASSERT_NEAR(v[2], c, 1e-3);
        ASSERT_TRUE(a >= 0 && b >= 0 && c >= 0 && a < 512 && b < 512 && c < 20);
        ++compared;
        equal += dcm.values[dcm.index(i, j, k)] == nii.values[nii.index(int(a), int(b), int(c))];
      }
  EXPECT_EQ(equal, compared);
  // README: z runs from -804.5 to -766.5 mm.
  const auto b = dcm.world_bounds();
  EXPECT_NEAR(b[2], -804.5, 1e-3);
  EXPECT_NEAR(b[5], -766.5, 1e-3);
  float lo = 1e9f, hi = -1e9f;
  for (float x : dcm.values) lo = std::min(lo, x), hi = std::max(hi, x);
  EXPECT_EQ(lo, -1024.0f);
  EXPECT_EQ(hi, 1839.0f);
}

TEST(VolumeIo, NrrdAndMetaImageGeometryFromHandWrittenHeaders) {
  test::Scratch tmp;
  // 3x2x2 int16 ramp; LPS directions with a rotation about z and a shear-free spacing.
  std::string raw;
  for (int16_t x = 0; x < 12; ++x) raw.append(reinterpret_cast<const char*>(&x), 2);
  {
    std::ofstream f(tmp("a.nrrd"), std::ios::binary);
    f << "NRRD0004\ntype: short\ndimension: 3\nspace: left-posterior-superior\nsizes: 3 2 2\n"
         "space directions: (0,2,0) (-2,0,0) (0,0,3)\nkinds: domain domain domain\nendian: little\n"
         "encoding: raw\nspace origin: (10,20,30)\n\n"
      << raw;
  }
  const Volume n = read_volume(tmp("a.nrrd"));
  ASSERT_EQ(n.dims, (std::array<int, 3>{3, 2, 2}));
  EXPECT_EQ(n.values[n.index(2, 1, 1)], 11.0f);
  // LPS (10,20,30) + 1*(0,2,0) + 1*(-2,0,0) + 1*(0,0,3) = (8,22,33) -> RAS (-8,-22,33).
  auto w = n.world(1, 1, 1);
  EXPECT_NEAR(w[0], -8, 1e-9);
  EXPECT_NEAR(w[1], -22, 1e-9);
  EXPECT_NEAR(w[2], 33, 1e-9);
  {
    std::ofstream f(tmp("a.mha"), std::ios::binary);
    f << "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
         "TransformMatrix = 0 1 0 -1 0 0 0 0 1\nOffset = 10 20 30\nElementSpacing = 2 2 3\n"
         "DimSize = 3 2 2\nElementType = MET_SHORT\nElementDataFile = LOCAL\n"
      << raw;
  }
  const Volume m = read_volume(tmp("a.mha"));
  EXPECT_EQ(m.values[m.index(2, 1, 1)], 11.0f);
  w = m.world(1, 1, 1);
  EXPECT_NEAR(w[0], -8, 1e-9);
  EXPECT_NEAR(w[1], -22, 1e-9);
  EXPECT_NEAR(w[2], 33, 1e-9);
}

std::string slurp_gz_raw(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

TEST(VolumeIo, TruncatedAndCorruptFilesNameTheFile) {
  test::Scratch tmp;
  const std::string full = slurp_gz_raw(chest("pulmonary_artery.nii.gz"));
  { std::ofstream(tmp("cut.nii.gz"), std::ios::binary) << full.substr(0, full.size() / 2); }
  try {
    read_volume(tmp("cut.nii.gz"));
    FAIL() << "truncated file was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cut.nii.gz"), std::string::npos) << e.what();
  }
  { std::ofstream(tmp("junk.nii"), std::ios::binary) << std::string(400, 'x'); }
  EXPECT_THROW(read_volume(tmp("junk.nii")), InputError);
  EXPECT_THROW(read_volume(tmp("missing.nii.gz")), InputError);
  { std::ofstream(tmp("x.txt")) << "hello"; }
  EXPECT_THROW(read_volume(tmp("x.txt")), InputError);
  // A truncated DICOM slice.
  const std::string slice = slurp_gz_raw(abdomen("dicom/CT.1.3.12.2.1107.5.1.4.60064.30000022120808113428000016573"));
  std::filesystem::create_directories(tmp("dcm"));
  std::ofstream(tmp("dcm/a.dcm"), std::ios::binary) << slice.substr(0, slice.size() / 3);
  EXPECT_THROW(read_volume(tmp("dcm")), InputError);
}

// The 12 sform numbers (srow_x, srow_y, srow_z) and the first voxel, read from the file's bytes.
std::pair<std::array<float, 12>, int> raw_sform_and_first_voxel(const std::string& path, int datatype_bytes) {
  gzFile f = gzopen(path.c_str(), "rb");
  unsigned char h[352];
  EXPECT_EQ(gzread(f, h, 352), 352);
  std::array<float, 12> srow{};
  std::memcpy(srow.data(), h + 280, 48);
  int first = 0;
  EXPECT_EQ(gzread(f, &first, datatype_bytes), datatype_bytes);
  gzclose(f);
  return {srow, first};
}

TEST(VolumeIo, WrittenLabelMapReadsBackOnTheSameGrid) {
  test::Scratch tmp;
  // This map's qform has qfac = -1 (pixdim[0]), for which VTK reverses the slices: the reader
  // undoes that, so voxel indices are the file's and a written map has the input's own header.
  const std::string in = abdomen("example_seg_dicom.nii.gz");
  const Volume v = read_volume(in);
  const auto p = v.world(0, 0, 0);
  EXPECT_NEAR(p[2], -804.5, 1e-4);  // README: z runs from -804.5 (first slice) to -766.5
  write_label_nifti(v, tmp("l.nii.gz"));
  const Volume w = read_volume(tmp("l.nii.gz"));
  ASSERT_EQ(w.dims, v.dims);
  EXPECT_EQ(w.values, v.values);
  for (int c = 0; c < 16; ++c) EXPECT_NEAR(w.ijk_to_ras[c], v.ijk_to_ras[c], 1e-4);
  const auto a = raw_sform_and_first_voxel(in, 1), b = raw_sform_and_first_voxel(tmp("l.nii.gz"), 1);
  for (int c = 0; c < 12; ++c) EXPECT_NEAR(a.first[c], b.first[c], 1e-4) << c;
  EXPECT_EQ(b.second & 0xff, static_cast<int>(v.values[0]));
}

// The shared multi-label map carries TotalSegmentator's table in a Caret XML header extension
// (data README); a single-label mask has none.
TEST(VolumeIo, LabelNamesFromTheNiftiHeaderExtension) {
  const Volume v = read_volume(abdomen("example_seg_dicom.nii.gz"));
  ASSERT_EQ(v.label_names.size(), 117u);
  EXPECT_EQ(v.label_names.at(1), "spleen");
  EXPECT_EQ(v.label_names.at(5), "liver");
  EXPECT_EQ(v.label_names.at(52), "aorta");
  for (const auto& [value, name] : v.label_names) EXPECT_EQ(label_id(name), value) << name;
  EXPECT_TRUE(read_volume(chest("heart.nii.gz")).label_names.empty());
}

TEST(LabelTable, MatchesTheSharedTsv) {
  std::ifstream in(test::shared("ct/totalsegmentator_label_table.tsv"));
  std::string line;
  std::getline(in, line);
  int rows = 0;
  while (std::getline(in, line)) {
    std::istringstream is(line);
    int id;
    std::string name;
    is >> id >> name;
    EXPECT_EQ(label_id(name), id) << name;
    EXPECT_EQ(label_name(id), name);
    ++rows;
  }
  EXPECT_EQ(rows, 117);
  EXPECT_EQ(label_count(), 117);
  EXPECT_EQ(default_face_budget("liver"), 5000);
  EXPECT_EQ(default_face_budget("gallbladder"), 500);
  EXPECT_EQ(default_face_budget("kidney_left"), 800);
}

// ---- mutated headers (issue 17): each refused with one line naming the file and the field ----

std::string gunzip(const std::string& path) {
  gzFile f = gzopen(path.c_str(), "rb");
  std::string out;
  char buf[65536];
  int r;
  while ((r = gzread(f, buf, sizeof(buf))) > 0) out.append(buf, static_cast<size_t>(r));
  gzclose(f);
  return out;
}

template <typename T>
std::string patched(std::string bytes, size_t offset, T value) {
  std::memcpy(bytes.data() + offset, &value, sizeof(T));
  return bytes;
}

// Reads `bytes` written to `name`; expects one InputError line naming the file and `field`.
void expect_refused(const test::Scratch& tmp, const std::string& name, const std::string& bytes,
                    const std::string& field) {
  const std::string path = tmp(name);
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out << bytes;
  }
  try {
    read_volume(path);
    ADD_FAILURE() << name << ": accepted, expected an error naming " << field;
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(path), std::string::npos) << msg;
    EXPECT_NE(msg.find(field), std::string::npos) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    for (unsigned char c : msg) ASSERT_TRUE(c >= 32 && c < 127) << "non-printable byte in: " << msg;
  }
}

TEST(VolumeIo, NiftiHeaderFieldsAreCheckedBeforeVtkReadsThem) {
  test::Scratch tmp;
  const std::string nii = gunzip(chest("pulmonary_artery.nii.gz"));
  ASSERT_GT(nii.size(), 352u);
  const float nan = std::nanf(""), inf = INFINITY;
  struct Case {
    const char* name;
    std::string bytes;
    const char* field;
  };
  const Case cases[] = {
      {"dim0_zero.nii", patched<int16_t>(nii, 40, 0), "dim[0]"},
      {"dim0_huge.nii", patched<int16_t>(nii, 40, 300), "dim[0]"},
      {"dim1_zero.nii", patched<int16_t>(nii, 42, 0), "dim[1]"},
      {"dim2_negative.nii", patched<int16_t>(nii, 44, -7), "dim[2]"},
      {"dim3_huge.nii", patched<int16_t>(nii, 46, 32767), "truncated"},
      {"dim4_many.nii", patched<int16_t>(patched<int16_t>(nii, 40, 4), 48, 9), "dim[4]"},
      {"datatype.nii", patched<int16_t>(nii, 70, 999), "datatype"},
      {"rgb.nii", patched<int16_t>(nii, 70, 128), "datatype"},
      {"bitpix.nii", patched<int16_t>(nii, 72, 3), "bitpix"},
      {"vox_offset_zero.nii", patched<float>(nii, 108, 0.0f), "vox_offset"},
      {"vox_offset_huge.nii", patched<float>(nii, 108, 1e30f), "vox_offset"},
      {"vox_offset_nan.nii", patched<float>(nii, 108, nan), "vox_offset"},
      {"vox_offset_frac.nii", patched<float>(nii, 108, 352.5f), "vox_offset"},
      {"pixdim_zero.nii", patched<float>(nii, 80, 0.0f), "pixdim[1]"},
      {"pixdim_1e30.nii", patched<float>(nii, 88, 1e30f), "pixdim[3]"},
      {"pixdim_nan.nii", patched<float>(nii, 84, nan), "pixdim[2]"},
      {"scl_inter_inf.nii", patched<float>(nii, 116, inf), "scl_inter"},
      {"scl_slope_nan.nii", patched<float>(nii, 112, nan), "scl_slope"},
      {"srow_inf.nii", patched<int16_t>(patched<float>(nii, 280, inf), 254, 1), "srow_x"},
      {"srow_far.nii", patched<int16_t>(patched<float>(nii, 324, -2147483649.0f), 254, 1), "srow_z"},
      {"quatern.nii", patched<int16_t>(patched<float>(nii, 256, 3.0f), 252, 1), "quatern"},
      {"qoffset_nan.nii", patched<int16_t>(patched<float>(nii, 276, nan), 252, 1), "qoffset"},
      {"sizeof_hdr.nii", patched<int32_t>(nii, 0, 1000), "sizeof_hdr"},
      {"magic.nii", patched<char>(nii, 345, 'x'), "magic"},
      {"sform_code.nii", patched<int16_t>(nii, 254, -3), "sform_code"},
      {"truncated.nii", nii.substr(0, nii.size() - 1), "truncated"},
      {"header_only.nii", nii.substr(0, 200), "header"},
  };
  for (const Case& c : cases) expect_refused(tmp, c.name, c.bytes, c.field);
  // The same through gzip: a stream cut short, and a corrupt stream.
  const std::string gz = slurp_gz_raw(chest("pulmonary_artery.nii.gz"));
  expect_refused(tmp, "cut.nii.gz", gz.substr(0, gz.size() - 40), "truncated");
  std::string flipped = gz;
  flipped[gz.size() / 2] = static_cast<char>(flipped[gz.size() / 2] ^ 0x5a);
  expect_refused(tmp, "flipped.nii.gz", flipped, "compressed");
}

// The Caret/CIFTI label table is read by an XML parser: long, deep or broken text is an error or
// ignored, never a stack overflow (std::regex recursed once per character).
TEST(VolumeIo, LabelTableExtensionIsReadByAnXmlParser) {
  test::Scratch tmp;
  Volume v = read_volume(chest("pulmonary_artery.nii.gz"));
  write_label_nifti(v, tmp("plain.nii"));
  std::string nii;
  {
    std::ifstream in(tmp("plain.nii"), std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    nii = ss.str();
  }
  auto with_extension = [&](std::string xml) {
    while ((xml.size() + 8) % 16) xml += '\0';
    std::string out = nii.substr(0, 348);
    out += std::string("\1\0\0\0", 4);
    const int32_t esize = static_cast<int32_t>(xml.size() + 8), ecode = 30;
    out.append(reinterpret_cast<const char*>(&esize), 4);
    out.append(reinterpret_cast<const char*>(&ecode), 4);
    out += xml;
    const float vox = static_cast<float>(out.size());
    std::memcpy(out.data() + 108, &vox, 4);
    return out + nii.substr(352);
  };
  // A valid table: names and keys as written, CDATA or text.
  {
    std::ofstream(tmp("named.nii"), std::ios::binary) << with_extension(
        "<CIFTI><LabelTable><Label Key=\"5\" Red=\"1\"><![CDATA[liver]]></Label>"
        "<Label Key=\"52\">aorta </Label><Label Key=\"0\">unknown</Label></LabelTable></CIFTI>");
    const Volume named = read_volume(tmp("named.nii"));
    ASSERT_EQ(named.label_names.size(), 2u);
    EXPECT_EQ(named.label_names.at(5), "liver");
    EXPECT_EQ(named.label_names.at(52), "aorta");
  }
  // 200,000 characters of an unclosed CDATA name, and 100,000 nested elements.
  std::string long_name = "<LabelTable><Label Key=\"1\"><![CDATA[" + std::string(200000, 'x');
  std::string deep = "<LabelTable>";
  for (int i = 0; i < 100000; ++i) deep += "<a>";
  for (const std::string& xml :
       {long_name, deep, std::string("<LabelTable><Label Key=\"12abc\">x</Label></LabelTable>"),
        std::string("<LabelTable><Label Key=\"99999999999\">x</Label></LabelTable>")})
    expect_refused(tmp, "bad_table.nii", with_extension(xml), "LabelTable");
  // An extension whose size runs past vox_offset.
  std::string bad_size = with_extension("<LabelTable></LabelTable>");
  const int32_t huge = 1 << 30;
  std::memcpy(bad_size.data() + 352, &huge, 4);
  expect_refused(tmp, "bad_ext.nii", bad_size, "extension");
}

TEST(VolumeIo, NrrdAndMetaImageHeadersAreStrict) {
  test::Scratch tmp;
  const std::string body(6 * 5 * 4 * 2, '\1');
  auto nrrd = [&](const std::string& fields) {
    return "NRRD0004\ntype: short\ndimension: 3\nspace: left-posterior-superior\nsizes: 6 5 4\n"
           "endian: little\nencoding: raw\n" +
           fields + "\n" + body;
  };
  expect_refused(tmp, "nan_dir.nrrd", nrrd("space directions: (nan,0,0) (0,1,0) (0,0,1)\n"), "space directions");
  expect_refused(tmp, "inf_origin.nrrd", nrrd("space origin: (0,inf,0)\n"), "space origin");
  expect_refused(tmp, "far_origin.nrrd", nrrd("space origin: (0,0,-2147483649)\n"), "10 m");
  expect_refused(tmp, "huge_spacing.nrrd", nrrd("space directions: (1,0,0) (0,1,0) (0,0,1e30)\n"), "spacing");
  expect_refused(tmp, "short.nrrd", nrrd("").substr(0, nrrd("").size() - 3), "truncated");
  std::string huge_sizes = nrrd("");
  huge_sizes.replace(huge_sizes.find("sizes: 6 5 4"), 12, "sizes: 99999 99999 99999");
  expect_refused(tmp, "huge.nrrd", huge_sizes, "sizes");
  std::string text_sizes = nrrd("");
  text_sizes.replace(text_sizes.find("sizes: 6 5 4"), 12, "sizes: 6 5x 4");
  expect_refused(tmp, "text.nrrd", text_sizes, "sizes");
  expect_refused(tmp, "no_blank.nrrd", std::string("NRRD0004\ntype: short\n") + std::string(70000, 'a'), "header");
  auto mha = [&](const std::string& fields) {
    return "ObjectType = Image\nNDims = 3\nBinaryData = True\nCompressedData = False\nDimSize = 6 5 4\n"
           "ElementType = MET_SHORT\n" +
           fields + "ElementDataFile = LOCAL\n" + body;
  };
  expect_refused(tmp, "cut.mha", mha("").substr(0, mha("").size() - 1), "truncated");
  expect_refused(tmp, "nan_spacing.mha", mha("ElementSpacing = 1 nan 1\n"), "ElementSpacing");
  expect_refused(tmp, "zero_spacing.mha", mha("ElementSpacing = 1 0 1\n"), "spacing");
  expect_refused(tmp, "inf_offset.mha", mha("Offset = 0 0 inf\n"), "Offset");
  expect_refused(tmp, "ndims.mha", mha("").replace(mha("").find("NDims = 3"), 9, "NDims = 0"), "NDims");
  expect_refused(tmp, "type.mha", mha("").replace(mha("").find("MET_SHORT"), 9, "MET_XYZZY"), "ElementType");
  expect_refused(tmp, "list.mha", mha("").replace(mha("").find("LOCAL"), 5, "LIST"), "ElementDataFile");
  expect_refused(tmp, "channels.mha", mha("ElementNumberOfChannels = 3\n"), "ElementNumberOfChannels");
  // A valid compressed MetaImage still reads, with LPS geometry.
  const std::string ok = mha("ElementSpacing = 0.5 0.5 2\nOffset = 10 20 30\n");
  std::ofstream(tmp("ok.mha"), std::ios::binary) << ok;
  const Volume v = read_volume(tmp("ok.mha"));
  EXPECT_EQ(v.dims, (std::array<int, 3>{6, 5, 4}));
  EXPECT_DOUBLE_EQ(v.ijk_to_ras[0], -0.5);
  EXPECT_DOUBLE_EQ(v.ijk_to_ras[3], -10.0);
  EXPECT_DOUBLE_EQ(v.ijk_to_ras[11], 30.0);
  EXPECT_FLOAT_EQ(v.values[0], 257.0f);
}

}  // namespace
}  // namespace softatlas::pipeline
