#!/usr/bin/env bash
# Configures a build directory the one way every script does: Release, warnings as errors, Ninja,
# and ccache when it is installed. scripts/test.sh and scripts/demo.sh both configure build/ with
# exactly these arguments, so running one after the other builds nothing twice.
#   scripts/configure.sh [BUILD_DIR [EXTRA_CMAKE_ARGS...]]     (default: build)
# Later arguments win, e.g. scripts/sanitize.sh passes -DBGKMAP_SANITIZE=... for its own dirs.
set -euo pipefail
cd "$(dirname "$0")/.."
dir="${1:-build}"
shift $(($# > 0 ? 1 : 0))
launcher=()
if command -v ccache >/dev/null 2>&1; then
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
fi
cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=Release -DBGKMAP_WERROR=ON "${launcher[@]}" \
  "$@" >/dev/null
