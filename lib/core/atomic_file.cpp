#include "qota/atomic_file.hpp"

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <string>
#include <system_error>

#include "qota/error.hpp"

namespace qota {
namespace {

namespace fs = std::filesystem;
constexpr const char* kPrefix = ".qota-partial-";

// Removes staging folders in `dir` left by processes that are gone.
void removeAbandoned(const fs::path& dir) {
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind(kPrefix, 0) != 0) continue;
    const std::string rest = name.substr(std::strlen(kPrefix));
    const long pid = std::strtol(rest.c_str(), nullptr, 10);
    if (pid <= 0 || pid == ::getpid()) continue;
    if (::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH) {
      std::error_code ignored;
      fs::remove_all(it->path(), ignored);
    }
  }
}

std::string reason(const std::error_code& ec) { return ec.message(); }

}  // namespace

OutputStage::~OutputStage() {
  for (const Entry& e : entries_) {
    std::error_code ec;
    fs::remove_all(e.folder, ec);
  }
}

void OutputStage::checkTarget(const fs::path& target) {
  std::error_code ec;
  const fs::file_status st = fs::symlink_status(target, ec);
  if (fs::exists(st) && !fs::is_regular_file(st) && !fs::is_symlink(st)) {
    throw Error(target.string() + ": exists and is not a regular file (a folder, a device or a pipe); "
                "give the name of a file");
  }
}

fs::path OutputStage::stage(const fs::path& target) {
  checkTarget(target);
  std::error_code ec;
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  removeAbandoned(dir);
  static std::atomic<unsigned> counter{0};
  const fs::path folder = dir / (kPrefix + std::to_string(::getpid()) + "-" + std::to_string(counter++));
  if (!fs::create_directory(folder, ec)) {
    throw Error(target.string() + ": cannot write (" + (ec ? reason(ec) : std::string("staging folder exists")) + ")");
  }
  entries_.push_back({target, folder});
  return folder / target.filename();
}

void OutputStage::commit() {
  for (const Entry& e : entries_) {
    const fs::path dir = e.target.has_parent_path() ? e.target.parent_path() : fs::path(".");
    const std::string main = e.target.filename().string();
    bool wroteAux = false;
    std::error_code ec;
    // The main file first, so that its sidecars never stand beside an older version of it.
    std::vector<fs::path> files{e.folder / main};
    for (fs::directory_iterator it(e.folder, ec), end; !ec && it != end; it.increment(ec)) {
      if (it->path().filename() != main) files.push_back(it->path());
    }
    if (ec) throw Error(e.target.string() + ": cannot read its staging folder (" + reason(ec) + ")");
    for (const fs::path& f : files) {
      if (f.filename().string() == main + ".aux.xml") wroteAux = true;
      fs::rename(f, dir / f.filename(), ec);
      if (ec) throw Error(e.target.string() + ": cannot move " + f.filename().string() + " into place (" + reason(ec) + ")");
    }
    if (!wroteAux) fs::remove(dir / (main + ".aux.xml"), ec);  // it described the file replaced
    fs::remove_all(e.folder, ec);
  }
  entries_.clear();
}

AtomicFile::AtomicFile(const fs::path& target) : target_(target) {
  path_ = stage_.stage(target);
  stream_.open(path_, std::ios::out | std::ios::trunc | std::ios::binary);
  if (!stream_) {
    throw Error(target_.string() + ": cannot write (" + std::generic_category().message(errno) + ")");
  }
}

void AtomicFile::commit() {
  stream_.flush();
  const bool written = static_cast<bool>(stream_);
  stream_.close();
  if (!written || stream_.fail()) throw Error(target_.string() + ": write failed (is the disk full?)");
  // On disk before it takes the target's name: a crash after the rename finds the whole file.
  const int fd = ::open(path_.c_str(), O_RDONLY);
  const bool synced = fd >= 0 && ::fsync(fd) == 0;
  if (fd >= 0) ::close(fd);
  if (!synced) throw Error(target_.string() + ": cannot sync (" + std::generic_category().message(errno) + ")");
  stage_.commit();
}

}  // namespace qota
