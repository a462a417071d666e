// Float bounds that enclose a double value (rounded toward -inf / +inf): for tables that keep
// ranges in half the bytes and must stay on the safe side of them.
#pragma once
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>

namespace qota {

// The next float toward +inf (up) or -inf (!up) from a finite f, by its bits: inline, where
// std::nextafter is a library call (these run once per triangle and range).
inline float floatStep(float f, bool up) {
  if (f == 0) return up ? std::numeric_limits<float>::denorm_min() : -std::numeric_limits<float>::denorm_min();
  const auto bits = std::bit_cast<std::uint32_t>(f);
  // Away from zero is one more in the magnitude bits, toward zero one less.
  return std::bit_cast<float>((f > 0) == up ? bits + 1 : bits - 1);
}

inline float floatBelow(double x) {
  float f = static_cast<float>(x);
  if (static_cast<double>(f) > x) f = std::isfinite(f) ? floatStep(f, false) : std::numeric_limits<float>::max();
  return f;
}

inline float floatAbove(double x) {
  float f = static_cast<float>(x);
  if (static_cast<double>(f) < x) f = std::isfinite(f) ? floatStep(f, true) : std::numeric_limits<float>::lowest();
  return f;
}

}  // namespace qota
