#include "describe.hpp"

#include <charconv>
#include <cmath>

#include "qota/error.hpp"

namespace qota::detail {

std::string formatDouble(double x) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, x);
  return std::string(buf, r.ptr);
}

std::string formatVector(const Eigen::Vector3d& v) {
  return formatDouble(v.x()) + ',' + formatDouble(v.y()) + ',' + formatDouble(v.z());
}

double parseDouble(std::string_view text, const std::string& what) {
  double x = 0;
  const auto r = std::from_chars(text.data(), text.data() + text.size(), x);
  if (r.ec != std::errc() || r.ptr != text.data() + text.size() || !std::isfinite(x)) {
    throw Error(what + ": '" + std::string(text) + "' is not a finite number");
  }
  return x;
}

Eigen::Vector3d parseVector(std::string_view text, const std::string& what) {
  Eigen::Vector3d v;
  std::size_t start = 0;
  for (int i = 0; i < 3; ++i) {
    const std::size_t comma = i < 2 ? text.find(',', start) : text.size();
    if (comma == std::string_view::npos) {
      throw Error(what + ": '" + std::string(text) + "' is not three comma-separated numbers");
    }
    v[i] = parseDouble(text.substr(start, comma - start), what);
    start = comma + 1;
  }
  if (start != text.size() + 1) {
    throw Error(what + ": '" + std::string(text) + "' is not three comma-separated numbers");
  }
  return v;
}

}  // namespace qota::detail
