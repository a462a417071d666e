// The tools' sources are the library's (qota/source.hpp): the same names in the tools' namespace.
#pragma once

#include "qota/source.hpp"

namespace qota::tools {

using qota::estimatedPeakBytes;
using qota::isRaster;
using qota::mappingNameOf;
using qota::openIndex;
using qota::requireSource;
using qota::SourceOptions;

}  // namespace qota::tools
