#include "qota/atomic_file.hpp"

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
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
    throw Error(target.string() +
                ": exists and is not a regular file (a folder, a device or a pipe); "
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
      if (ec)
        throw Error(e.target.string() + ": cannot move " + f.filename().string() + " into place (" + reason(ec) + ")");
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

std::string readSmallFile(const fs::path& path, std::uint64_t most) {
  // O_NONBLOCK: opening a FIFO with no writer returns at once (and the file is refused below).
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) throw Error(path.string() + ": cannot open (" + std::strerror(errno) + ")");
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat st {};
  if (::fstat(fd, &st) != 0) throw Error(path.string() + ": cannot read (" + std::strerror(errno) + ")");
  if (!S_ISREG(st.st_mode)) {
    throw Error(path.string() + ": not a regular file (a FIFO, a device or a folder); give a file");
  }
  if (static_cast<std::uint64_t>(st.st_size) > most) {
    throw Error(path.string() + ": " + std::to_string(st.st_size) + " bytes, more than the " + std::to_string(most) +
                " such a file can hold; not the file asked for");
  }
  std::string text;
  char buffer[1 << 16];
  for (;;) {
    const ssize_t n = ::read(fd, buffer, sizeof buffer);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw Error(path.string() + ": cannot read (" + std::strerror(errno) + ")");
    if (n == 0) break;
    text.append(buffer, static_cast<std::size_t>(n));
    if (text.size() > most) throw Error(path.string() + ": grew while read, past " + std::to_string(most) + " bytes");
  }
  return text;
}

}  // namespace qota
