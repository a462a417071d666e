#include "text_output.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <exception>
#include <new>
#include <ostream>

#include "cancel.hpp"
#include "qota/error.hpp"

namespace qota::tools {

std::string formatNumber(double value, int precision) {
  precision = std::min(precision, kMaxPrecision);
  // A fixed double needs up to 309 integer digits, a sign, a point and the decimals.
  std::string buf(330 + static_cast<std::size_t>(std::max(precision, 0)), '\0');
  const auto r = precision < 0
                     ? std::to_chars(buf.data(), buf.data() + buf.size(), value)
                     : std::to_chars(buf.data(), buf.data() + buf.size(), value, std::chars_format::fixed, precision);
  // The buffer fits every double; an error here would be a bug, never garbage on the output.
  if (r.ec != std::errc()) throw Error("cannot format a number");
  buf.resize(static_cast<std::size_t>(r.ptr - buf.data()));
  return buf;
}

std::string formatReadable(double value, int decimals) {
  if (std::isfinite(value) && std::fabs(value) < 1e15) return formatNumber(value, decimals);
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, value, std::chars_format::scientific);
  if (r.ec != std::errc()) throw Error("cannot format a number");
  return std::string(buf, r.ptr);
}

int reportFailure(const char* tool, std::ostream& err) {
  err << "qota " << tool << ": ";
  if (cancelRequested()) {  // (whatever the work threw when it stopped: the signal is the cause)
    try {
      throwIfCancelled();
    } catch (const std::exception& e) {
      err << e.what() << '\n';
      return 2;
    }
  }
  try {
    throw;
  } catch (const std::bad_alloc&) {
    err << "out of memory";
  } catch (const std::exception& e) {
    err << e.what();
  } catch (...) {
    err << "unexpected error";
  }
  err << '\n';
  return 2;
}

std::string formatHours(double hours) {
  if (!std::isfinite(hours)) return formatNumber(hours);
  return formatNumber(std::round(hours * 3.6e6) / 3.6e6);
}

}  // namespace qota::tools
