#include "qota/any_mapping.hpp"

#include <GeographicLib/Constants.hpp>
#include <map>
#include <optional>
#include <sstream>

#include "describe.hpp"
#include "qota/error.hpp"

namespace qota {

std::string describe(const AnyMapping& mapping) {
  return std::visit([](const auto& m) { return m.describe(); }, mapping);
}

const char* mappingName(const AnyMapping& mapping) {
  return std::visit([](const auto& m) { return m.name(); }, mapping);
}

Eigen::Vector3d toMapped(const AnyMapping& mapping, const Eigen::Vector3d& world) {
  return std::visit([&](const auto& m) { return m.toMapped(world); }, mapping);
}

Eigen::Vector3d toWorld(const AnyMapping& mapping, const Eigen::Vector3d& mapped) {
  return std::visit([&](const auto& m) { return m.toWorld(mapped); }, mapping);
}

MappedLine lineOf(const AnyMapping& mapping, double u, double v) {
  return std::visit([&](const auto& m) { return m.line(u, v); }, mapping);
}

AnyMapping parseMapping(const std::string& text) {
  std::istringstream in(text);
  std::string name, word;
  in >> name;
  std::map<std::string, std::string> params;
  while (in >> word) {
    const auto eq = word.find('=');
    if (eq == std::string::npos || eq == 0) {
      throw Error("mapping '" + text + "': '" + word + "' is not key=value");
    }
    params[word.substr(0, eq)] = word.substr(eq + 1);
  }
  // Takes a parameter out of params, so that leftovers can be reported as unknown.
  auto take = [&](const char* key) -> std::optional<std::string> {
    auto it = params.find(key);
    if (it == params.end()) return std::nullopt;
    std::string value = it->second;
    params.erase(it);
    return value;
  };
  auto vec = [&](const char* key, Eigen::Vector3d fallback) {
    const auto v = take(key);
    return v ? detail::parseVector(*v, std::string("mapping ") + name + " " + key) : fallback;
  };
  auto num = [&](const char* key, double fallback) {
    const auto v = take(key);
    return v ? detail::parseDouble(*v, std::string("mapping ") + name + " " + key) : fallback;
  };
  AnyMapping result;
  if (name == "cartesian") {
    const Eigen::Vector3d gravity = vec("gravity", {0, 0, -1});
    result = CartesianMapping(gravity, vec("origin", Eigen::Vector3d::Zero()));
  } else if (name == "spherical") {
    result = SphericalMapping(vec("centre", Eigen::Vector3d::Zero()));
  } else if (name == "cylindrical") {
    const Eigen::Vector3d point = vec("point", Eigen::Vector3d::Zero());
    result = CylindricalMapping(point, vec("axis", {0, 0, 1}));
  } else if (name == "geodetic") {
    const double a = num("a", GeographicLib::Constants::WGS84_a());
    result = GeodeticMapping(a, num("f", GeographicLib::Constants::WGS84_f()));
  } else {
    throw Error("unknown mapping '" + name +
                "' (expected cartesian, spherical, cylindrical or geodetic)");
  }
  if (!params.empty()) {
    throw Error("mapping " + name + ": unknown parameter '" + params.begin()->first + "'");
  }
  return result;
}

}  // namespace qota
