// Outputs written whole or not at all.
//
// Every file qota writes goes first to a private staging folder beside its target (on the same
// file system, so the final move is a rename), named ".qota-partial-<pid>-<n>", under the
// target's own name, so that drivers that add sidecar files (.aux.xml, ENVI's and EHdr's .hdr,
// a PNG's .wld) put them there too. Only when everything a command writes is complete and closed
// without error are the staged files moved into place, each by rename(2): a symlink at the
// target is replaced, never written through. On an error or a cancellation the staging folders
// are removed and the files that were there before stay as they were. A run killed outright
// (SIGKILL, a power cut) leaves its staging folder behind; the next run that writes into the same
// folder removes the staging folders whose process is gone.
//
// A target that exists and is neither a regular file nor a symlink (a folder, a device, a FIFO)
// is refused.
#pragma once

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace qota {

class OutputStage {
 public:
  OutputStage() = default;
  ~OutputStage();  // removes whatever was staged and not committed
  OutputStage(const OutputStage&) = delete;
  OutputStage& operator=(const OutputStage&) = delete;

  // Throws qota::Error when `target` exists and is not a regular file or a symlink.
  static void checkTarget(const std::filesystem::path& target);
  // Stages `target` and returns the path to write it to (in a new staging folder beside it).
  // Throws qota::Error naming the target when it cannot be written there.
  std::filesystem::path stage(const std::filesystem::path& target);
  // Moves every staged file into place, in the order staged, and a stale "<target>.aux.xml" of
  // an earlier file out of the way when this run wrote none. Throws qota::Error when a move
  // fails (the files moved before it stay).
  void commit();

 private:
  struct Entry {
    std::filesystem::path target, folder;
  };
  std::vector<Entry> entries_;
};

// One file written through a stream and staged (above).
class AtomicFile {
 public:
  explicit AtomicFile(const std::filesystem::path& target);
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  std::ofstream& stream() { return stream_; }
  const std::filesystem::path& temporary() const { return path_; }
  // Flushes and syncs the data, checks that every write succeeded, and moves the file into place.
  // Throws qota::Error naming the target when anything failed (a full disk): nothing is placed.
  void commit();

 private:
  std::filesystem::path target_;
  OutputStage stage_;
  std::filesystem::path path_;
  std::ofstream stream_;
};

// The whole of a small input file (a state, a list): a regular file of at most `most` bytes,
// read without blocking. Throws qota::Error naming the path when it is missing, is not a regular
// file (a FIFO, a device, a folder: never waited on or read without end), or is larger.
std::string readSmallFile(const std::filesystem::path& path, std::uint64_t most);

}  // namespace qota
