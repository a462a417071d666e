#include "qota/any_mapping.hpp"

#include <map>
#include <sstream>
#include <utility>

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

Eigen::Vector3d MappingParameters::vector(const char* key, const Eigen::Vector3d& fallback) {
  const auto it = words_.find(key);
  if (it == words_.end()) return fallback;
  Eigen::Vector3d v = detail::parseVector(it->second, "mapping " + mapping_ + " " + key);
  words_.erase(it);
  return v;
}

double MappingParameters::number(const char* key, double fallback) {
  const auto it = words_.find(key);
  if (it == words_.end()) return fallback;
  const double x = detail::parseDouble(it->second, "mapping " + mapping_ + " " + key);
  words_.erase(it);
  return x;
}

namespace {

// The mapping of AnyMapping's alternatives named `name`, from its parameters.
template <std::size_t I = 0>
AnyMapping parseAs(const std::string& name, MappingParameters& params) {
  if constexpr (I < std::variant_size_v<AnyMapping>) {
    using M = std::variant_alternative_t<I, AnyMapping>;
    if (name == M::name()) return M::fromParameters(params);
    return parseAs<I + 1>(name, params);
  } else {
    throw Error("unknown mapping '" + name + "' (expected " + mappingNames() + ")");
  }
}

}  // namespace

std::string mappingNames() {
  std::string names;
  [&]<std::size_t... I>(std::index_sequence<I...>) {
    ((names += (I == 0                  ? ""
                : I + 1 == sizeof...(I) ? " or "
                                        : ", "),
      names += std::variant_alternative_t<I, AnyMapping>::name()),
     ...);
  }
  (std::make_index_sequence<std::variant_size_v<AnyMapping>>());
  return names;
}

AnyMapping parseMapping(const std::string& text) {
  std::istringstream in(text);
  std::string name, word;
  in >> name;
  std::map<std::string, std::string> words;
  while (in >> word) {
    const auto eq = word.find('=');
    if (eq == std::string::npos || eq == 0) {
      std::string message = "mapping '";
      message.append(text).append("': '").append(word).append("' is not key=value");
      throw Error(message);
    }
    words[word.substr(0, eq)] = word.substr(eq + 1);
  }
  MappingParameters params(name, std::move(words));
  AnyMapping result = parseAs(name, params);
  if (!params.left().empty()) {
    throw Error("mapping " + name + ": unknown parameter '" + params.left().begin()->first + "'");
  }
  return result;
}

}  // namespace qota
