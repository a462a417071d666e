#!/usr/bin/env bash
# clang-tidy (Debian's clang-tidy-14) with .clang-tidy's checks over lib/, coords/ and tools/, or
# over the files given. Configures build-tidy with clang for its compile_commands.json (nothing
# is built: clang understands those flags, GCC's build would hand it some it does not), without
# the precompiled header, so each file is read with the includes it names. Prints every
# warning; exits 1 when there is one.
#
#   scripts/tidy.sh [FILE...]      (some ten minutes for the whole tree on two cores)
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install-deps.sh clang-14 clang-tidy-14
cmake -S . -B build-tidy -DCMAKE_CXX_COMPILER=clang++-14 -DQOTA_BUILD_TESTS=OFF -DQOTA_BUILD_BENCH=OFF \
  -DQOTA_BUILD_EXAMPLES=OFF -DQOTA_CCACHE=OFF -DQOTA_PCH=OFF > /dev/null
files=("$@")
[ ${#files[@]} -eq 0 ] && mapfile -t files < <(git ls-files 'lib/*.cpp' 'coords/*.cpp' 'tools/*.cpp')
out=$(mktemp)
trap 'rm -f "$out"' EXIT
printf '%s\n' "${files[@]}" | xargs -P 2 -n 4 clang-tidy-14 -p build-tidy --quiet 2> /dev/null |
  grep -E '^/.*(warning|error):' | sort -u > "$out" || true
cat "$out"
echo "clang-tidy: ${#files[@]} files, $(wc -l < "$out") warnings"
[ ! -s "$out" ]
