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
  {
    std::ofstream(tmp("cut.nii.gz"), std::ios::binary) << full.substr(0, full.size() / 2);
  }
  try {
    read_volume(tmp("cut.nii.gz"));
    FAIL() << "truncated file was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cut.nii.gz"), std::string::npos) << e.what();
  }
  {
    std::ofstream(tmp("junk.nii"), std::ios::binary) << std::string(400, 'x');
  }
  EXPECT_THROW(read_volume(tmp("junk.nii")), InputError);
  EXPECT_THROW(read_volume(tmp("missing.nii.gz")), InputError);
  {
    std::ofstream(tmp("x.txt")) << "hello";
  }
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

}  // namespace
}  // namespace softatlas::pipeline
