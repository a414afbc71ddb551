#!/usr/bin/env bash
# Installs every build, test and tool dependency of bgkmap from Debian 12 packages.
# Idempotent: skips apt entirely when everything is already installed.
set -euo pipefail

PACKAGES=(
  build-essential cmake ninja-build pkg-config git clang-format
  universal-ctags  # scripts/check-function-length.sh (the House.function_length test)
  clang-14 libclang-rt-14-dev
  lld  # links the ~170 executables in a sixth of GNU ld's time (CMakeLists.txt)
  libeigen3-dev
  libyaml-cpp-dev libspdlog-dev libfmt-dev libcli11-dev nlohmann-json3-dev
  libgdal-dev gdal-bin libpng-dev
  liblz4-dev libzstd-dev zlib1g-dev  # MCAP chunks (lz4, zstd) and CRC32: tools/io/mcap_*
  libgtest-dev libgmock-dev libbenchmark-dev
  libprotobuf-dev protobuf-compiler libgrpc++-dev libgrpc-dev protobuf-compiler-grpc
  libboost-dev
  libssl-dev openssl
  librocksdb-dev
  libzstd-dev  # the compact point encoding (proto/codec/compact_points.h)
  liboctomap-dev
  librosbag-storage-dev  # ROS 1 .bag files: tools/io/ros1_bag.cc
  nats-server libnats-dev
  gnuplot-nox
  python3-grpcio python3-protobuf python3-numpy python3-pytest python3-pip python3-setuptools
  python3-zstandard  # the Python client's compact scans (client/python/bgkmap/_codec.py)
  chromium chromium-driver
)

# The project's npm packages, each folder with its own package-lock.json: web/ (Leaflet, embedded
# in bgkmapd, and playwright-core, which drives Debian's chromium in the browser test) and
# tests/interop/ (Foxglove's MCAP, ROS 2 CDR, schema and WebSocket libraries, the independent
# implementations the ROS 2 and Foxglove tests check bgkmap against). Needs npm (Debian's `npm`
# package, or a Node.js that brings it).
install_npm_folder() {  # folder relative to the checkout
  local dir
  dir="$(cd "$(dirname "$0")/.." && pwd)/$1"
  # The lock file as last installed: npm ci runs again only when it changed.
  if ! cmp -s "$dir/package-lock.json" "$dir/node_modules/.bgkmap-installed-lock" 2>/dev/null; then
    echo "install-deps: npm ci in $1/"
    (cd "$dir" && npm ci --no-audit --no-fund --loglevel=error &&
      cp package-lock.json node_modules/.bgkmap-installed-lock)
  fi
}
install_npm() {
  if ! command -v npm >/dev/null; then
    ${SUDO:-} apt-get install -y -qq --no-install-recommends npm >/dev/null
  fi
  install_npm_folder web
  install_npm_folder tests/interop
}

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "ok installed" || missing+=("$p")
done
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages present"
  install_npm
  exit 0
fi

echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "install-deps: done"
install_npm
