#!/usr/bin/env bash
# Usage: lab/scripts/measure-planes.sh OUT_DIR [DRONEWATT]
# The simulated-plane targets of docs/src/vehicle-types.md: for the plane and the quadplane,
# 4 fit flights (what `learn` sees: seeds 101-104, 800 m triangles at 60 m, 60 s loiter,
# 3 m/s from the west, payloads 0/200/400/100 g; learn holds the 4th out, so it fits on 3) and
# 5 test flights no fit or choice has seen (seeds 201-205; other routes, heights, speeds,
# winds 0-8 m/s from four directions, payloads, one PX4). Each test flight is replayed with the
# shipped profile (online adaptation) and with the learned one, and scored against the
# simulator's truth by lab/scripts/measure-plane.py (JSON lines in OUT_DIR/scores.jsonl).
#
# --set validation (lab/scripts/measure-planes.sh OUT_DIR [DRONEWATT] --set validation): the
# validation flights every design and constant of the estimator is chosen on, never the test
# flights: seeds 301-310 per airframe, made like the test flights (routes, heights, speeds,
# winds 0-8 m/s from other directions, payloads, two PX4) with other values, plus the 4 fit
# flights scored with the shipped profile. Means per airframe and profile are printed at the
# end (OUT_DIR/summary.txt) for any set.
#
# --set test2: a second test set, made after the first had been scored for the VTOL
# transitions' wing lift (docs/src/vehicle-types.md): seeds 401-405 per airframe, made like the
# test flights (legs 700-1400 m at 45-95 m, 13-17 m/s, loiters 25-110 s, wind 0-8 m/s from
# four other directions, payloads 0-450 g, the last PX4) with other values. Scored once.
set -euo pipefail
set_name=test; pos=()
while [ $# -gt 0 ]; do
  case $1 in
    --set) set_name=$2; shift 2 ;;
    *) pos+=("$1"); shift ;;
  esac
done
out=${pos[0]}; dw=${pos[1]:-target/debug/dronewatt}
case $set_name in test|test2|validation) ;; *) echo "--set test|test2|validation, not $set_name" >&2; exit 2 ;; esac
export DRONEWATT_HOME=off
mkdir -p "$out"; : > "$out/scores.jsonl"
for v in plane quadplane; do
  mkdir -p "$out/$v/fit"
  pay=(0 200 400 100)
  for i in 0 1 2 3; do
    f="$out/$v/fit/fit$i"
    "$dw" simulate --vehicle $v --seed $((101 + i)) --leg-m 800 --altitude-m 60 --hover-s 60 \
      --wind-mps 3 --wind-dir-deg 270 --payload-g ${pay[$i]} --out "$f.tlog" --truth "$out/$v/fit$i.csv" 2>/dev/null
    if [ "$set_name" = validation ]; then
      "$dw" replay "$f.tlog" --speed max --vehicle $v --json "$out/$v/fit$i.shipped.jsonl" --quiet 2>/dev/null
      printf '{"vehicle":"%s","test":"fit%d","profile":"shipped","scores":%s}\n' $v $i \
        "$(python3 lab/scripts/measure-plane.py "$out/$v/fit$i.shipped.jsonl" "$out/$v/fit$i.csv" 60 20 --json)" >> "$out/scores.jsonl"
    fi
  done
  "$dw" learn "$out/$v/fit" --vehicle $v --holdout-every 4 --out "$out/$v/learned" --data-dir off > "$out/$v/learn.txt"
  if [ "$set_name" = validation ]; then tests=(
    "--seed 301 --leg-m 700 --altitude-m 50 --wind-mps 1 --wind-dir-deg 200 --payload-g 100 --speed-mps 14 --hover-s 50"
    "--seed 302 --leg-m 1100 --altitude-m 90 --wind-mps 5 --wind-dir-deg 20 --payload-g 250 --speed-mps 16 --hover-s 30"
    "--seed 303 --leg-m 800 --altitude-m 60 --wind-mps 7 --wind-dir-deg 135 --payload-g 0 --speed-mps 15 --hover-s 90"
    "--seed 304 --leg-m 1300 --altitude-m 45 --wind-mps 3 --wind-dir-deg 250 --payload-g 400 --speed-mps 13 --hover-s 40 --autopilot px4"
    "--seed 305 --leg-m 950 --altitude-m 75 --wind-mps 8 --wind-dir-deg 330 --payload-g 200 --speed-mps 17 --hover-s 25"
    "--seed 306 --leg-m 650 --altitude-m 110 --wind-mps 0 --payload-g 350 --speed-mps 15 --hover-s 70"
    "--seed 307 --leg-m 1400 --altitude-m 55 --wind-mps 6 --wind-dir-deg 90 --payload-g 50 --speed-mps 14 --hover-s 100"
    "--seed 308 --leg-m 1000 --altitude-m 85 --wind-mps 2 --wind-dir-deg 160 --payload-g 450 --speed-mps 16 --hover-s 35"
    "--seed 309 --leg-m 750 --altitude-m 65 --wind-mps 4.5 --wind-dir-deg 10 --payload-g 0 --speed-mps 13.5 --hover-s 60 --autopilot px4"
    "--seed 310 --leg-m 1200 --altitude-m 40 --wind-mps 7.5 --wind-dir-deg 225 --payload-g 300 --speed-mps 15.5 --hover-s 45"
  ); elif [ "$set_name" = test2 ]; then tests=(
    "--seed 401 --leg-m 1100 --altitude-m 60 --wind-mps 2 --wind-dir-deg 120 --payload-g 250 --speed-mps 14.5 --hover-s 80"
    "--seed 402 --leg-m 700 --altitude-m 95 --wind-mps 8 --wind-dir-deg 280 --payload-g 100 --speed-mps 16 --hover-s 40"
    "--seed 403 --leg-m 1400 --altitude-m 45 --wind-mps 0 --payload-g 450 --speed-mps 13 --hover-s 110"
    "--seed 404 --leg-m 850 --altitude-m 70 --wind-mps 6 --wind-dir-deg 15 --payload-g 0 --speed-mps 17 --hover-s 25"
    "--seed 405 --leg-m 1250 --altitude-m 85 --wind-mps 4 --wind-dir-deg 200 --payload-g 350 --speed-mps 15 --hover-s 60 --autopilot px4"
  ); else tests=(
    "--seed 201 --leg-m 1200 --altitude-m 80 --wind-mps 0 --payload-g 0 --speed-mps 13 --hover-s 30"
    "--seed 202 --leg-m 600 --altitude-m 40 --wind-mps 6 --wind-dir-deg 180 --payload-g 300 --speed-mps 15 --hover-s 60"
    "--seed 203 --leg-m 1000 --altitude-m 100 --wind-mps 8 --wind-dir-deg 45 --payload-g 500 --speed-mps 16 --hover-s 20"
    "--seed 204 --leg-m 1500 --altitude-m 50 --wind-mps 4 --wind-dir-deg 300 --payload-g 150 --speed-mps 14 --hover-s 120"
    "--seed 205 --leg-m 900 --altitude-m 70 --wind-mps 2 --wind-dir-deg 90 --payload-g 0 --speed-mps 17 --hover-s 40 --autopilot px4"
  ); fi
  for i in "${!tests[@]}"; do
    t="$out/$v/test$i"
    # shellcheck disable=SC2086
    "$dw" simulate --vehicle $v ${tests[$i]} --out "$t.tlog" --truth "$t.csv" 2>/dev/null
    "$dw" replay "$t.tlog" --speed max --vehicle $v --json "$t.shipped.jsonl" --quiet 2>/dev/null
    "$dw" replay "$t.tlog" --speed max --vehicle "$out/$v/learned/profile.toml" --json "$t.learned.jsonl" --quiet 2>/dev/null
    for p in shipped learned; do
      printf '{"vehicle":"%s","test":%d,"profile":"%s","scores":%s}\n' $v $i $p \
        "$(python3 lab/scripts/measure-plane.py "$t.$p.jsonl" "$t.csv" 60 20 --json)" >> "$out/scores.jsonl"
    done
  done
done
python3 - "$out/scores.jsonl" <<'PY' | tee "$out/summary.txt"
import json, sys
from collections import defaultdict
rows = [json.loads(l) for l in open(sys.argv[1])]
keys = ("forecast_mape_vs_truth_pct", "fixed_wing_adapted_mape_vs_truth_pct", "fixed_wing_raw_mape_vs_truth_pct")
g = defaultdict(list)
for r in rows:
    kind = "fit" if str(r["test"]).startswith("fit") else "flights"
    g[(r["vehicle"], r["profile"], kind)].append(r["scores"])
for (v, p, kind), ss in sorted(g.items()):
    mean = lambda k: sum(s[k] for s in ss if s.get(k) == s.get(k) and s.get(k) is not None) / max(1, sum(1 for s in ss if s.get(k) == s.get(k) and s.get(k) is not None))
    st = defaultdict(list)
    for s in ss:
        for name, b in s["by_state_whole_flight"].items():
            if b["windows"]:
                st[name].append(b["mape_pct"])
    print(f"{v:<9} {p:<7} {kind:<7} n={len(ss)} forecast {mean(keys[0]):5.1f} % (each {', '.join(f'{s[keys[0]]:.1f}' for s in ss)}); fw adapted {mean(keys[1]):5.1f} %, fw raw {mean(keys[2]):5.1f} %; worst energy {max(abs(s['energy_error_pct']) for s in ss):.2f} %; "
          + ", ".join(f"{n} {sum(x)/len(x):.1f} %" for n, x in sorted(st.items())))
PY
