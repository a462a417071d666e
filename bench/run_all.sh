#!/usr/bin/env bash
# Every benchmark whose figures the README and docs/performance.md quote, one after another, on
# this machine, into one report (stdout, and REPORT when given): each prints its figures beside
# a baseline measured in the same run (gdallocationinfo, gdal_viewshed, r.viewshed, Embree,
# brute force, the whole raster in memory), with the run-to-run spread beside each timing. It
# builds what it runs first (in BUILD, configured). Nothing else should run meanwhile. About 13
# minutes on 2 cores with the default RUNS; BIG=1 adds the 1.7 G-pixel tiled shadow (10 more).
#   bench/run_all.sh [BUILD] [RUNS] [REPORT]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build} runs=${2:-3} report=${3:-/dev/null}
bench=$build/bench
# What it runs, built first (the Embree and TIN benchmarks where their libraries are installed).
targets=(qota_cli qota_bench qota_shadow_bench qota_planet_bench qota_cuts_bench)
known=$(cmake --build "$build" --target help)
for t in qota_embree_bench qota_tin_bench; do
  grep -qw "$t" <<< "$known" && targets+=("$t")
done
cmake --build "$build" -j"$(nproc)" --target "${targets[@]}" > /dev/null

section() {
  printf '\n==== %s\n' "$1"
}
# One benchmark: its section, and its failure (a check it makes, such as a memory estimate's
# bound) reported without stopping the others; the script exits 1 when any failed.
failed=()
run() {
  local title=$1
  shift
  section "$title"
  "$@" || { echo "FAILED: $title (exit $?)"; failed+=("$title"); }
}

{
  echo "qota benchmarks: $(git describe --always --dirty 2>/dev/null || echo unknown), $(date -u +%FT%TZ)"
  echo "machine: $(nproc) cores, $(awk '/MemTotal/ { printf "%.0f GiB", $2 / 1048576 }' /proc/meminfo), $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ //')"
  run "sample (bench/sample_bench.sh: qota sample beside gdallocationinfo)" bench/sample_bench.sh "$build" "$runs"
  run "viewshed (bench/viewshed_bench.sh: beside gdal_viewshed and r.viewshed)" bench/viewshed_bench.sh "$build" "$runs"
  run "shadow by tiles (bench/shadow_tiles.sh: beside the whole raster in memory)" bench/shadow_tiles.sh "$build" "$runs"
  run "shadow memory (bench/shadow_memory.sh: estimates beside measured peaks)" bench/shadow_memory.sh "$build"
  run "queries (qota_bench: Google Benchmark)" "$bench/qota_bench" --benchmark_repetitions="$runs" \
    --benchmark_report_aggregates_only=true
  run "shadow masks (shadow_bench)" "$bench/shadow_bench"
  run "curved mappings (planet_bench)" "$bench/planet_bench"
  run "cut lines (cuts_bench)" "$bench/cuts_bench"
  for b in embree tin; do
    if [ -x "$bench/${b}_bench" ]; then
      run "$b (${b}_bench: beside Embree)" "$bench/${b}_bench"
    else
      section "$b: not built (needs Debian's libembree-dev$([ "$b" = tin ] && echo " and libcgal-dev"))"
    fi
  done
  # The Maxpoly table of docs/performance.md (the default's 8 is the run above).
  if [ -x "$bench/tin_bench" ]; then
    for maxpoly in 16 32; do
      run "tin, Maxpoly $maxpoly (tin_bench --no-large --maxpoly $maxpoly)" "$bench/tin_bench" --no-large --maxpoly "$maxpoly"
    done
  fi
  if [ "${#failed[@]}" -gt 0 ]; then
    printf '\nfailed: %s\n' "${failed[*]}"
    exit 1
  fi
} 2>&1 | tee "$report"
