#!/usr/bin/env bash
# Usage: scripts/measure-planes.sh OUT_DIR [DRONEWATT]
# The simulated-plane targets of docs/src/vehicle-types.md: for the plane and the quadplane,
# 4 fit flights (what `learn` sees: seeds 101-104, 800 m triangles at 60 m, 60 s loiter,
# 3 m/s from the west, payloads 0/200/400/100 g; learn holds the 4th out, so it fits on 3) and
# 5 test flights no fit or choice has seen (seeds 201-205; other routes, heights, speeds,
# winds 0-8 m/s from four directions, payloads, one PX4). Each test flight is replayed with the
# shipped profile (online adaptation) and with the learned one, and scored against the
# simulator's truth by scripts/measure-plane.py (JSON lines in OUT_DIR/scores.jsonl).
set -euo pipefail
out=$1; dw=${2:-target/debug/dronewatt}
export DRONEWATT_HOME=off
mkdir -p "$out"; : > "$out/scores.jsonl"
for v in plane quadplane; do
  mkdir -p "$out/$v/fit"
  pay=(0 200 400 100)
  for i in 0 1 2 3; do
    "$dw" simulate --vehicle $v --seed $((101 + i)) --leg-m 800 --altitude-m 60 --hover-s 60 \
      --wind-mps 3 --wind-dir-deg 270 --payload-g ${pay[$i]} --out "$out/$v/fit/fit$i.tlog" 2>/dev/null
  done
  "$dw" learn "$out/$v/fit" --vehicle $v --holdout-every 4 --out "$out/$v/learned" --data-dir off > "$out/$v/learn.txt"
  tests=(
    "--seed 201 --leg-m 1200 --altitude-m 80 --wind-mps 0 --payload-g 0 --speed-mps 13 --hover-s 30"
    "--seed 202 --leg-m 600 --altitude-m 40 --wind-mps 6 --wind-dir-deg 180 --payload-g 300 --speed-mps 15 --hover-s 60"
    "--seed 203 --leg-m 1000 --altitude-m 100 --wind-mps 8 --wind-dir-deg 45 --payload-g 500 --speed-mps 16 --hover-s 20"
    "--seed 204 --leg-m 1500 --altitude-m 50 --wind-mps 4 --wind-dir-deg 300 --payload-g 150 --speed-mps 14 --hover-s 120"
    "--seed 205 --leg-m 900 --altitude-m 70 --wind-mps 2 --wind-dir-deg 90 --payload-g 0 --speed-mps 17 --hover-s 40 --autopilot px4"
  )
  for i in 0 1 2 3 4; do
    t="$out/$v/test$i"
    # shellcheck disable=SC2086
    "$dw" simulate --vehicle $v ${tests[$i]} --out "$t.tlog" --truth "$t.csv" 2>/dev/null
    "$dw" replay "$t.tlog" --speed max --vehicle $v --json "$t.shipped.jsonl" --quiet 2>/dev/null
    "$dw" replay "$t.tlog" --speed max --vehicle "$out/$v/learned/profile.toml" --json "$t.learned.jsonl" --quiet 2>/dev/null
    for p in shipped learned; do
      printf '{"vehicle":"%s","test":%d,"profile":"%s","scores":%s}\n' $v $i $p \
        "$(python3 scripts/measure-plane.py "$t.$p.jsonl" "$t.csv" 60 20 --json)" >> "$out/scores.jsonl"
    done
  done
done
