#!/usr/bin/env bash
# Every benchmark whose figures the README and docs/performance.md quote, one after another, on
# this machine, into one report (stdout, and REPORT when given): each prints its figures beside
# a baseline measured in the same run (gdallocationinfo, gdal_viewshed, r.viewshed, Embree,
# brute force, the whole raster in memory), with the run-to-run spread beside each timing. It
# builds what it runs first (in BUILD, configured). Nothing else should run meanwhile. About 15
# minutes on 2 cores with the default RUNS; BIG=1 adds the 1.7 G-pixel tiled shadow (10 more).
#   bench/run_all.sh [BUILD] [RUNS] [REPORT]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build} runs=${2:-3} report=${3:-/dev/null}
bench=$build/bench
# What it runs, built first (the Embree and TIN benchmarks where their libraries are installed).
targets=(qota_cli qota_bench qota_shadow_bench qota_planet_bench qota_cuts_bench)
for t in qota_embree_bench qota_tin_bench; do
  cmake --build "$build" --target help | grep -q "$t" && targets+=("$t")
done
cmake --build "$build" -j"$(nproc)" --target "${targets[@]}" > /dev/null

section() {
  printf '\n==== %s\n' "$*"
}

{
  echo "qota benchmarks: $(git describe --always --dirty 2>/dev/null || echo unknown), $(date -u +%FT%TZ)"
  echo "machine: $(nproc) cores, $(awk '/MemTotal/ { printf "%.0f GiB", $2 / 1048576 }' /proc/meminfo), $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ //')"
  section "sample (bench/sample_bench.sh: qota sample beside gdallocationinfo)"
  bench/sample_bench.sh "$build" "$runs"
  section "viewshed (bench/viewshed_bench.sh: beside gdal_viewshed and r.viewshed)"
  bench/viewshed_bench.sh "$build" "$runs"
  section "shadow by tiles (bench/shadow_tiles.sh: beside the whole raster in memory)"
  bench/shadow_tiles.sh "$build" "$runs"
  section "shadow memory (bench/shadow_memory.sh: estimates beside measured peaks)"
  bench/shadow_memory.sh "$build"
  section "queries (qota_bench: Google Benchmark)"
  "$bench/qota_bench" --benchmark_repetitions="$runs" --benchmark_report_aggregates_only=true
  section "shadow masks (shadow_bench)"
  "$bench/shadow_bench"
  section "curved mappings (planet_bench)"
  "$bench/planet_bench"
  section "cut lines (cuts_bench)"
  "$bench/cuts_bench"
  for b in embree tin; do
    if [ -x "$bench/${b}_bench" ]; then
      section "$b (${b}_bench: beside Embree)"
      "$bench/${b}_bench"
    else
      section "$b: not built (needs Debian's libembree-dev$([ "$b" = tin ] && echo " and libcgal-dev"))"
    fi
  done
} 2>&1 | tee "$report"
