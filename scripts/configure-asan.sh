#!/usr/bin/env bash
# Configures build-asan, the one instrumented build that serves both scripts/sanitize.sh (the test
# suite under AddressSanitizer + UndefinedBehaviorSanitizer, as shared libraries) and
# scripts/fuzz.sh (the libFuzzer harnesses): clang, every qota library with libFuzzer's coverage
# (-fsanitize=fuzzer-no-link), line tables for the sanitizers' stacks and no fuller debug
# information (it would double the build's time). The same options every time, so the second
# script rebuilds nothing.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install-deps.sh
./scripts/install-deps.sh clang-14 libclang-rt-14-dev
cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++-14 \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -gline-tables-only -DNDEBUG" \
  -DQOTA_SANITIZE=address,undefined -DQOTA_BUILD_FUZZERS=ON -DQOTA_BUILD_TESTS=ON \
  -DQOTA_BUILD_EXAMPLES=ON -DQOTA_BUILD_BENCH=OFF -DBUILD_SHARED_LIBS=ON > /dev/null
