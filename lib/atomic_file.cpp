#include "qota/atomic_file.hpp"

#include <unistd.h>

#include <cerrno>
#include <string>
#include <system_error>

#include "qota/error.hpp"

namespace qota {

AtomicFile::AtomicFile(std::filesystem::path target) : target_(std::move(target)) {
  temp_ = target_;
  temp_ += ".tmp." + std::to_string(::getpid());
  stream_.open(temp_, std::ios::out | std::ios::trunc | std::ios::binary);
  if (!stream_) {
    throw Error(target_.string() + ": cannot write (" + std::generic_category().message(errno) + ")");
  }
}

AtomicFile::~AtomicFile() {
  if (!committed_) {
    stream_.close();
    std::error_code ec;
    std::filesystem::remove(temp_, ec);
  }
}

void AtomicFile::commit() {
  stream_.flush();
  const bool ok = static_cast<bool>(stream_);
  stream_.close();
  if (!ok || stream_.fail()) throw Error(target_.string() + ": write failed");
  std::error_code ec;
  std::filesystem::rename(temp_, target_, ec);
  if (ec) throw Error(target_.string() + ": cannot rename into place (" + ec.message() + ")");
  committed_ = true;
}

}  // namespace qota
