// Writes that fail cleanly (issue 17): every command that writes, run into a read-only folder and
// onto a full disk (a small tmpfs, mounted when the test runs as root), gives exit 1, one error line
// "softatlas: ..." naming the output, and leaves nothing behind (no empty --out, no folder without
// its pictures, no hidden staging folder).
#include <fcntl.h>
#include <sys/mount.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include "run_softatlas.hpp"

#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

std::string data(const std::string& rel) { return std::string(SOFTATLAS_SOURCE_DIR) + "/data/" + rel; }

using softatlas::test::Result;

Result run(const std::vector<std::string>& args, const fs::path& err_file) {
  return softatlas::test::run_softatlas(args, err_file.string());
}

// Every path under dir (relative), hidden ones included.
std::set<std::string> listing(const fs::path& dir) {
  std::set<std::string> out;
  std::error_code ec;
  for (fs::recursive_directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec))
    out.insert(fs::relative(it->path(), dir).string());
  return out;
}

// A scratch folder with a mount point in it; the mount is undone at the end.
struct Scratch {
  fs::path dir, mnt;
  bool mounted = false;
  Scratch() {
    dir = fs::temp_directory_path() / ("softatlas-faults-" + std::to_string(::getpid()) + "-" +
                                       ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir);
    fs::create_directories(dir / "mnt");
    mnt = dir / "mnt";
  }
  ~Scratch() {
    if (mounted) umount2(mnt.c_str(), MNT_DETACH);
    std::error_code ec;
    fs::permissions(mnt, fs::perms::owner_all, ec);
    fs::remove_all(dir, ec);
  }
  // A tmpfs of `bytes` at mnt (read-only if asked); false if this process may not mount.
  bool mount_tmpfs(size_t bytes, bool read_only) {
    const std::string opts = "size=" + std::to_string(bytes) + ",mode=0777";
    if (::mount("tmpfs", mnt.c_str(), "tmpfs", read_only ? MS_RDONLY : 0, opts.c_str()) != 0) return false;
    mounted = true;
    return true;
  }
  // A folder that cannot be written: a read-only tmpfs as root, else mode 0555 (not root).
  void make_read_only() {
    if (::geteuid() == 0) {
      ASSERT_TRUE(mount_tmpfs(1 << 20, true)) << "as root, a read-only tmpfs should mount";
    } else {
      fs::permissions(mnt, fs::perms::owner_read | fs::perms::owner_exec);
    }
  }
};

struct Writer {
  std::string name;
  std::vector<std::string> args_before_out;  // the output path is appended
};

std::vector<Writer> writers() {
  std::vector<Writer> w = {
      {"sim demo", {"sim", "demo", "--hold-steps", "20", "--out"}},
      {"bench accuracy", {"bench", "accuracy", "--grid", "tiny", "--no-paper", "--no-fit", "--out"}},
  };
#ifdef SOFTATLAS_HAVE_PIPELINE
  w.push_back({"build",
               {"build", data("sample/ct_heart_crop.nii.gz"), "--labels",
                "heart=" + data("sample/heart_on_ct_heart_crop_grid.nii.gz"), "-q", "-o"}});
  w.push_back({"export", {"export", data("atlas"), "-o"}});
#endif
#ifdef SOFTATLAS_HAVE_APP
  w.push_back({"lesson run",
               {"lesson", "run", data("lessons/liver_mobility.yaml"), "--device",
                data("lessons/scripts/liver_mobility.pass.yaml"), "--width", "320", "--height", "180", "--out"}});
#endif
  return w;
}

std::string output_name(const Writer& w) { return w.name == "export" ? "atlas.glb" : "out"; }

// Runs w with its output at `place` and checks: exit 1, one line naming the output, and the
// listing of `watched` unchanged.
void expect_clean_failure(const Writer& w, const fs::path& place, const fs::path& watched, const fs::path& err,
                          const std::string& why) {
  const std::set<std::string> before = listing(watched);
  std::vector<std::string> args = w.args_before_out;
  args.push_back(place.string());
  const Result r = run(args, err);
  EXPECT_EQ(r.rc, 1) << w.name << " (" << why << ")\n" << r.err;
  // Progress lines may come first (bench, lesson run); the error is the one last line.
  std::vector<std::string> errors;
  std::istringstream lines(r.err);
  std::string last;
  for (std::string line; std::getline(lines, line); last = line)
    if (line.rfind("softatlas: ", 0) == 0) errors.push_back(line);
  EXPECT_EQ(errors.size(), 1u) << w.name << " (" << why << ")\n" << r.err;
  EXPECT_EQ(last.rfind("softatlas: ", 0), 0u) << w.name << " (" << why << ")\n" << r.err;
  EXPECT_NE(last.find(place.string()), std::string::npos) << w.name << ": the error names the output\n" << r.err;
  EXPECT_EQ(last.find(".partial"), std::string::npos) << w.name << ": names the hidden staging folder\n" << r.err;
  EXPECT_EQ(last.find(".tmp"), std::string::npos) << w.name << ": names a temporary file\n" << r.err;
  EXPECT_EQ(listing(watched), before) << w.name << " (" << why << "): something was left behind";
}

}  // namespace

// One test per writer (ctest runs them side by side; `bench accuracy` computes for a minute under
// the sanitizers before its write fails on the full disk).
class EveryWriter : public ::testing::TestWithParam<std::string> {
 protected:
  Writer writer() const {
    for (const Writer& w : writers())
      if (w.name == GetParam()) return w;
    ADD_FAILURE() << "no writer " << GetParam();
    return {};
  }
};

std::vector<std::string> writer_names() {
  std::vector<std::string> names;
  for (const Writer& w : writers()) names.push_back(w.name);
  return names;
}

// Read-only: found before any work (io::check_writable), so each command fails at once.
TEST_P(EveryWriter, ReadOnlyOutputFolderGivesOneLineAndLeavesNothing) {
  const Writer w = writer();
  Scratch tmp;
  tmp.make_read_only();
  expect_clean_failure(w, tmp.mnt / output_name(w), tmp.mnt, tmp.dir / "err.txt", "read-only folder");
  expect_clean_failure(w, tmp.mnt / "deeper" / output_name(w), tmp.mnt, tmp.dir / "err.txt", "read-only parent");
}

TEST_P(EveryWriter, FullDiskGivesOneLineAndLeavesNothing) {
  if (::geteuid() != 0) GTEST_SKIP() << "mounting a small tmpfs needs root";
  const Writer w = writer();
  // 8 KiB: the staging folder is made, the first large file does not fit.
  Scratch tmp;
  ASSERT_TRUE(tmp.mount_tmpfs(8 << 10, false));
  expect_clean_failure(w, tmp.mnt / output_name(w), tmp.mnt, tmp.dir / "err.txt", "8 KiB disk");
  // Into an existing folder holding a file of its own: that file stays, nothing is added. Build
  // refuses existing folders and export writes a file; every other writer stages through the same
  // io::StagedFolder, so the two quick ones stand for it.
  if (w.name == "sim demo" || w.name == "lesson run") {
    fs::create_directories(tmp.mnt / "existing");
    std::ofstream(tmp.mnt / "existing" / "mine.txt") << "keep me\n";
    expect_clean_failure(w, tmp.mnt / "existing", tmp.mnt, tmp.dir / "err.txt", "8 KiB disk, existing folder");
  }
}

INSTANTIATE_TEST_SUITE_P(WriteFaults, EveryWriter, ::testing::ValuesIn(writer_names()),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           std::string name = info.param;
                           for (char& c : name)
                             if (c == ' ') c = '_';
                           return name;
                         });

// `sim demo` writes a 470 KB SVG and then results.json: on a disk with room for the SVG only, the
// folder must not appear with the SVG and without the results (the "folder without its SVG").
TEST(WriteFaults, SimDemoOnADiskWithRoomForOneFileLeavesNothing) {
  if (::geteuid() != 0) GTEST_SKIP() << "mounting a small tmpfs needs root";
  Scratch tmp;
  // Measure the SVG on a roomy tmpfs first, then remount just large enough for it.
  ASSERT_TRUE(tmp.mount_tmpfs(16 << 20, false));
  const Writer demo = writers()[0];
  std::vector<std::string> args = demo.args_before_out;
  args.push_back((tmp.mnt / "probe").string());
  ASSERT_EQ(run(args, tmp.dir / "err.txt").rc, 0);
  const uintmax_t svg = fs::file_size(tmp.mnt / "probe" / "deformation.svg");
  ASSERT_EQ(umount2(tmp.mnt.c_str(), MNT_DETACH), 0);
  tmp.mounted = false;
  const size_t page = static_cast<size_t>(sysconf(_SC_PAGESIZE));
  ASSERT_TRUE(tmp.mount_tmpfs((svg + page - 1) / page * page, false));
  expect_clean_failure(demo, tmp.mnt / "out", tmp.mnt, tmp.dir / "err.txt", "room for the SVG only");
}
