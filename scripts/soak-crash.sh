#!/usr/bin/env bash
# Crash soak: SIGKILLs bgkmapd at random moments during two-robot ingest, ROUNDS times
# TRIALS trials (each round with its own seed), restarting it each time and checking that every
# acknowledged scan survived and the map equals an uninterrupted run of the recovered scans.
# CI runs one round of 21; this runs as many as asked:  scripts/soak-crash.sh [ROUNDS] [TRIALS]
set -euo pipefail
cd "$(dirname "$0")/.."
rounds="${1:-10}"
trials="${2:-30}"
bash scripts/configure.sh build  # the configuration of scripts/test.sh and demo.sh
cmake --build build -j"$(nproc)" --target persistence_test crash_test bgkmapd
for ((round = 1; round <= rounds; ++round)); do
  seed=$((20261121 + round))
  echo "round $round/$rounds: $trials server kills, seed $seed"
  BGKMAP_CRASH_TRIALS="$trials" BGKMAP_CRASH_SEED="$seed" build/tests/server/persistence_test \
    --gtest_filter='PersistenceTest.SigkillLosesNoAcknowledgedScanAndRecoveryIsExact' \
    | grep -E 'crash trials|FAILED|OK \]'
  # The storage-level crash test too (32 writer kills; its kill moments depend on timing).
  build/tests/storage/crash_test | grep -E "FAILED|PASSED"
done
echo "soak: $rounds rounds passed"
