// Output folders that appear whole or not at all (issue 17): a command that writes several files
// into --out DIR writes them into a staging folder and moves them into place only when every file
// was written. A full disk, a read-only folder or an error half way leaves nothing behind: no
// empty DIR, no folder without its pictures, no staging folder.
#pragma once

#include <filesystem>
#include <exception>
#include <string>
#include <type_traits>

namespace softatlas::io {

// Checks, before any work, that `target` (a file or folder to be made, or an existing folder) can
// be written: its nearest existing ancestor must be a folder this process may write into (a
// read-only file system or folder fails here, not after minutes of computing). Throws InputError
// naming target. A full disk is only found when writing.
void check_writable(const std::string& target);

// Removes the staging folders `STEM<PID>` in `dir` whose process is gone (killed writers).
void remove_stale_partials(const std::filesystem::path& dir, const std::string& stem);

// `message` with every occurrence of the staging folder `from` replaced by the target `to` (errors
// name the folder the user asked for, not the hidden one).
std::string name_target(std::string message, const std::string& from, const std::string& to);

class StagedFolder {
 public:
  // Prepares the staging folder for `target`: a hidden sibling `.NAME.partial.PID` when target
  // does not exist yet (its missing parents are created and removed again on failure), or a
  // hidden `.partial.PID` inside target when it is an existing folder (its files are replaced by
  // name on commit, other files stay). Throws InputError naming target when it cannot be written.
  explicit StagedFolder(const std::string& target);
  ~StagedFolder();  // not committed: removes everything it created
  StagedFolder(const StagedFolder&) = delete;
  StagedFolder& operator=(const StagedFolder&) = delete;

  // The folder to write into (the staging folder).
  std::string path() const { return stage_.string(); }
  // Moves the staged files into target; throws InputError naming target on failure (and leaves
  // target as it was, as far as the file system allows).
  void commit();
  // Runs write(path()) and then commit(). Any error while writing becomes one InputError that
  // names target (not the hidden staging folder), e.g. "out/lesson: write failed (disk full?)".
  template <class F>
  auto write_and_commit(F&& write) {
    try {
      if constexpr (std::is_void_v<decltype(write(path()))>) {
        write(path());
        commit();
      } else {
        auto result = write(path());
        commit();
        return result;
      }
    } catch (const std::exception& e) {
      fail(e);
    }
  }

 private:
  [[noreturn]] void fail(const std::exception& e) const;

 public:
 private:
  std::filesystem::path target_, stage_, created_;  // created_: first parent made by us, or empty
  bool existed_ = false, committed_ = false;
};

}  // namespace softatlas::io
