// Small output helpers shared by the tools.
#pragma once

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "qota/atomic_file.hpp"  // AtomicFile, shared with the library

namespace qota::tools {

// The shortest decimal that reads back as the same double (precision < 0), or fixed decimals.
std::string formatNumber(double value, int precision = -1);


}  // namespace qota::tools
