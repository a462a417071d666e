// Assimp and OGR, kept at arm's length. Their parsers are not ours to fix, and hostile files make
// some of them loop for ever or crash: a PLY header with a mangled end_header sends Debian's
// Assimp 5.2 seeking without end, a 157-byte DXF file sends GDAL 3.6's DXF driver round for ever.
// So those reads run in a child process: the child reads the file and sends the mesh back
// through a pipe; the parent waits at most MeshFileOptions::readerSeconds (plus a second per 5 MB
// of file) and turns a crash, a hang or a garbled reply into a qota::Error naming the file.

#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "mesh_readers.hpp"
#include "qota/error.hpp"

namespace qota::detail {
namespace {

namespace isolated {

class Pipe {
 public:
  explicit Pipe(int fd) : fd_(fd) {}
  bool write(const void* p, std::size_t n) const {
    const char* c = static_cast<const char*>(p);
    while (n > 0) {
      const ssize_t k = ::write(fd_, c, n);
      if (k < 0 && errno == EINTR) continue;
      if (k <= 0) return false;
      c += k, n -= static_cast<std::size_t>(k);
    }
    return true;
  }
  template <class T>
  bool pod(const T& v) {
    return write(&v, sizeof v);
  }
  template <class T>
  bool vec(const std::vector<T>& v) {
    return pod<std::uint64_t>(v.size()) && write(v.data(), v.size() * sizeof(T));
  }
  bool str(const std::string& s) { return pod<std::uint64_t>(s.size()) && write(s.data(), s.size()); }

 private:
  int fd_;
};

// Reads the child's reply with a deadline; false on timeout, error or end of data.
class Reply {
 public:
  Reply(int fd, std::chrono::steady_clock::time_point deadline) : fd_(fd), deadline_(deadline) {}
  bool read(void* p, std::size_t n) {
    char* c = static_cast<char*>(p);
    while (n > 0) {
      const auto left =
          std::chrono::duration_cast<std::chrono::milliseconds>(deadline_ - std::chrono::steady_clock::now());
      if (left.count() <= 0) return timedOut_ = true, false;
      pollfd pfd{fd_, POLLIN, 0};
      const int r = ::poll(&pfd, 1, static_cast<int>(std::min<long long>(left.count(), 1000)));
      if (r < 0 && errno == EINTR) continue;
      if (r < 0) return false;
      if (r == 0) continue;
      const ssize_t k = ::read(fd_, c, n);
      if (k < 0 && errno == EINTR) continue;
      if (k <= 0) return false;
      c += k, n -= static_cast<std::size_t>(k);
    }
    return true;
  }
  template <class T>
  bool pod(T& v) {
    return read(&v, sizeof v);
  }
  // A vector of at most `limit` elements (a garbled count must not allocate the machine away).
  template <class T>
  bool vec(std::vector<T>& v, std::uint64_t limit) {
    std::uint64_t n = 0;
    if (!pod(n) || n > limit) return false;
    v.resize(n);
    return read(v.data(), n * sizeof(T));
  }
  bool str(std::string& s) {
    std::uint64_t n = 0;
    if (!pod(n) || n > (1u << 24)) return false;
    s.resize(n);
    return read(s.data(), n);
  }
  bool timedOut() const { return timedOut_; }

 private:
  int fd_;
  std::chrono::steady_clock::time_point deadline_;
  bool timedOut_ = false;
};

bool send(Pipe& p, const MeshFile& m) {
  bool ok = p.pod<char>('M') && p.str(m.format) && p.str(m.crsWkt) && p.pod<std::uint8_t>(m.singlePrecision) &&
            p.pod(m.origin) && p.pod<std::uint64_t>(m.degenerate) && p.pod<std::uint64_t>(m.triangulated) &&
            p.vec(m.mesh.vertices) && p.vec(m.mesh.indices) && p.vec(m.mesh.offsets) && p.vec(m.polygonMaterial) &&
            p.vec(m.polygonObject) && p.vec(m.polygonSource) && p.pod<std::uint64_t>(m.materials.size());
  for (const auto& s : m.materials) ok = ok && p.str(s);
  ok = ok && p.pod<std::uint64_t>(m.objects.size());
  for (const auto& s : m.objects) ok = ok && p.str(s);
  return ok;
}

bool receive(Reply& r, MeshFile& m) {
  constexpr std::uint64_t kLimit = 1ull << 32;
  std::uint8_t single = 0;
  std::uint64_t materials = 0, objects = 0;
  bool ok = r.str(m.format) && r.str(m.crsWkt) && r.pod(single) && r.pod(m.origin) && r.pod(m.degenerate) &&
            r.pod(m.triangulated) && r.vec(m.mesh.vertices, kLimit) && r.vec(m.mesh.indices, kLimit) &&
            r.vec(m.mesh.offsets, kLimit) && r.vec(m.polygonMaterial, kLimit) && r.vec(m.polygonObject, kLimit) &&
            r.vec(m.polygonSource, kLimit) && r.pod(materials) && materials <= kLimit;
  for (std::uint64_t i = 0; ok && i < materials; ++i) ok = r.str(m.materials.emplace_back());
  ok = ok && r.pod(objects) && objects <= kLimit;
  for (std::uint64_t i = 0; ok && i < objects; ++i) ok = r.str(m.objects.emplace_back());
  m.singlePrecision = single != 0;
  return ok;
}

}  // namespace isolated

}  // namespace

// Runs read(out) in a child process and takes its MeshFile back (see above); `reader` names the
// library in messages.
void readIsolated(MeshFile& out, const MeshFileOptions& options, const char* reader,
                  const std::function<void(MeshFile&)>& read) {
  int fds[2];
  if (::pipe(fds) != 0) throw Error(out.path + ": cannot start the mesh reader (pipe)");
  const pid_t pid = ::fork();
  if (pid < 0) {
    ::close(fds[0]), ::close(fds[1]);
    throw Error(out.path + ": cannot start the mesh reader (fork)");
  }
  if (pid == 0) {  // the child: read, send, leave without running the parent's exit handlers
    ::close(fds[0]);
    isolated::Pipe pipe(fds[1]);
    try {
      read(out);
      isolated::send(pipe, out);
    } catch (const std::exception& e) {
      pipe.pod<char>('E') && pipe.str(e.what());
    }
    ::close(fds[1]);
    ::_exit(0);
  }
  ::close(fds[1]);
  std::error_code ec;
  const auto bytes = std::filesystem::file_size(out.path, ec);
  const double seconds = options.readerSeconds + static_cast<double>(ec ? 0 : bytes) / 5e6;
  isolated::Reply reply(
      fds[0], std::chrono::steady_clock::now() + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                                     std::chrono::duration<double>(seconds)));
  char kind = 0;
  std::string message;
  bool ok = reply.pod(kind) && (kind == 'M' ? isolated::receive(reply, out) : kind == 'E' && reply.str(message));
  const bool timedOut = reply.timedOut();
  ::close(fds[0]);
  if (timedOut || !ok) ::kill(pid, SIGKILL);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (timedOut) {
    throw Error(out.path + ": " + reader + " took more than " + std::to_string(static_cast<long>(seconds)) +
                " s to read it; giving up");
  }
  if (WIFSIGNALED(status) && !ok) {
    throw Error(out.path + ": " + reader + " crashed reading it (signal " + std::to_string(WTERMSIG(status)) + ")");
  }
  if (!ok) throw Error(out.path + ": " + reader + "'s reply was cut short");
  if (kind == 'E') throw Error(message);
}

}  // namespace qota::detail
