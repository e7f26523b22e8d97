// Every bad input of the issue: one InputError naming the file or organ, and no output folder.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "softatlas/pipeline/cli.hpp"
#include "softatlas/pipeline/volume.hpp"
#include "softatlas/sim/error.hpp"
#include "test_util.hpp"

namespace softatlas::pipeline {
namespace {
using test::abdomen;
using test::chest;
namespace fs = std::filesystem;

// Runs the command, expects InputError whose message contains `needle`, and no output folder.
void expect_rejected(const std::vector<std::string>& args, const std::string& out, const std::string& needle) {
  try {
    cli_main(args);
    ADD_FAILURE() << "accepted bad input, expected an error naming " << needle;
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(needle), std::string::npos) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << "one line: " << msg;
  }
  EXPECT_FALSE(fs::exists(out)) << "output left behind: " << out;
  // No temporary sibling left either.
  for (const auto& e : fs::directory_iterator(fs::path(out).parent_path()))
    EXPECT_EQ(e.path().filename().string().find(fs::path(out).filename().string()), std::string::npos)
        << e.path();
}

std::vector<std::string> chest_build(const std::string& ct, const std::string& labels, const std::string& out) {
  return {"build", ct, "--labels", labels, "-q", "-o", out};
}

TEST(BadInput, TruncatedCt) {
  test::Scratch tmp;
  std::ifstream in(chest("ct_heart_crop.nii.gz"), std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  std::ofstream(tmp("ct.nii.gz"), std::ios::binary) << ss.str().substr(0, ss.str().size() * 2 / 3);
  expect_rejected(chest_build(tmp("ct.nii.gz"), "heart=" + chest("heart_on_ct_heart_crop_grid.nii.gz"), tmp("out")),
                  tmp("out"), "ct.nii.gz");
}

TEST(BadInput, LabelMapWithNoLabels) {
  test::Scratch tmp;
  Volume v = read_volume(chest("pulmonary_artery.nii.gz"));
  std::fill(v.values.begin(), v.values.end(), 0.0f);
  write_label_nifti(v, tmp("empty.nii.gz"));
  expect_rejected(chest_build(chest("ct_heart_crop.nii.gz"), tmp("empty.nii.gz"), tmp("out")), tmp("out"),
                  "empty.nii.gz");
}

TEST(BadInput, RequestedOrganAbsentFromTheLabelMap) {
  test::Scratch tmp;
  expect_rejected({"build", abdomen("ct_from_dicom.nii.gz"), "--labels", abdomen("example_seg_dicom.nii.gz"),
                   "--organs", "liver,kidney_left", "-q", "-o", tmp("out")},
                  tmp("out"), "kidney_left");
}

TEST(BadInput, UnknownOrganName) {
  test::Scratch tmp;
  expect_rejected({"build", abdomen("ct_from_dicom.nii.gz"), "--labels", abdomen("example_seg_dicom.nii.gz"),
                   "--organs", "livr", "-q", "-o", tmp("out")},
                  tmp("out"), "livr");
}

TEST(BadInput, LabelGridThatDoesNotOverlapTheCt) {
  test::Scratch tmp;
  Volume v = read_volume(chest("pulmonary_artery.nii.gz"));
  v.ijk_to_ras[11] += 1000.0;  // 1 m up
  write_label_nifti(v, tmp("far.nii.gz"));
  expect_rejected(chest_build(chest("ct_heart_crop.nii.gz"), "pulmonary_artery=" + tmp("far.nii.gz"), tmp("out")),
                  tmp("out"), "far.nii.gz");
}

TEST(BadInput, BudgetBelowAClosedSurface) {
  test::Scratch tmp;
  auto args = chest_build(chest("ct_heart_crop.nii.gz"), "pulmonary_artery=" + chest("pulmonary_artery.nii.gz"), tmp("out"));
  args.insert(args.end(), {"--budget", "pulmonary_artery=3"});
  expect_rejected(args, tmp("out"), "pulmonary_artery");
}

TEST(BadInput, MeshWithNaNs) {
  test::Scratch tmp;
  std::ofstream(tmp("liver.obj")) << "v 0 0 0\nv 1 0 0\nv 0 nan 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 2 3 4\nf 1 3 4\n";
  expect_rejected({"build", "--mesh", tmp("liver.obj"), "-q", "-o", tmp("out")}, tmp("out"), "liver.obj");
}

TEST(BadInput, MeshWithNonManifoldEdges) {
  test::Scratch tmp;
  // Three triangles on the edge (1,2).
  std::ofstream(tmp("stomach.obj")) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n";
  expect_rejected({"build", "--mesh", tmp("stomach.obj"), "-q", "-o", tmp("out")}, tmp("out"), "non-manifold");
}

TEST(BadInput, OutputFolderThatExists) {
  test::Scratch tmp;
  fs::create_directories(tmp("out"));
  try {
    cli_main(chest_build(chest("ct_heart_crop.nii.gz"), "pulmonary_artery=" + chest("pulmonary_artery.nii.gz"), tmp("out")));
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("already exists"), std::string::npos);
  }
  EXPECT_TRUE(fs::is_empty(tmp("out")));
}

TEST(BadInput, MalformedBudgetAndMissingSeeds) {
  test::Scratch tmp;
  auto args = chest_build(chest("ct_heart_crop.nii.gz"), "pulmonary_artery=" + chest("pulmonary_artery.nii.gz"), tmp("out"));
  args.insert(args.end(), {"--budget", "pulmonary_artery=lots"});
  expect_rejected(args, tmp("out"), "--budget pulmonary_artery");
  expect_rejected({"build", chest("ct_heart_crop.nii.gz"), "--seeds", tmp("none.yaml"), "-q", "-o", tmp("out")},
                  tmp("out"), "none.yaml");
}

}  // namespace
}  // namespace softatlas::pipeline
