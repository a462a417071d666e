// What the fuzz harnesses share: a private scratch folder, writing an input to a file, and the
// rule that only qota::Error may leave the library on bad input (anything else is a bug, and
// libFuzzer reports it as a crash).
#pragma once

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <string_view>

namespace qota::fuzz {

// Ends the run as a crash, saying why first (libFuzzer then keeps the input): a broken check
// would otherwise show only as a signal.
[[noreturn]] inline void fail(const std::string& why) {
  std::fprintf(stderr, "qota fuzz: %s\n", why.c_str());
  std::fflush(stderr);
  std::abort();
}

// A folder of this process's own, made once, emptied of what an earlier process of the same
// number left (temporary folders outlive their processes, and numbers come round), and removed
// when the process ends normally (a crash leaves it to be looked at).
inline const std::filesystem::path& scratch() {
  static const std::filesystem::path dir = [] {
    const auto d = std::filesystem::temp_directory_path() / ("qota_fuzz_" + std::to_string(::getpid()));
    std::error_code ec;
    std::filesystem::remove_all(d, ec);
    if (!std::filesystem::create_directories(d, ec) || ec) fail("cannot make " + d.string() + ": " + ec.message());
    return d;
  }();
  static const bool removedAtExit = [] {
    std::atexit([] {
      std::error_code ec;
      std::filesystem::remove_all(dir, ec);
    });
    return true;
  }();
  (void)removedAtExit;
  return dir;
}

// A copy of a file through streams, which retry a read or write a signal interrupts: the
// kernel's copy under std::filesystem::copy_file fails with EINTR when libFuzzer's timer signal
// (SIGALRM, every few seconds) arrives during it, and leaves an empty file behind.
inline void copyFile(const std::filesystem::path& from, const std::filesystem::path& to) {
  std::ifstream in(from, std::ios::binary);
  const std::string bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  std::ofstream out(to, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  out.flush();
  if (!in.good() && !in.eof()) fail("cannot read " + from.string());
  if (!out || bytes.empty()) fail("cannot copy " + from.string() + " to " + to.string());
}

inline std::string writeFile(const std::string& name, const std::uint8_t* data, std::size_t size) {
  const auto path = scratch() / name;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  return path.string();
}

// Reads fuzz bytes as a little structured stream: numbers first, the rest as a blob.
class Bytes {
 public:
  Bytes(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {}
  std::uint8_t byte() { return pos_ < size_ ? data_[pos_++] : 0; }
  std::uint32_t u32() {
    std::uint32_t v = 0;
    for (int i = 0; i < 4; ++i) v |= static_cast<std::uint32_t>(byte()) << (8 * i);
    return v;
  }
  double f64() {
    std::uint64_t v = 0;
    for (int i = 0; i < 8; ++i) v |= static_cast<std::uint64_t>(byte()) << (8 * i);
    double d;
    static_assert(sizeof d == sizeof v);
    __builtin_memcpy(&d, &v, sizeof d);
    return d;
  }
  std::string_view rest() {
    const std::string_view r(reinterpret_cast<const char*>(data_) + pos_, size_ - pos_);
    pos_ = size_;
    return r;
  }
  bool done() const { return pos_ >= size_; }

 private:
  const std::uint8_t* data_;
  std::size_t size_, pos_ = 0;
};

}  // namespace qota::fuzz
