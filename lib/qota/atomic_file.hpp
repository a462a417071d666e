// Files written whole or not at all.
#pragma once

#include <filesystem>
#include <fstream>

namespace qota {

// A file written under a temporary name and renamed into place by commit(), so that a failed or
// interrupted run never leaves a half-written file under the requested name. Without commit() the
// temporary is removed.
class AtomicFile {
 public:
  explicit AtomicFile(std::filesystem::path target);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  std::ofstream& stream() { return stream_; }
  const std::filesystem::path& temporary() const { return temp_; }
  void commit();  // throws qota::Error when the data cannot be written or renamed

 private:
  std::filesystem::path target_, temp_;
  std::ofstream stream_;
  bool committed_ = false;
};

}  // namespace qota
