// Small output helpers shared by the tools.
#pragma once

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <ostream>
#include <string>

#include "qota/atomic_file.hpp"  // AtomicFile, shared with the library

namespace qota::tools {

// The most decimals -p takes: more than a double holds (17 significant digits) for any height,
// with room for tiny values; every one printed is a true digit of the double's exact value.
constexpr int kMaxPrecision = 100;

// The shortest decimal that reads back as the same double (precision < 0), or fixed decimals
// (precision 0 .. kMaxPrecision; more is clamped). Exact for any double, however large; "nan",
// "inf", "-inf" for those.
std::string formatNumber(double value, int precision = -1);

// A number for people: fixed decimals while it stays short, else the shortest round trip in
// scientific notation (a shadow reach of 1e300 m is not printed as 300 digits).
std::string formatReadable(double value, int decimals);

// Hours elapsed (differences of Julian days, a few microseconds of rounding) for people: rounded
// to the millisecond, then the shortest form ("23", "1.5").
std::string formatHours(double hours);

// For a tool's catch (...): prints "qota <tool>: <what went wrong>" for whatever was thrown (a
// qota::Error's message, "out of memory", a library's exception) and returns exit code 2.
int reportFailure(const char* tool, std::ostream& err);

}  // namespace qota::tools
