// Every bad input of the issue: one InputError naming the file or organ, and no output folder.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <thread>

#include "softatlas/io/organ_set.hpp"
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
    EXPECT_EQ(e.path().filename().string().find(fs::path(out).filename().string()), std::string::npos) << e.path();
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
  auto args =
      chest_build(chest("ct_heart_crop.nii.gz"), "pulmonary_artery=" + chest("pulmonary_artery.nii.gz"), tmp("out"));
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
    cli_main(
        chest_build(chest("ct_heart_crop.nii.gz"), "pulmonary_artery=" + chest("pulmonary_artery.nii.gz"), tmp("out")));
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("already exists"), std::string::npos);
  }
  EXPECT_TRUE(fs::is_empty(tmp("out")));
}

TEST(BadInput, MalformedBudgetAndMissingSeeds) {
  test::Scratch tmp;
  auto args =
      chest_build(chest("ct_heart_crop.nii.gz"), "pulmonary_artery=" + chest("pulmonary_artery.nii.gz"), tmp("out"));
  args.insert(args.end(), {"--budget", "pulmonary_artery=lots"});
  expect_rejected(args, tmp("out"), "--budget pulmonary_artery");
  expect_rejected({"build", chest("ct_heart_crop.nii.gz"), "--seeds", tmp("none.yaml"), "-q", "-o", tmp("out")},
                  tmp("out"), "none.yaml");
}

// ---- faults (issue 17) ----

// `build` killed (SIGKILL) at random moments, fixed draws: the output path is then absent or a
// complete organ set, never partial; the hidden .NAME.partial.PID folders of the killed writers
// are removed by the next run.
TEST(Faults, KilledBuildLeavesNothingOrACompleteSetAndTheNextRunCleansUp) {
  test::Scratch tmp;
  const std::string cli = std::string(SOFTATLAS_BINARY_DIR) + "/tests/pipeline/softatlas_pipeline_cli";
  ASSERT_TRUE(fs::exists(cli)) << cli;
  const std::vector<std::string> args = {cli,
                                         "build",
                                         chest("ct_heart_crop.nii.gz"),
                                         "--labels",
                                         "pulmonary_artery=" + chest("pulmonary_artery.nii.gz"),
                                         "-q",
                                         "-o",
                                         tmp("set")};
  auto spawn = [&]() {
    const pid_t pid = fork();
    if (pid == 0) {
      std::vector<char*> argv;
      for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
      argv.push_back(nullptr);
      const int devnull = open("/dev/null", O_WRONLY);
      dup2(devnull, 2);
      execv(cli.c_str(), argv.data());
      _exit(127);
    }
    return pid;
  };
  // One complete run gives the time span to draw kill moments from.
  const auto t0 = std::chrono::steady_clock::now();
  int status = 0;
  waitpid(spawn(), &status, 0);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "reference build failed";
  const double full_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_NO_THROW(io::read_organ_set(tmp("set")));
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> when(0.0, full_s);
  int killed_mid_write = 0;
  for (int draw = 0; draw < 6; ++draw) {
    fs::remove_all(tmp("set"));
    const pid_t pid = spawn();
    std::this_thread::sleep_for(std::chrono::duration<double>(when(rng)));
    kill(pid, SIGKILL);
    waitpid(pid, &status, 0);
    if (fs::exists(tmp("set"))) {
      EXPECT_NO_THROW(io::read_organ_set(tmp("set"))) << "draw " << draw << ": partial organ set at the output path";
    }
    for (const auto& e : fs::directory_iterator(tmp.dir))
      if (e.path().filename().string().rfind(".set.partial.", 0) == 0) ++killed_mid_write;
  }
  // A stale folder of a dead writer, whether or not a draw hit the write itself.
  fs::create_directories(tmp.dir / ".set.partial.2147480000" / "organs");
  fs::remove_all(tmp("set"));
  waitpid(spawn(), &status, 0);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  EXPECT_NO_THROW(io::read_organ_set(tmp("set")));
  for (const auto& e : fs::directory_iterator(tmp.dir))
    EXPECT_NE(e.path().filename().string().rfind(".set.partial.", 0), 0u) << "left behind: " << e.path();
  std::printf("[ faults ] reference build %.2f s, %d partial folders seen after kills\n", full_s, killed_mid_write);
}

// An output folder that cannot be written gives one clean error and leaves nothing behind. As
// root, permissions do not stop a write, so a folder under /proc stands in for a read-only one.
TEST(Faults, UnwritableOutputGivesOneCleanError) {
  test::Scratch tmp;
  std::string parent;
  if (geteuid() == 0) {
    parent = "/proc/softatlas-readonly";
  } else {
    fs::create_directories(tmp.dir / "ro");
    fs::permissions(tmp.dir / "ro", fs::perms::owner_read | fs::perms::owner_exec);
    parent = tmp("ro");
  }
  const std::string out = parent + "/set";
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"build", chest("ct_heart_crop.nii.gz"), "--labels",
                                 "pulmonary_artery=" + chest("pulmonary_artery.nii.gz"), "-q", "-o", out},
        std::vector<std::string>{"export", std::string(SOFTATLAS_SOURCE_DIR) + "/data/atlas", "-o",
                                 parent + "/atlas.glb"}}) {
    try {
      cli_main(args);
      ADD_FAILURE() << args[0] << ": wrote into an unwritable folder";
    } catch (const InputError& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find(parent), std::string::npos) << msg;
      EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    } catch (const std::exception& e) {
      ADD_FAILURE() << args[0] << ": not a clean InputError: " << e.what();
    }
    EXPECT_FALSE(fs::exists(out));
    EXPECT_FALSE(fs::exists(parent + "/atlas.glb"));
  }
  if (geteuid() != 0) fs::permissions(tmp.dir / "ro", fs::perms::owner_all);
}

// Numbers on the command line: the whole token, finite, in range.
TEST(Faults, CommandLineNumbersAreStrict) {
  test::Scratch tmp;
  for (const char* bad : {"nan", "-1", "inf", "1e999", "12abc", "1e308"}) {
    const std::vector<std::string> args = {"build",       chest("ct_heart_crop.nii.gz"),
                                           "--labels",    "pulmonary_artery=" + chest("pulmonary_artery.nii.gz"),
                                           "--stiffness", bad,
                                           "-q",          "-o",
                                           tmp("out")};
    int rc = 0;
    try {
      rc = cli_main(args);
    } catch (const InputError&) {
      rc = 1;
    }
    EXPECT_NE(rc, 0) << "--stiffness " << bad << " accepted";
    EXPECT_FALSE(fs::exists(tmp("out"))) << "--stiffness " << bad;
  }
}

}  // namespace
}  // namespace softatlas::pipeline
