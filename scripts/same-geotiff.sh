#!/usr/bin/env bash
# Whether two GeoTIFFs hold the same map: prints "the same bytes", "the same pixels" (every
# band's values, bit for bit, and the same georeferencing and band descriptions, in files whose
# blocks lie in another order: `bgkmap build` writes its raster strip by strip; the compression's
# predictor is not the map) or "DIFFERENT".
#   scripts/same-geotiff.sh A.tif B.tif
set -euo pipefail
a="$1"
b="$2"
if cmp -s "$a" "$b"; then
  echo "the same bytes"
  exit 0
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
gdal_translate -q -of ENVI "$a" "$tmp/a.raw"
gdal_translate -q -of ENVI "$b" "$tmp/b.raw"
info() { gdalinfo "$1" | grep -v -E '^(Files:|Driver:)|\.tif$|^ +[^ ]+\.(tif|qml)$|^ +PREDICTOR='; }
if cmp -s "$tmp/a.raw" "$tmp/b.raw" && diff -q <(info "$a") <(info "$b") >/dev/null; then
  echo "the same pixels"
else
  echo "DIFFERENT"
fi
