#!/usr/bin/env bash
# The whole test suite under AddressSanitizer + UndefinedBehaviorSanitizer (build-asan), then
# the tests that run threads under ThreadSanitizer (build-tsan). Any report fails the run. The
# ASan build (scripts/configure-asan.sh: clang, shared with scripts/fuzz.sh) is also the
# shared-library build (BUILD_SHARED_LIBS=ON): every test runs against libqota*.so, and
# package.find_package checks the install (SONAMEs, the tool's RPATH).
#
#   scripts/sanitize.sh [asan|tsan]     (default: both)
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install-deps.sh
which=${1:-all}
# The sanitizers' own rules: a report is fatal, with a stack; leaks are checked. An allocation's
# stack is kept 8 frames deep (of 30): a quarter off the suite's time (the index builds allocate
# in deep recursions) and still the caller that matters. (UBSan's checks on each use of a
# pointer are left out of the build: CMakeLists.txt says why.)
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1:malloc_context_size=8}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$PWD/tests/fuzz/lsan.supp}
export TSAN_OPTIONS=${TSAN_OPTIONS:-halt_on_error=1:second_deadlock_stack=1:suppressions=$PWD/tests/tsan.supp}

if [ "$which" = all ] || [ "$which" = asan ]; then
  ./scripts/configure-asan.sh  # (clang; the fuzzers are built there too, for scripts/fuzz.sh)
  cmake --build build-asan -j2
  # All but five long repeats on larger data of code the suite runs under ASan anyway: the grid
  # path against the quadtree on Rainier (RotatedAndSyntheticGrids), tiles on a projected grid
  # (the other ShadowTiles.EqualTheWholeRaster*), and the tool building Rainier's whole
  # quadtree to print, draw or save it (cli.info, cli.render_tree.tree_file and
  # cli.build.spherical_tree run the same code on smaller terrains; the README's commands, whose
  # tools the suite runs on smaller rasters): five minutes of the run.
  ctest --test-dir build-asan -j2 --output-on-failure --timeout 1200 \
    -E '^(GridFastPath.RainierMatchesTheQuadtree|ShadowTiles.EqualTheWholeRasterOnAProjectedGrid|cli.info.lonlat|cli.render_tree.lonlat|cli.build.sample_tree|cli.readme_commands)$'
fi
if [ "$which" = all ] || [ "$which" = tsan ]; then
  # Line tables only: the stacks of a report, without the full debug information's build time.
  # -O1: 40 s less to build from nothing than -O2, 10 s more to run these tests.
  cmake -S . -B build-tsan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" \
    -DQOTA_SANITIZE=thread -DQOTA_BUILD_TESTS=ON -DQOTA_BUILD_EXAMPLES=OFF -DQOTA_BUILD_BENCH=OFF > /dev/null
  cmake --build build-tsan -j2 --target qota_tsan_tests  # (the test files that run threads)
  # The tests whose code runs threads: shadows (the strips and cell passes), parallel batches and
  # builds,
  # the deferred quadtree, statistics read while others query, the viewshed sweep's slices and
  # its exact tests (some 20 s under TSan). Not the memory budgets (TSan's
  # shadow memory makes the process itself hundreds of MiB), nor the largest repeats of threaded
  # code other tests run (Rainier's whole grid against the quadtree; tiles on a projected grid,
  # on the ellipsoid and without a CRS, after tiles flat): four minutes of the run under TSan.
  # Nor three more whose time under TSan goes to what runs on one thread (some two minutes of a
  # shard): the outputs' provenance tags on whole Rainier runs (the threaded runs are the other
  # ShadowTool tests'), the ray-march oracle on Rainier (the shadow's threads run in every Shadow
  # test), the strip walk on the ellipsoid (StripWalkIdenticalToQuadtree runs it flat).
  slow=ShadowTool.MemoryLimitsAndTileOptionsAreChecked:GridFastPath.RainierMatchesTheQuadtree
  slow+=:ShadowTiles.EqualTheWholeRasterOnAProjectedGrid:ShadowTiles.EqualTheWholeRasterOnTheEllipsoid
  slow+=:ShadowTiles.EqualTheWholeRasterWithoutCrs
  slow+=:ShadowTool.OutputsRecordTheirMaking:Shadow.AgreesWithRayMarchOnTheRealDem
  slow+=:Shadow.StripWalkIdenticalToQuadtreeOnTheEllipsoid
  # In two shards at once (GoogleTest's own sharding), one a core.
  filter="*Thread*:*Parallel*:*Concurren*:Shadow*:*Deferred*:GridFast*:*Batch*:RasterSampler.*:SampleTool.*"
  filter+=":Viewshed.Sweep*:Viewshed.Cumulative*-$slow"
  pids=()
  for shard in 0 1; do
    GTEST_TOTAL_SHARDS=2 GTEST_SHARD_INDEX=$shard build-tsan/tests/qota_tsan_tests --gtest_filter="$filter" \
      > "build-tsan/shard$shard.log" 2>&1 &
    pids+=($!)
  done
  failed=0
  for shard in 0 1; do
    wait "${pids[$shard]}" || failed=1
    tail -n 3 "build-tsan/shard$shard.log"
  done
  if [ "$failed" -ne 0 ]; then
    cat build-tsan/shard0.log build-tsan/shard1.log
    echo "ThreadSanitizer: a shard failed (its log is above)"
    exit 1
  fi
fi
