#!/usr/bin/env bash
# Live-monitoring benchmark (issue 6): `dronewatt monitor` (the dev build `make run` ships) fed a 10 Hz
# flight by pymavlink over UDP on 127.0.0.1 (tests/peers/gcs_flight.py), publishing every
# estimate back as NAMED_VALUE_FLOAT. Prints
#   - resident memory of dronewatt from /proc: VmRSS at the end, VmHWM (peak);
#   - the delay from each tick's SYS_STATUS leaving the peer to the next dw_meas_w
#     arriving back at the peer, p50/p99: an upper bound on arrival → publish latency
#     (it also holds the peer's own send of the tick's other messages and any wait of the
#     resampler for its grid time).
# Usage: scripts/bench-live.sh [SECONDS]   (default 60)
set -euo pipefail
cd "$(dirname "$0")/.."
DUR=${1:-60}
BIN=${DRONEWATT_BIN:-target/debug/dronewatt}   # DRONEWATT_BIN=target/release/dronewatt for a release build
[ -x "$BIN" ] || cargo build --locked
PORT=$(.venv-py/bin/python -c 'import socket; s=socket.socket(socket.AF_INET, socket.SOCK_DGRAM); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
printf '[sinks.mavlink]\nrate_hz = 50\n%s' "${BENCH_EXTRA:-}" > "$TMP/bench.toml"
"$BIN" monitor "udpin:127.0.0.1:$PORT" -q --config "$TMP/bench.toml" 2> "$TMP/dw.log" &
DW=$!
sleep 1
.venv-py/bin/python tests/peers/gcs_flight.py --port "$PORT" --seconds "$DUR" --power-w 500 > "$TMP/peer.json" &
PEER=$!
PEAK=0
while kill -0 "$PEER" 2>/dev/null; do
  RSS=$(awk '/^VmRSS/ {print $2}' "/proc/$DW/status")
  [ "$RSS" -gt "$PEAK" ] && PEAK=$RSS
  sleep 1
done
wait "$PEER"
HWM=$(awk '/^VmHWM/ {print $2}' "/proc/$DW/status")
RSS=$(awk '/^VmRSS/ {print $2}' "/proc/$DW/status")
kill -TERM "$DW"; wait "$DW" || true
.venv-py/bin/python - "$TMP/peer.json" "$RSS" "$PEAK" "$HWM" "$DUR" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
rss, peak, hwm, dur = (int(x) for x in sys.argv[2:6])
n = len(r["values"].get("dw_meas_w", []))
print(f"dronewatt monitor, {dur} s at 10 Hz: {n} estimates published back")
print(f"resident memory: {rss/1024:.1f} MiB at the end, {peak/1024:.1f} MiB highest sampled, VmHWM {hwm/1024:.1f} MiB")
print(f"SYS_STATUS -> dw_meas_w over UDP: p50 {r['delay_p50_ms']:.2f} ms, p99 {r['delay_p99_ms']:.2f} ms ({r['delays']} samples)")
print(f"  of which the peer spends sending the tick's 11 messages: p50 {r['tick_send_p50_ms']:.2f} ms")
if r['after_tick_end_p50_ms'] is not None:
    print(f"last message of the tick sent -> dw_meas_w back: p50 {r['after_tick_end_p50_ms']:.2f} ms, p99 {r['after_tick_end_p99_ms']:.2f} ms")
PY
