// Round-trip formatting and parsing of mapping parameters (describe() / parseMapping).
#pragma once

#include <Eigen/Core>
#include <string>
#include <string_view>

namespace qota::detail {

// Shortest text that reads back to the same double.
std::string formatDouble(double x);
// "x,y,z" with formatDouble.
std::string formatVector(const Eigen::Vector3d& v);
// Parses a finite double; throws qota::Error naming `what` otherwise.
double parseDouble(std::string_view text, const std::string& what);
// Parses "x,y,z"; throws qota::Error naming `what` otherwise.
Eigen::Vector3d parseVector(std::string_view text, const std::string& what);

}  // namespace qota::detail
