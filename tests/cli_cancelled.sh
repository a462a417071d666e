#!/bin/sh
# qota shadow stopped by SIGTERM mid-run: exit by the signal (143), "cancelled" said, and neither
# the output nor a staging folder left in the output's folder. Prints "nothing left" when so.
#   tests/cli_cancelled.sh QOTA DATA_DIR
set -u
qota=$1 data=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# Rainier three times finer (3603 x 3603), by tiles of 256: several seconds of work.
gdal_translate -q -outsize 3603 3603 "$data/mt_rainier_90m.tif" "$work/big.tif" || exit 1
mkdir "$work/out"
"$qota" shadow "$work/big.tif" -o "$work/out/shadow.tif" -az 90 -alt 5 --tile-size 256 2> "$work/err" > /dev/null &
pid=$!
sleep 2
kill -TERM $pid
wait $pid
code=$?
left=$(ls -A "$work/out")
echo "exit $code; left: '$left'; said: $(cat "$work/err")"
[ "$code" -eq 143 ] && [ -z "$left" ] && grep -q "cancelled by SIGTERM" "$work/err" && echo "nothing left"
