#!/usr/bin/env bash
# MCAP read + integrate throughput against the same scans as a KITTI folder (issue 26,
# docs/benchmarks.md "ROS 2 recordings"): the 22 KITTI scans (~120k points each) written as
# MCAP by Foxglove's @mcap/core (tests/interop/ros2/write_recordings.mjs; chunks uncompressed,
# lz4, zstd), then bench/recording_read. Results in out/bench/ros2.md.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
bash scripts/configure.sh build
cmake --build build -j"$(nproc)" --target recording_read
SHARED=$(cmake -LA -N build | sed -n 's/^BGKMAP_SHARED_DATA:PATH=//p')
SEQ="$SHARED/kitti_raw_0048"
DIR=out/bench/ros2
mkdir -p "$DIR"
for c in none lz4 zstd; do
  node tests/interop/ros2/write_recordings.mjs --sequence "$SEQ" "$DIR/kitti_$c.mcap" "$c"
done
build/bench/recording_read "$SEQ" "$DIR/kitti_none.mcap" "$DIR/kitti_lz4.mcap" \
  "$DIR/kitti_zstd.mcap" --repeat "${REPEAT:-5}" | tee out/bench/ros2.md
