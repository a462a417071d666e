#!/usr/bin/env bash
# Fuzzes qota's inputs with libFuzzer (clang from Debian), under AddressSanitizer and
# UndefinedBehaviorSanitizer:
#
#   scripts/fuzz.sh SECONDS [HARNESS...]
#
# Harnesses (tests/fuzz/fuzz_NAME.cpp): treefile, mesh, sample_line, raster, cli, tiles (tiles
# states, and tiles' metadata and bytes given to qota assemble), sheet (the one-sheet proof
# against pairs of triangles). Each first
# replays its seed corpus (tests/fuzz/corpus/NAME) and every crash ever found
# (tests/fuzz/crashes/NAME, kept as regressions once fixed), then fuzzes for SECONDS seconds
# starting from the corpus (new inputs go to a scratch copy, not the repository). A crash, a
# hang (over 20 s on one input; 120 s for raster, whose every input runs five tools, a shadow and
# a tree build among them, some 20 times slower under the sanitizers than in a release build), a
# leak or an out-of-memory input is written to build-fuzz/crashes/NAME/ and counted. Prints one line per harness, "NAME: N runs, M crashes",
# and exits 1 when any harness crashed.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:?usage: scripts/fuzz.sh SECONDS [HARNESS...]}
shift
harnesses=("$@")
[ ${#harnesses[@]} -eq 0 ] && harnesses=(treefile mesh sample_line raster cli tiles sheet)

# The harnesses live in build-asan, the instrumented build scripts/sanitize.sh runs the tests in
# (after it, nothing is left to build).
./scripts/configure-asan.sh
mkdir -p build-fuzz
cmake --build build-asan -j2 --target $(printf 'qota_fuzz_%s ' "${harnesses[@]}") > build-fuzz/build.log 2>&1 ||
  { tail -40 build-fuzz/build.log; exit 2; }

# A smaller quarantine, and freed memory returned to the system: the raster harness's RSS would
# otherwise only grow, input after input, to the 3 GB limit.
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:allocator_may_return_null=1:quarantine_size_mb=64:allocator_release_to_os_interval_ms=1000}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$PWD/tests/fuzz/lsan.supp}
# One harness: its seeds and past crashes replayed, then SECONDS of fuzzing; prints its line
# (and the report's lines on a crash) and exits 1 when it crashed.
fuzz_one() {
  local name=$1
  local bin=build-asan/tests/fuzz/fuzz_$name
  # Absolute paths: a harness may change its working folder (fuzz_cli runs in its own).
  local seeds=$PWD/tests/fuzz/corpus/$name known=$PWD/tests/fuzz/crashes/$name
  local work=$PWD/build-fuzz/corpus/$name artifacts=$PWD/build-fuzz/crashes/$name
  mkdir -p "$seeds" "$known" "$work" "$artifacts"
  local log=build-fuzz/$name.log timeout=20 crashes=0 runs=0
  [ "$name" = raster ] && timeout=120
  # Every input ever kept, once: the seeds and the crashes of the past must all pass now.
  if ! "$bin" -runs=0 -timeout=$timeout -rss_limit_mb=3072 -artifact_prefix="$artifacts/" "$seeds" "$known" > "$log" 2>&1; then
    crashes=1
  fi
  runs=$(grep -Eo '^#[0-9]+' "$log" | tail -1 | tr -d '#' || true)
  if [ "$crashes" -eq 0 ] && [ "$seconds" -gt 0 ]; then
    if ! "$bin" -max_total_time="$seconds" -timeout=$timeout -rss_limit_mb=3072 -print_final_stats=1 \
        -artifact_prefix="$artifacts/" "$work" "$seeds" >> "$log" 2>&1; then
      crashes=1
    fi
    runs=$(grep -Eo 'stat::number_of_executed_units: *[0-9]+' "$log" | tail -1 | grep -Eo '[0-9]+$' || echo "$runs")
  fi
  echo "$name: ${runs:-0} runs, $crashes crashes"
  if [ "$crashes" -ne 0 ]; then
    # The report: the log's last lines but libFuzzer's progress (so also what the process said
    # before a signal: an uncaught exception's 'terminate called', a library's 'stack smashing
    # detected', the harness's own reason for an abort).
    grep -Ev '^#[0-9]+[[:space:]]+(NEW|REDUCE|pulse|INITED|RELOAD)' "$log" | tail -n 50 | sed 's/^/  /'
    # The input itself, in hex, so that a crash found in CI can be replayed from its log.
    for unit in "$artifacts"/*; do
      [ -f "$unit" ] || continue
      echo "  input $(basename "$unit") ($(stat -c %s "$unit") bytes):"
      od -An -tx1 -v "$unit" | head -64 | sed 's/^/   /'
    done
    return 1
  fi
}

# The harnesses run side by side, one a core (QOTA_FUZZ_JOBS; each is one process on one
# thread, with a scratch folder of its own): the same fuzzing in half the time on two cores.
# Their lines are printed in the order given.
jobs=${QOTA_FUZZ_JOBS:-$(nproc)}
for name in "${harnesses[@]}"; do
  while [ "$(jobs -rp | wc -l)" -ge "$jobs" ]; do wait -n || true; done
  (if fuzz_one "$name" > "build-fuzz/$name.summary"; then echo 0; else echo 1; fi > "build-fuzz/$name.status") &
done
wait
failed=0
for name in "${harnesses[@]}"; do
  cat "build-fuzz/$name.summary"
  [ "$(cat "build-fuzz/$name.status")" = 0 ] || failed=1
done
exit $failed
