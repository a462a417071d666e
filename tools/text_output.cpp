#include "text_output.hpp"

#include <charconv>

#include "qota/error.hpp"

namespace qota::tools {

std::string formatNumber(double value, int precision) {
  char buf[64];
  const auto r = precision < 0
                     ? std::to_chars(buf, buf + sizeof buf, value)
                     : std::to_chars(buf, buf + sizeof buf, value, std::chars_format::fixed, precision);
  return std::string(buf, r.ptr);
}

}  // namespace qota::tools
