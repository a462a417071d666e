// GDAL error plumbing shared by the library's and the tools' GDAL code (not part of the public
// qota/ headers: it needs GDAL's own).
#pragma once

#include <cpl_error.h>

#include <string>
#include <vector>

namespace qota::detail {

// Keeps GDAL from printing its own errors while we turn them into a qota::Error (or decide they
// are none, as when probing whether a file is a raster).
struct QuietGdalErrors {
  QuietGdalErrors() {
    CPLPushErrorHandler(CPLQuietErrorHandler);
    CPLErrorReset();
  }
  ~QuietGdalErrors() { CPLPopErrorHandler(); }
  QuietGdalErrors(const QuietGdalErrors&) = delete;
  QuietGdalErrors& operator=(const QuietGdalErrors&) = delete;
};

// Records every error GDAL reports while it lives (none printed): whether any was a failure, and
// the first failure's message. For writes, where GDAL reports a full disk as an error at the
// close and still returns.
class GdalErrorLog {
 public:
  GdalErrorLog() {
    CPLPushErrorHandlerEx(&GdalErrorLog::handler, this);
    CPLErrorReset();
  }
  ~GdalErrorLog() { CPLPopErrorHandler(); }
  GdalErrorLog(const GdalErrorLog&) = delete;
  GdalErrorLog& operator=(const GdalErrorLog&) = delete;
  bool failed() const { return failed_; }
  const std::string& message() const { return message_; }
  // GDAL's warnings (the first few), in order: what it skipped or ignored.
  const std::vector<std::string>& warnings() const { return warnings_; }
  // The failure's message, else the warnings joined: why something came out empty.
  std::string reason() const {
    if (!message_.empty()) return message_;
    std::string out;
    for (const auto& w : warnings_) out += (out.empty() ? "" : "; ") + w;
    return out.empty() ? std::string("GDAL gave no reason") : out;
  }

 private:
  static void CPL_STDCALL handler(CPLErr level, CPLErrorNum, const char* msg) {
    auto* self = static_cast<GdalErrorLog*>(CPLGetErrorHandlerUserData());
    if (level == CE_Failure || level == CE_Fatal) {
      if (!self->failed_ && msg) self->message_ = msg;
      self->failed_ = true;
    } else if (level == CE_Warning && msg && self->warnings_.size() < 8) {
      self->warnings_.emplace_back(msg);
    }
  }
  bool failed_ = false;
  std::string message_;
  std::vector<std::string> warnings_;
};

// GDAL's last error as ": message", or "" when there is none.
inline std::string gdalMessage() {
  const char* m = CPLGetLastErrorMsg();
  return (m && *m) ? std::string(": ") + m : std::string();
}

}  // namespace qota::detail
