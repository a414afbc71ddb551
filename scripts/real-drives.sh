#!/usr/bin/env bash
# The truth that needs no survey on every real sequence in ../shared/data (docs/results.md,
# "Real drives: today's map"): the ground the robot drove over must come out traversable, and
# the map of the odd scans must agree with the map of the even scans. Each sequence is mapped
# with the settings of the robot that recorded it (experiments/robots/*.yaml; per robot, never
# per sequence) and scored with `bgkmap eval --footprint-radius` (the robot's half width: 0.8 m
# for the cars, 0.3 m for the person carrying the hall's sensor). Each is run twice: with the
# sequence's own poses, and with realistic SLAM-like pose error added (--pose-noise 1: 3 cm and
# 0.1 deg per scan plus a slow drift of 5 cm and 0.2 deg; sim/pose_noise.h), and a third time
# with that error stated by the robot (pose_sigma_z: 0.03, docs/semantics.md "Pose noise").
# Then each of the three again with every scan's z aligned to the map built so far before it is
# integrated (--align-z, the robot's step of core/vertical_alignment.h; docs/mapping-your-robot.md
# "Vertical alignment"), twice the error (--pose-noise 2) without and with the alignment, and
# no error and the error with the scans' roll and pitch levelled too (--align-tilt 1,
# "Levelling the tilt").
#   scripts/real-drives.sh [build-dir] [out-dir]       (about three minutes on 2 vCPUs)
# Writes $OUT/<sequence>[_noise]/{eval.json,table.md,drive_<method>.png} and $OUT/table.md.
# METHODS (default bgk+) is passed to --methods.
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
BUILD="${1:-$ROOT/build}"
OUT="${2:-$ROOT/out/real-drives}"
DATA="${BGKMAP_SHARED_DATA:-$ROOT/../shared/data}"
METHODS="${METHODS:-bgk+}"
BGKMAP="$BUILD/tools/bgkmap/bgkmap"
ROBOTS="$ROOT/experiments/robots"
cmake --build "$BUILD" -j2 --target bgkmap
rm -rf "$OUT"
mkdir -p "$OUT"

# sequence | robot config | footprint radius (m)
RUNS=(
  "kitti_raw_0048|car_kitti|0.8"
  "ouster_os1_128_street|car_ouster|0.8"
  "balm_hall|handheld_hall|0.3"
)
for run in "${RUNS[@]}"; do
  IFS='|' read -r seq robot radius <<< "$run"
  # 1s: the same added error, stated by the robot (pose_sigma_z: its 3 cm of z jitter).
  cat "$ROBOTS/$robot.yaml" > "$OUT/$robot-stated.yaml"
  echo "pose_sigma_z: 0.03" >> "$OUT/$robot-stated.yaml"
  # a: aligned (--align-z); l: aligned and levelled (--align-z --align-tilt 1).
  for noise in 0 1 1s 0a 1a 1sa 2 2a 0l 1l; do
    name="$seq"
    args=()
    config="$ROBOTS/$robot.yaml"
    level="${noise%%[sal]*}"
    if [[ "$level" != 0 ]]; then
      name="${seq}_noise$noise"
      args=(--pose-noise "$level")
    elif [[ "$noise" != 0 ]]; then
      name="${seq}_$noise"
    fi
    [[ "$noise" == *s* ]] && config="$OUT/$robot-stated.yaml"
    [[ "$noise" == *a ]] && args+=(--align-z)
    [[ "$noise" == *l ]] && args+=(--align-z --align-tilt 1)
    echo "real-drives: $name ($SECONDS s so far)"
    "$BGKMAP" eval "$DATA/$seq" --config "$config" --footprint-radius "$radius" \
      --methods "$METHODS" --name "$name" --out "$OUT/$name" "${args[@]}" > /dev/null
  done
done

# One table of the runs, from their eval.json.
python3 - "$OUT" "${RUNS[@]}" > "$OUT/table.md" <<'PY'
import json, sys, os
out, runs = sys.argv[1], sys.argv[2:]
pct = lambda v: "n/a" if v is None else "%.2f" % (100 * v)
print("| Sequence | Robot | Footprint | Pose error | Method | Scans | Driven cells | Known (%) | "
      "Traversable (%) | On arrival: known / traversable (%) | Blocked: no value / mean / "
      "variance / disagreement | Odd/even agreement (%) | Odd/even, driven (%) | Odd/even dz RMS (m) |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
for run in runs:
    seq, robot, radius = run.split("|")
    for noise in ("0", "1", "1s", "0a", "1a", "1sa", "2", "2a", "0l", "1l"):
        level = noise.rstrip("sal")
        name = seq if noise == "0" else seq + "_" + noise if level == "0" else seq + "_noise" + noise
        error = "none" if level == "0" else "x" + level
        error += ", stated" if "s" in noise else ""
        error += ", aligned" if noise.endswith("a") else ""
        error += ", aligned and levelled" if noise.endswith("l") else ""
        j = json.load(open(os.path.join(out, name, "eval.json")))
        for m in j["methods"]:
            d, a, b = m["drive"], m["drive_on_arrival"], m["drive"]["blocked_by"]
            oe, oed = m["odd_even"], m["odd_even_driven"]
            print("| %s | %s | disc %s m | %s | %s | %d | %d | %s | %s | %s / %s | %d / %d / %d / %d | %s | %s | %s |" % (
                seq, robot, radius, error, m["method"], m["scans"],
                d["driven_cells"], pct(d["known_share"]), pct(d["traversable_share"]),
                pct(a["known_share"]), pct(a["traversable_share"]),
                b["no_value"], b["high_mean"], b["high_variance"], b["disagreement"],
                pct(oe["state_agreement"]), pct(oed["state_agreement"]),
                "n/a" if oe["dz_rms_m"] is None else "%.3f" % oe["dz_rms_m"]))
PY
cat "$OUT/table.md"
echo "real-drives: $SECONDS s; per run: $OUT/<sequence>/table.md (why blocked, causes, odd/even)"
