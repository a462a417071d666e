// Float bounds that enclose a double value (rounded toward -inf / +inf): for tables that keep
// ranges in half the bytes and must stay on the safe side of them.
#pragma once
#include <cmath>
#include <limits>

namespace qota {

inline float floatBelow(double x) {
  float f = static_cast<float>(x);
  if (static_cast<double>(f) > x) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
  return f;
}

inline float floatAbove(double x) {
  float f = static_cast<float>(x);
  if (static_cast<double>(f) < x) f = std::nextafter(f, std::numeric_limits<float>::infinity());
  return f;
}

}  // namespace qota
