#!/usr/bin/env bash
# Installs the Debian packages qota builds against (or, given names, those packages). Skips what
# is already present, so it is cheap to run before every build. Needs root (or sudo) only when
# something is missing.
set -euo pipefail

packages=(
  build-essential cmake pkg-config
  ccache                        # rebuilds compile only what changed (CI's builds, branch switches)
  libgdal-dev gdal-bin          # rasters, CRS transforms (and gdallocationinfo for the tests)
  libgeographiclib-dev          # ellipsoid math
  libeigen3-dev                 # rotations, plane fits
  libglm-dev                    # interop type for rendering code
  libgtest-dev libgmock-dev     # tests
  libbenchmark-dev              # bench/
  libcli11-dev                  # argument parsing for the qota tool
  nlohmann-json3-dev            # qota info --json
  libcairo2-dev fonts-dejavu-core  # the tools' PNG previews: colour, legends and scales with text
  libpng-dev                    # PNG previews
  libxxhash-dev                 # block hashes of heights, checksums of states and tiles
  proj-data                     # the EGM96 geoid grid (egm96_15.gtx) heights over a geoid need
  libnova-dev                   # solar position (VSOP87) for qota shadow
  libhowardhinnant-date-dev tzdata  # dates and IANA time zones for qota shadow --time/--tz
  libassimp-dev                 # mesh files (OBJ, PLY, glTF, STL, ...)
  libembree-dev                 # bench/embree_bench: the general ray tracer qota is measured against
  libcgal-dev                   # bench/tin_bench: Delaunay TINs and exact predicates for its oracle
  pybind11-dev python3-dev python3-numpy python3-venv python3-pip python3-setuptools python3-wheel python3-pytest python3-gdal
                                # the Python package (python/) and its tests
  python3-pytest-xdist          # those tests on every core (scripts/python-test.sh)
  python3-rasterio python3-xarray python3-rioxarray python3-affine
                                # Python interop (rasterio datasets, DataArrays), optional at runtime
  python3-dask python3-distributed python3-pandas python3-zarr python3-mypy python3-geopandas
                                # qota.dask: shadows and points over a Dask cluster (pandas for its
                                # DataFrames, zarr for Zarr output; qota.sample on GeoDataFrames),
                                # optional at runtime
)

[ $# -gt 0 ] && packages=("$@")
missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed'; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi

echo "qota: installing ${missing[*]}" >&2
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO=sudo; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
