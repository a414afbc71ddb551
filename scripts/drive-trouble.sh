#!/usr/bin/env bash
# Realistic trouble in the simulator (docs/results.md, "Real drives: today's map"): the City
# street driven at 1 m per scan (10 m/s) by the simulated car (experiments/robots/car_sim.yaml,
# footprint a 0.8 m disc), with traffic (experiments/city_traffic.yaml: a car ahead and one
# behind at the robot's speed, one oncoming, two crossing ahead) and with SLAM-like pose error
# (--pose-noise 1), each scored against the perfect-pose run without traffic:
#   static        perfect poses, no traffic (the reference)
#   traffic       perfect poses, traffic
#   static_noise  pose error, no traffic
#   traffic_noise pose error, traffic
#   static_noise_stated, traffic_noise_stated  the same, the robot stating its pose error
#                 (experiments/robots/car_sim_pose_error.yaml: pose_sigma_z)
#   static_on_traffic_cells  the reference map judged on the traffic run's trail cells (what
#                 the map calls those cells when no vehicle ever drove there)
#   *_aligned     the same, each scan's z aligned to the map built so far before it is
#                 integrated (--align-z: the robot's step of core/vertical_alignment.h,
#                 docs/mapping-your-robot.md "Vertical alignment"); static_aligned checks that
#                 it does not hurt perfect poses
#   *_levelled    aligned, and each scan's roll and pitch levelled against the map too
#                 (--align-tilt 1, docs/mapping-your-robot.md "Levelling the tilt")
# Scores: AUC against the ground truth (the world at the last scan), the driven cells (final
# map, and on arrival: the map just before the robot drives onto them) with their causes, stale
# trails (cells a vehicle left that are still non-traversable 5 scans later) and missed new
# obstacles (cells a vehicle arrived at not shown on the map after that scan).
#   scripts/drive-trouble.sh [build-dir] [out-dir]    (6 minutes on 2 vCPUs, half of it the
#                                                      ray casting of the two simulations)
# Writes $OUT/<run>/{eval.json,table.md,drive_bgk+.png,...} and $OUT/table.md. METHODS (default
# bgk+) is passed to --methods; the simulations are kept and reused if $OUT/sim exists.
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
BUILD="${1:-$ROOT/build}"
OUT="${2:-$ROOT/out/drive-trouble}"
METHODS="${METHODS:-bgk+}"
BGKMAP="$BUILD/tools/bgkmap/bgkmap"
CONFIG="$ROOT/experiments/robots/car_sim.yaml"
cmake --build "$BUILD" -j2 --target bgkmap
mkdir -p "$OUT/sim"
stage() { echo "drive-trouble: $1 ($SECONDS s so far)"; }

sim() {  # name, extra simulate arguments
  if [[ ! -f "$OUT/sim/$1/scenario.json" ]]; then
    stage "simulating $1"
    "$BGKMAP" simulate city --config "$CONFIG" --length 100 --truth-spacing 0.5 \
      --out "$OUT/sim/$1" "${@:2}" > /dev/null
  fi
}
sim static
sim traffic --change "$ROOT/experiments/city_traffic.yaml"

evaluate() {  # run name, sequence, extra eval arguments
  stage "evaluating $1"
  rm -rf "${OUT:?}/$1"
  "$BGKMAP" eval "$OUT/sim/$2" --config "${RUN_CONFIG:-$CONFIG}" --footprint-radius 0.8 --methods "$METHODS" \
    --name "$1" --out "$OUT/$1" "${@:3}" > /dev/null
}
evaluate static static --figure-scans 50
evaluate traffic traffic --figure-scans 50
evaluate static_noise static --pose-noise 1 --figure-scans 50
evaluate traffic_noise traffic --pose-noise 1 --figure-scans 50
# The same pose error, stated by the robot (pose_sigma_z, docs/semantics.md "Pose noise").
RUN_CONFIG="$ROOT/experiments/robots/car_sim_pose_error.yaml" \
  evaluate static_noise_stated static --pose-noise 1 --no-figures
RUN_CONFIG="$ROOT/experiments/robots/car_sim_pose_error.yaml" \
  evaluate traffic_noise_stated traffic --pose-noise 1 --no-figures
# Each scan aligned vertically to the map before it (the robot's step, not a map rule).
evaluate static_aligned static --align-z --no-figures
evaluate static_noise_aligned static --pose-noise 1 --align-z --no-figures
evaluate traffic_noise_aligned traffic --pose-noise 1 --align-z --no-figures
RUN_CONFIG="$ROOT/experiments/robots/car_sim_pose_error.yaml" \
  evaluate static_noise_stated_aligned static --pose-noise 1 --align-z --no-figures
RUN_CONFIG="$ROOT/experiments/robots/car_sim_pose_error.yaml" \
  evaluate traffic_noise_stated_aligned traffic --pose-noise 1 --align-z --no-figures
# Roll and pitch levelled too (--align-tilt 1: the robot's step for a localization whose tilt
# errs, docs/mapping-your-robot.md "Levelling the tilt"); static_levelled checks perfect poses.
evaluate static_levelled static --align-z --align-tilt 1 --no-figures
evaluate static_noise_levelled static --pose-noise 1 --align-z --align-tilt 1 --no-figures
evaluate traffic_noise_levelled traffic --pose-noise 1 --align-z --align-tilt 1 --no-figures
evaluate static_on_traffic_cells static --traffic "$OUT/sim/traffic/traffic.json" --no-odd-even \
  --no-figures

python3 - "$OUT" > "$OUT/table.md" <<'PY'
import json, sys, os
out = sys.argv[1]
runs = ["static", "traffic", "static_noise", "traffic_noise", "static_noise_stated",
        "traffic_noise_stated", "static_aligned", "static_noise_aligned", "traffic_noise_aligned",
        "static_noise_stated_aligned", "traffic_noise_stated_aligned", "static_levelled",
        "static_noise_levelled", "traffic_noise_levelled", "static_on_traffic_cells"]
pct = lambda v: "n/a" if v is None else "%.2f" % (100 * v)
ref = {m["method"]: m for m in json.load(open(os.path.join(out, "static", "eval.json")))["methods"]}
print("| Run | Method | AUC | AUC - reference | Driven: traversable, final (%) | On arrival: known / "
      "traversable (%) | Stale trails, 5 scans after (%) | Stale cells | Missed new obstacles, 1 scan "
      "after (%) | Odd/even agreement (%) |")
print("|---|---|---|---|---|---|---|---|---|---|")
for run in runs:
    for m in json.load(open(os.path.join(out, run, "eval.json")))["methods"]:
        auc = m["offline"]["auc"]
        t = m.get("traffic")
        print("| %s | %s | %.4f | %+.4f | %s | %s / %s | %s | %s | %s | %s |" % (
            run, m["method"], auc, auc - ref[m["method"]]["offline"]["auc"],
            pct(m["drive"]["traversable_share"]), pct(m["drive_on_arrival"]["known_share"]),
            pct(m["drive_on_arrival"]["traversable_share"]),
            pct(t["trail_stale_rate"]) if t else "", t["trail_stale_cells"] if t else "",
            pct(t["new_missed_rate"]) if t else "",
            pct(m["odd_even"]["state_agreement"]) if "odd_even" in m else ""))
PY
cat "$OUT/table.md"
stage "done: $OUT/table.md; causes per run in $OUT/<run>/table.md"
