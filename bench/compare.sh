#!/usr/bin/env bash
# Before and after: runs the same benchmarks of two builds in turns (A B A B ...), so that both
# see the same machine state, and keeps every run's output. The spread between the runs of one
# build is the noise to read the A/B differences against.
#
#   bench/compare.sh BUILD_A BUILD_B [ROUNDS] [OUT_DIR]
#     BUILD_A, BUILD_B: build folders holding bench/{qota_bench,embree_bench,planet_bench,shadow_bench}
#     ROUNDS: runs of each benchmark per build (default 2); OUT_DIR default bench-compare/
#   QOTA_COMPARE: the benchmarks to run (default "qota embree planet shadow")
#
# Each benchmark takes its own flags here (the figures of the README's tables: qota_bench's
# Google Benchmark table, embree_bench's and planet_bench's rows, shadow_bench at its default
# size). Prints each run's table; the logs stay in OUT_DIR/NAME.{a,b}.ROUND.log.
set -euo pipefail
a=$1 b=$2 rounds=${3:-2} out=${4:-bench-compare}
mkdir -p "$out"
declare -A flags=(
  [qota]=""
  [embree]=""
  [planet]=""
  [shadow]=""
)
for name in ${QOTA_COMPARE:-qota embree planet shadow}; do
  for ((r = 1; r <= rounds; ++r)); do
    for side in a b; do
      build=$a
      [ "$side" = b ] && build=$b
      bin=$build/bench/${name}_bench
      [ -x "$bin" ] || { echo "no $bin"; exit 1; }
      log=$out/$name.$side.$r.log
      echo "== ${name}_bench, build $side ($build), round $r" | tee "$log"
      # shellcheck disable=SC2086
      "$bin" ${flags[$name]} 2>&1 | tee -a "$log"
    done
  done
done
echo "logs: $out/"
