#!/usr/bin/env bash
# Installs dependencies, builds everything with warnings as errors and runs the whole test suite.
# build/ is configured by scripts/configure.sh, exactly as scripts/demo.sh does it.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
bash scripts/configure.sh build
cmake --build build -j"$(nproc)"
ctest --test-dir build -j"$(nproc)" --output-on-failure --timeout 600
