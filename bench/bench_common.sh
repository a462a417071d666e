# Shared by the benchmark scripts (sourced): the Rainier mosaics and the timing of commands.
# Needs $work (a scratch folder) and $runs set, and the current folder at the repository's root.

# A VRT of the Rainier tile n x n times, one source per copy, on stdout: mosaic N [TYPE NODATA].
# Without TYPE, the tile's Int16 as it is (nodata not declared); with it, that type and the
# tile's nodata kept (ComplexSource).
mosaic() {
  local n=$1 type=${2:-Int16} nodata=${3:-} size=1201 dem=$PWD/data/mt_rainier_90m.tif
  echo "<VRTDataset rasterXSize=\"$((n * size))\" rasterYSize=\"$((n * size))\">"
  echo "  <SRS>EPSG:4326</SRS>"
  echo "  <GeoTransform>-122.000416666666666, 0.000833333333333333, 0, 47.000416666666666, 0, -0.000833333333333333</GeoTransform>"
  if [ -n "$nodata" ]; then
    echo "  <VRTRasterBand dataType=\"$type\" band=\"1\"><NoDataValue>$nodata</NoDataValue>"
  else
    echo "  <VRTRasterBand dataType=\"$type\" band=\"1\">"
  fi
  local source=SimpleSource extra=""
  [ -n "$nodata" ] && source=ComplexSource extra="<NODATA>$nodata</NODATA>"
  for ((r = 0; r < n; ++r)); do
    for ((c = 0; c < n; ++c)); do
      echo "    <$source><SourceFilename relativeToVRT=\"0\">$dem</SourceFilename><SourceBand>1</SourceBand>$extra"
      echo "      <SrcRect xOff=\"0\" yOff=\"0\" xSize=\"$size\" ySize=\"$size\"/><DstRect xOff=\"$((c * size))\" yOff=\"$((r * size))\" xSize=\"$size\" ySize=\"$size\"/></$source>"
    done
  done
  echo "  </VRTRasterBand>"
  echo "</VRTDataset>"
}

# Median (med), spread (max - min over the median, %) of a command's wall seconds and its median
# peak RSS (mem, KB), over $runs runs; stdin from $input (default /dev/null).
measure() {
  local times=() rss=()
  for ((k = 0; k < runs; ++k)); do
    /usr/bin/time -f "%e %M" -o "$work/time" "$@" > "$work/out" 2> "$work/err" < "${input:-/dev/null}" || {
      cat "$work/err"; exit 1; }
    read -r t m < "$work/time"
    times+=("$t") rss+=("$m")
  done
  printf '%s\n' "${times[@]}" | sort -g > "$work/t"
  printf '%s\n' "${rss[@]}" | sort -g > "$work/m"
  local mid=$(((runs + 1) / 2))
  med=$(sed -n "${mid}p" "$work/t") lo=$(head -1 "$work/t") hi=$(tail -1 "$work/t")
  mem=$(sed -n "${mid}p" "$work/m")
  spread=$(awk -v a="$lo" -v b="$hi" -v m="$med" 'BEGIN { printf "%.0f", (m > 0 ? 100 * (b - a) / m : 0) }')
}
