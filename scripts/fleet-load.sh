#!/usr/bin/env bash
# Fleet load benchmark (issue 14): recorded simulated fleet traffic through one dronewatt.
#
# For each fleet size N (default 1 10 100 250; one MAVLink link holds at most 254 vehicles,
# system ids being 8 bits): `dronewatt simulate --vehicles N` records a fleet's flight into
# one tlog (seed 1, deterministic), then two runs of `dronewatt replay` read it:
#
#   paced  --speed 1 (messages at the recorded rate, as a live link delivers them) for
#          SECONDS, stopped by SIGINT (the clean shutdown path: every sink drains):
#            cpu_us_per_vs   CPU time (user+sys, /proc) / (N × SECONDS): µs per vehicle-second
#            rss_mib         peak resident memory (VmHWM); rss_kib_per_vehicle = (RSS(N) − RSS(1)) / (N − 1)
#            missed          reports the sinks missed (summary `missed_reports`) + windows never reported
#            lag_s           how far the newest estimate trails the replay clock at the stop
#                            (backlog: an upper bound on message → estimate latency at that moment)
#   flat   --speed max: the whole tlog as fast as it goes: windows_per_s, the most vehicles
#          at 10 Hz windows this machine sustains = windows_per_s / 10.
#
# Both with the LSTM on every window (the default) and, with LSTM_RATE set, a second pass with
# `[fleet] lstm_rate_hz = LSTM_RATE`. Writes fleet-load.csv and fleet-load.png (plotted by
# `cargo run --example fleet_load_plot`) into OUT (default target/fleet-load).
#
# Usage: scripts/fleet-load.sh [SECONDS] [N ...]      (default: 30, 1 10 100 250)
#        LSTM_RATE=2 scripts/fleet-load.sh 30 1 10 100 250
set -euo pipefail
cd "$(dirname "$0")/.."
DUR=${1:-30}
shift || true
SIZES=${*:-1 10 100 250}
BIN=${DRONEWATT_BIN:-target/debug/dronewatt}
OUT=${OUT:-target/fleet-load}
[ -x "$BIN" ] || cargo build --locked
mkdir -p "$OUT"
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
TICK=$(getconf CLK_TCK)
CSV="$OUT/fleet-load.csv"
echo "lstm,vehicles,seconds,cpu_us_per_vs,rss_mib,estimates,missed,lag_s,flat_windows_per_s,max_vehicles_10hz" > "$CSV"

run_size() {  # $1 = N, $2 = config file, $3 = label
  local n=$1 cfg=$2 label=$3 tlog="$TMP/fleet$1.tlog"
  [ -f "$tlog" ] || "$BIN" simulate --vehicles "$n" --out "$tlog" --seed 1 --leg-m 200 --hover-s 10 2> /dev/null
  # Paced: real time for DUR seconds.
  "$BIN" replay "$tlog" --speed 1 -q --config "$cfg" --json "$TMP/paced.jsonl" 2> "$TMP/paced.err" &
  local pid=$! start
  start=$(date +%s.%N)
  sleep "$DUR"
  local cpu hwm
  cpu=$(awk -v t="$TICK" '{print ($14 + $15) / t}' "/proc/$pid/stat")
  hwm=$(awk '/^VmHWM/ {print $2}' "/proc/$pid/status")
  kill -INT "$pid"; wait "$pid" || true
  local wall
  wall=$(echo "$(date +%s.%N) - $start" | bc)
  # Flat out: the whole tlog.
  local t0 t1
  t0=$(date +%s.%N)
  "$BIN" replay "$tlog" --speed max -q --config "$cfg" --json "$TMP/flat.jsonl" 2> /dev/null
  t1=$(date +%s.%N)
  .venv-py/bin/python - "$TMP/paced.jsonl" "$TMP/flat.jsonl" "$n" "$DUR" "$cpu" "$hwm" "$wall" "$t0" "$t1" "$label" >> "$CSV" <<'PY'
import json, sys
paced, flat, n, dur, cpu, hwm, wall, t0, t1, label = sys.argv[1:]
n, dur, cpu, hwm, wall = int(n), float(dur), float(cpu), int(hwm), float(wall)
est, newest, summary = 0, 0.0, {}
for line in open(paced):
    v = json.loads(line)
    if v["type"] == "estimate" and v["models"]:
        est += 1
        newest = max(newest, v["t"])
    elif v["type"] == "summary":
        summary = v
missed = summary.get("missed_reports", 0) + max(0, summary.get("windows", 0) - summary.get("reports", 0))
# Replay time starts at the first record (t = 0); the stop came `dur` s after the start.
lag = max(0.0, dur - newest)
windows = sum(1 for line in open(flat) if line.startswith('{"type":"estimate"'))
wps = windows / (float(t1) - float(t0))
print(f"{label},{n},{dur},{cpu / (n * dur) * 1e6:.1f},{hwm / 1024:.1f},{est},{missed},{lag:.2f},{wps:.0f},{wps / 10:.0f}")
PY
  tail -1 "$CSV"
}

echo "" > "$TMP/full.toml"
for n in $SIZES; do run_size "$n" "$TMP/full.toml" "10hz"; done
if [ -n "${LSTM_RATE:-}" ]; then
  printf '[fleet]\nlstm_rate_hz = %s\n' "$LSTM_RATE" > "$TMP/rate.toml"
  for n in $SIZES; do run_size "$n" "$TMP/rate.toml" "${LSTM_RATE}hz"; done
fi
cargo run --locked --quiet --example fleet_load_plot -- "$CSV" "$OUT/fleet-load.png"
echo "wrote $CSV and $OUT/fleet-load.png (load average: $(cut -d' ' -f1-3 /proc/loadavg))"
