#!/usr/bin/env bash
# The sanitizer stages of CI (.ci/run); also run by hand:
#   scripts/sanitize.sh [asan] [asan-ci] [tsan]          (default: asan and tsan)
#
#   asan     ASan + UBSan (-fsanitize=address,undefined; every finding fatal, leaks included)
#            over the whole suite except the client package test (`-L package`: it installs the
#            library and links a downstream project without the sanitizer runtime), in
#            build-asan/.
#   asan-ci  The same build directory and options, for CI's time budget: only the GoogleTest
#            suites of core, proto and storage (the engine, the codecs, the store and its
#            recovery) are built and run; the server (the cluster's included: it needs bgkmapd
#            and gRPC built with ASan, ~29 CPU-minutes of compiling measured), tools, sim, eval,
#            cli and python suites run under ASan in `asan` only. docs/testing.md has the times
#            that decided it.
#   tsan  TSan over the server's map-serving and durability layers without gRPC or RocksDB
#         (ServedMap, ChangeScheduler, TileResidency, TileLockTable, MapSummary, WatchHub, a scan
#         in bands on threads and their hand-off: the threaded core, tests/server/serving/), in
#         build-tsan/. Not the gRPC or RocksDB suites: Debian's gRPC,
#         abseil and RocksDB are not built with TSan, so their internal hand-offs (a message or a
#         write batch passed between threads through their own atomics) are reported as races in
#         our frames; docs/testing.md lists them. tests/sanitizers/tsan.supp is for library-only
#         reports and is empty today.
#
# Both build with -O1 and frame pointers, without the benchmarks and with every CTest
# timeout x4 (BGKMAP_TEST_TIMEOUT_SCALE); DISABLED_ tests do not run. The sanitizers write their
# reports, also those of the bgkmapd and crash_writer processes the tests start, to
# <build dir>/sanitizer-reports/: any report fails the stage, even from a process a test killed.
# docs/testing.md says what each stage covers and how long it takes.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
stages=("$@")
[ ${#stages[@]} -gt 0 ] || stages=(asan tsan)
jobs=$(nproc)
TSAN_SUITES='^(Methods/)?(ChangeSchedulerTest|ScanBandsTest|ScanBandsServedTest|SharedTasksTest|IdleScratchReleaseTest|MapSummaryIndexTest|MapSummaryTest|ResidencyTest|ServedMapChangesTest|LatencyHistogramTest|ServerConfigTest|TileLockTableTest|TileResidencyTest|WatchHubTest)\.'
bash scripts/install-deps.sh

# -O1: compiles much faster than Release's -O3 and is what the sanitizers' manuals recommend.
# Warnings are the normal build's job (GCC warns differently with instrumentation).
configure() {  # build dir, sanitizers
  bash scripts/configure.sh "$1" -DBGKMAP_SANITIZE="$2" -DBGKMAP_WERROR=OFF \
    "-DCMAKE_CXX_FLAGS_RELEASE=-O1 -DNDEBUG" -DBGKMAP_BUILD_BENCHMARKS=OFF \
    -DBGKMAP_TEST_TIMEOUT_SCALE=4
}

# Runs ctest with the given arguments, then fails if any sanitizer report was written.
run_tests() {  # build dir, ctest arguments...
  local dir=$1 status=0
  shift
  ctest --test-dir "$dir" -j"$jobs" --output-on-failure "$@" || status=$?
  if compgen -G "$dir/sanitizer-reports/*" >/dev/null; then
    echo "sanitize: reports in $dir/sanitizer-reports:" >&2
    for f in "$dir"/sanitizer-reports/*; do
      echo "==== $f" >&2
      head -c 20000 "$f" >&2
    done
    status=1
  fi
  return $status
}

fresh_reports() {  # build dir
  rm -rf "$1/sanitizer-reports"
  mkdir -p "$1/sanitizer-reports"
  echo "$ROOT/$1/sanitizer-reports"
}

for stage in "${stages[@]}"; do
  start=$SECONDS
  case "$stage" in
    asan)
      configure build-asan address,undefined
      cmake --build build-asan -j"$jobs"
      echo "sanitize: asan built in $((SECONDS - start)) s"
      reports=$(fresh_reports build-asan)
      ASAN_OPTIONS="log_path=$reports/asan:detect_leaks=1" \
      UBSAN_OPTIONS="log_path=$reports/ubsan:print_stacktrace=1:halt_on_error=1" \
        run_tests build-asan -LE package
      ;;
    asan-ci)
      configure build-asan address,undefined
      cmake --build build-asan -j"$jobs" --target tests_core tests_proto tests_storage
      echo "sanitize: asan-ci built in $((SECONDS - start)) s"
      reports=$(fresh_reports build-asan)
      ASAN_OPTIONS="log_path=$reports/asan:detect_leaks=1" \
      UBSAN_OPTIONS="log_path=$reports/ubsan:print_stacktrace=1:halt_on_error=1" \
        run_tests build-asan -L '^(core|proto|storage)$'
      ;;
    tsan)
      configure build-tsan thread
      cmake --build build-tsan -j"$jobs" --target served_map_changes_test tile_residency_test \
        map_summary_test change_scheduler_test tile_lock_table_test watch_hub_test server_config_test \
        latency_histogram_test idle_scratch_release_test scan_bands_test scan_bands_served_test \
        shared_tasks_test
      echo "sanitize: tsan built in $((SECONDS - start)) s"
      reports=$(fresh_reports build-tsan)
      # detect_deadlocks=0: TSan's lock-order detector aborts beyond 64 locks held by one thread,
      # and TileLockTable holds one per tile of a region (in ascending order: no deadlock).
      TSAN_OPTIONS="log_path=$reports/tsan:suppressions=$ROOT/tests/sanitizers/tsan.supp:detect_deadlocks=0:history_size=4" \
        run_tests build-tsan -R "$TSAN_SUITES"
      ;;
    *)
      echo "usage: scripts/sanitize.sh [asan] [asan-ci] [tsan]" >&2
      exit 2
      ;;
  esac
  echo "sanitize: $stage passed in $((SECONDS - start)) s"
done
