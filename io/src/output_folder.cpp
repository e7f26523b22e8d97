#include "softatlas/io/output_folder.hpp"

#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "softatlas/sim/error.hpp"

namespace fs = std::filesystem;

namespace softatlas::io {

void remove_stale_partials(const fs::path& dir, const std::string& stem) {
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind(stem, 0) != 0) continue;
    const std::string pid_text = name.substr(stem.size());
    char* stop = nullptr;
    const long pid = std::strtol(pid_text.c_str(), &stop, 10);
    if (pid_text.empty() || *stop != '\0' || pid <= 0) continue;
    if (::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH) {
      std::error_code rm;
      fs::remove_all(it->path(), rm);
    }
  }
}

void check_writable(const std::string& target) {
  std::error_code ec;
  fs::path p = fs::absolute(target, ec).lexically_normal();
  if (ec || target.empty()) throw InputError(target, "not a usable output path");
  if (!p.has_filename()) p = p.parent_path();
  // The folder the new entries go into: target itself when it is an existing folder, else its
  // nearest existing ancestor.
  if (!fs::is_directory(p, ec)) {
    p = p.parent_path();
    while (!fs::exists(p, ec) && p != p.parent_path()) p = p.parent_path();
  }
  if (!fs::is_directory(p, ec)) throw InputError(target, p.string() + " is not a folder");
  if (::access(p.c_str(), W_OK | X_OK) != 0)
    throw InputError(target, "cannot write into " + p.string() + ": " + std::strerror(errno));
}

StagedFolder::StagedFolder(const std::string& target) {
  std::error_code ec;
  target_ = fs::absolute(target, ec).lexically_normal();
  if (ec || target.empty()) throw InputError(target, "not a usable output folder path");
  if (!target_.has_filename()) target_ = target_.parent_path();  // "DIR/" -> "DIR"
  existed_ = fs::exists(target_, ec);
  if (existed_ && !fs::is_directory(target_, ec)) throw InputError(target, "exists and is not a folder");
  const std::string pid = std::to_string(::getpid());
  fs::path dir;
  std::string stem;
  if (existed_) {
    dir = target_;
    stem = ".partial.";
  } else {
    dir = target_.parent_path();
    stem = "." + target_.filename().string() + ".partial.";
    for (fs::path p = dir; !p.empty() && !fs::exists(p, ec); p = p.parent_path()) {
      created_ = p;
      if (p == p.parent_path()) break;
    }
    fs::create_directories(dir, ec);
    if (ec) {
      const std::string why = ec.message();
      if (!created_.empty()) fs::remove_all(created_, ec);
      throw InputError(target, "cannot create the output folder: " + why);
    }
  }
  remove_stale_partials(dir, stem);
  stage_ = dir / (stem + pid);
  fs::remove_all(stage_, ec);
  fs::create_directory(stage_, ec);
  if (ec) {
    const std::string why = ec.message();
    if (!created_.empty()) fs::remove_all(created_, ec);
    throw InputError(target, "cannot write the output folder: " + why);
  }
}

StagedFolder::~StagedFolder() {
  if (committed_) return;
  std::error_code ec;
  fs::remove_all(stage_, ec);
  if (!created_.empty()) fs::remove_all(created_, ec);
}

void StagedFolder::commit() {
  std::error_code ec;
  if (!existed_) {
    fs::rename(stage_, target_, ec);
    if (ec) throw InputError(target_.string(), "cannot move the output into place: " + ec.message());
    committed_ = true;
    return;
  }
  // An existing folder: replace its files of the same names, one rename each.
  std::vector<fs::path> entries;
  for (fs::directory_iterator it(stage_, ec), end; !ec && it != end; it.increment(ec)) entries.push_back(it->path());
  if (ec) throw InputError(target_.string(), "cannot read the staged output: " + ec.message());
  for (const fs::path& from : entries) {
    const fs::path to = target_ / from.filename();
    if (fs::is_directory(from) && fs::is_directory(to)) fs::remove_all(to, ec);
    fs::rename(from, to, ec);
    if (ec) throw InputError(to.string(), "cannot move the output into place: " + ec.message());
  }
  fs::remove_all(stage_, ec);
  committed_ = true;
}

std::string name_target(std::string message, const std::string& from, const std::string& to) {
  for (size_t at = message.find(from); !from.empty() && at != std::string::npos;
       at = message.find(from, at + to.size()))
    message.replace(at, from.size(), to);
  return message;
}

void StagedFolder::fail(const std::exception& e) const {
  const std::string to = target_.string();
  const std::string what = name_target(e.what(), stage_.string(), to);
  if (what.rfind(to, 0) == 0) throw InputError("", what);
  throw InputError(to, what);
}

}  // namespace softatlas::io
