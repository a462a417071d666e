#!/usr/bin/env bash
# Builds the HTML manual (docs/: Sphinx with MyST, the API reference by Breathe over Doxygen's
# XML of the public headers) into build/docs/html, with warnings as errors.
set -euo pipefail
cd "$(dirname "$0")/.."
need=()
command -v doxygen > /dev/null || need+=(doxygen)
/usr/bin/python3 -c 'import sphinx, myst_parser, breathe' 2> /dev/null ||
  need+=(python3-sphinx python3-myst-parser python3-breathe)
if (( ${#need[@]} )); then
  apt-get install -y -qq "${need[@]}" > /dev/null
fi
mkdir -p build/docs
(cat docs/Doxyfile; echo "OUTPUT_DIRECTORY = build/docs") | doxygen -
QOTA_DOXYGEN_XML=$PWD/build/docs/xml /usr/bin/python3 -m sphinx -W --keep-going -q -b html docs build/docs/html
echo "manual: build/docs/html/index.html"
