#!/bin/sh
# Every command that writes files, when writing fails: all its outputs appear complete, or none do
# and the files that were there stay untouched. Run by ctest as
#   cli_outputs.sh QOTA DATA_DIR
# A full disk is a file size limit (ulimit -f) with SIGXFSZ ignored, so that a write fails with
# EFBIG as it would with ENOSPC. Prints "all outputs safe" when every check holds.
set -u
qota=$1
data=$2
dem=$data/SainteHelens.dem
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
failures=0
fail() {
  echo "FAIL: $*"
  failures=$((failures + 1))
}
# No staging folder may be left behind by a finished run.
no_partials() {
  if ls -a "$dir" | grep -q '^\.qota-partial-'; then fail "$1: a staging folder was left behind"; fi
}
# Runs a command with the file size limit (KiB); prints its exit code.
limited() {
  limit=$1
  shift
  (trap '' XFSZ; ulimit -f "$limit"; exec "$@" > "$dir/out.log" 2>&1 < "${STDIN:-/dev/null}")
  echo $?
}

# A full disk: every command exits 2, leaves nothing under the name, and an earlier file stays.
echo "earlier contents" > "$dir/keep.tif"
cp "$dir/keep.tif" "$dir/keep.orig"
code=$(limited 64 "$qota" shadow "$dem" -o "$dir/keep.tif" -az 200 -alt 30 -q)
[ "$code" = 2 ] || fail "shadow on a full disk exited $code"
cmp -s "$dir/keep.tif" "$dir/keep.orig" || fail "shadow on a full disk changed the file that was there"
grep -q "keep.tif" "$dir/out.log" || fail "shadow on a full disk did not name the file"
no_partials shadow

code=$(limited 64 "$qota" shadow "$dem" -o "$dir/new.tif" -az 200 -alt 30 -q)
[ "$code" = 2 ] || fail "shadow (new file) on a full disk exited $code"
[ -e "$dir/new.tif" ] && fail "shadow on a full disk left new.tif"

code=$(limited 64 "$qota" shadow "$dem" -o "$dir/new.envi" -of ENVI -az 200 -alt 30 -q)
[ "$code" = 2 ] || fail "shadow to ENVI on a full disk exited $code"
ls "$dir" | grep -q '^new\.' && fail "shadow to ENVI on a full disk left $(ls "$dir" | grep '^new\.')"

code=$(limited 2048 "$qota" build "$dem" -o "$dir/tree.qota" -q)
[ "$code" = 2 ] || fail "build on a full disk exited $code"
[ -e "$dir/tree.qota" ] && fail "build on a full disk left tree.qota"

code=$(limited 8 "$qota" render-tree "$dem" -o "$dir/tree.png" --size 2000 -q)
[ "$code" = 2 ] || fail "render-tree on a full disk exited $code"
[ -e "$dir/tree.png" ] && fail "render-tree on a full disk left tree.png"

awk 'BEGIN { for (i = 0; i < 20000; i++) printf "%.3f %.3f\n", 560000 + (i % 300) * 30, 5110000 + (i % 200) * 30 }' > "$dir/points.txt"
code=$(STDIN="$dir/points.txt" limited 16 "$qota" sample "$dem" -o "$dir/heights.txt")
[ "$code" = 2 ] || fail "sample on a full disk exited $code"
[ -e "$dir/heights.txt" ] && fail "sample on a full disk left heights.txt"
no_partials "the full-disk runs"

# A failing preview leaves the mask unplaced too (the preview's name is a folder).
mkdir "$dir/preview.png"
"$qota" shadow "$dem" -o "$dir/mask.tif" --png "$dir/preview.png" -q > "$dir/out.log" 2>&1
[ $? = 2 ] || fail "shadow with an unwritable preview did not fail"
[ -e "$dir/mask.tif" ] && fail "shadow with an unwritable preview placed the mask"
no_partials "the failed preview"

# A symlink at the output is replaced by the new file, never written through.
echo "victim" > "$dir/victim.tif"
ln -s victim.tif "$dir/link.tif"
"$qota" shadow "$dem" -o "$dir/link.tif" -az 200 -alt 30 -q || fail "shadow to a symlink failed"
[ -L "$dir/link.tif" ] && fail "the symlink at -o is still a symlink"
[ "$(cat "$dir/victim.tif")" = victim ] || fail "shadow wrote through the symlink"

# Not a regular file: refused.
"$qota" shadow "$dem" -o /dev/null -az 200 -alt 30 -q > "$dir/out.log" 2>&1
[ $? = 2 ] && grep -q "not a regular file" "$dir/out.log" || fail "shadow -o /dev/null was not refused"
mkfifo "$dir/fifo.txt"
echo "562500 5114500" | "$qota" sample "$dem" -o "$dir/fifo.txt" > "$dir/out.log" 2>&1
[ $? = 2 ] || fail "sample -o FIFO was not refused"

# A run killed outright leaves a recognisable staging folder, which the next run removes.
mkfifo "$dir/slow_input"
"$qota" sample "$dem" -o "$dir/killed.txt" < "$dir/slow_input" > /dev/null 2>&1 &
pid=$!
exec 3> "$dir/slow_input"   # the reader waits for more input
for _ in 1 2 3 4 5 6 7 8 9 10; do
  ls -a "$dir" | grep -q "^\.qota-partial-$pid-" && break
  sleep 0.5
done
ls -a "$dir" | grep -q "^\.qota-partial-$pid-" || fail "no staging folder while sample was writing"
kill -9 "$pid"
wait "$pid" 2> /dev/null
exec 3>&-
ls -a "$dir" | grep -q "^\.qota-partial-$pid-" || fail "the killed run's staging folder is gone already"
echo "562500 5114500" | "$qota" sample "$dem" -o "$dir/after.txt" || fail "sample after a killed run failed"
ls -a "$dir" | grep -q "^\.qota-partial-$pid-" && fail "the killed run's staging folder was not cleaned"
[ -e "$dir/killed.txt" ] && fail "the killed run placed its output"

# Tree files are the same bytes whatever the name, the cores, or what memory held before.
"$qota" build "$dem" -o "$dir/a.qota" -q || fail "build a.qota"
MALLOC_PERTURB_=165 taskset -c 0 "$qota" build "$dem" -o "$dir/b.qota" -q || fail "build b.qota"
cmp -s "$dir/a.qota" "$dir/b.qota" || fail "two builds of the same DEM differ"
"$qota" build "$data/testarea.obj" -o "$dir/m1.qota" -q && MALLOC_PERTURB_=90 "$qota" build "$data/testarea.obj" -o "$dir/m2.qota" -q
cmp -s "$dir/m1.qota" "$dir/m2.qota" || fail "two builds of the same mesh differ"
"$qota" build "$data/etopo20.tif" --mapping spherical -o "$dir/s1.qota" -q && MALLOC_PERTURB_=33 taskset -c 0 "$qota" build "$data/etopo20.tif" --mapping spherical -o "$dir/s2.qota" -q
cmp -s "$dir/s1.qota" "$dir/s2.qota" || fail "two builds of the same planet differ"

if [ "$failures" = 0 ]; then echo "all outputs safe"; else exit 1; fi
